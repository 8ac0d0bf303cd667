"""How long the hold to the evidence takes in a fit, against the numpy reference of the Rigid Map
rule timed in the same run, and a fingerprint of each learned region.

Run: ``.venv/bin/python benchmarks/bench_hold.py --out docs/bench_hold.md``. With
``PYTHONPATH=<another checkout>`` it times that checkout's code (the script uses only
``RigidMap.fit`` and ``edge_hold.hold_to_evidence``), so two checkouts compare on one machine:
the fingerprints say whether they learned the same regions, the ratios how fast each fit is.

Cases: fits whose edges stand far from the samples, where the hold works hardest: the eval
smoke grid's 400 sphere patterns over 90 deg (the slowest task of ``limbctl eval --smoke``), and
sparse i.i.d. teachings (500 + 400 + 600 samples) of two region families
(``bench_region_families``), two servos and three. Each fit runs ``--repeat`` times after one
untimed fit that compiles; the best counts. The hold's own time is read by wrapping
``hold_to_evidence`` for the best run's fit.
"""

from __future__ import annotations

import argparse
import functools
import hashlib
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from bench_envelope import reference_seconds, table
from bench_region_families import FAMILIES, TEACHINGS, make_truth, teach

import limbctl.region.taught as taught_module
from limbctl.envelope import RigidMap
from limbctl.eval.experiments import build_model, draw_training
from limbctl.eval.grids import build_tasks
from limbctl.geometry.quat import limb_direction, swing_from_direction

#: The reference's epochs: bench_fit's (issue 12 item 5: 2,000 nodes, 1,000 samples, 100 epochs).
REFERENCE_EPOCHS = 100
#: Region seed of the family teachings: one no test or benchmark table was tuned on.
FAMILY_SEED = 64


def cases() -> list[tuple[str, np.ndarray, Callable[[], RigidMap]]]:
    """(name, orientations (N, 4), a maker of the unfitted model) of every timed fit."""
    task = next(t for t in build_tasks("smoke") if t.experiment == "som-patterns" and t.x == 400)
    # the gate's model of the task, on the training data run_task draws
    train = draw_training(task.data, np.random.default_rng(task.seed))
    gate = next(spec for spec in task.models if spec.kind == "rigidmap")
    made = functools.partial(build_model, gate, task.seed, task.data.range_deg)
    out = [("eval smoke: 400 sphere patterns, 90 deg", train, made)]
    for family in FAMILIES[:2]:
        truth, mapping = make_truth(family, FAMILY_SEED)
        q = teach(truth, mapping, TEACHINGS["i.i.d. sparse (1500)"], FAMILY_SEED)
        name = f"{family}, seed {FAMILY_SEED}, i.i.d. sparse"
        swing = swing_from_direction(limb_direction(q))
        two = functools.partial(RigidMap, seed=FAMILY_SEED)
        three = functools.partial(RigidMap, seed=FAMILY_SEED, twist=True)
        out += [(f"{name}, two servos", swing, two), (f"{name}, three servos", q, three)]
    return out


def fingerprint(model: RigidMap) -> str:
    """The first 12 hex digits of the sha256 of the learned swing region's arrays."""
    mesh = model.region.swing.mesh if model.twist else model.region.mesh
    digest = hashlib.sha256()
    for array in (mesh.vertices, mesh.edges, mesh.margins):
        digest.update(np.ascontiguousarray(array).tobytes())
    return digest.hexdigest()[:12]


def timed_fit(q: np.ndarray, made: Callable[[], RigidMap]) -> tuple[float, float, RigidMap]:
    """One fit: its seconds, the seconds spent holding, the model."""
    held = [0.0]
    inner = taught_module.hold_to_evidence

    def hold(*args, **kwargs):
        start = time.perf_counter()
        try:
            return inner(*args, **kwargs)
        finally:
            held[0] += time.perf_counter() - start

    taught_module.hold_to_evidence = hold
    try:
        start = time.perf_counter()
        model = made().fit(q)
        return time.perf_counter() - start, held[0], model
    finally:
        taught_module.hold_to_evidence = inner


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, help="write the table here (markdown)")
    parser.add_argument("--repeat", type=int, default=2, help="timed fits per case (best counts)")
    args = parser.parse_args(argv)
    reference = reference_seconds(0, REFERENCE_EPOCHS)
    rows = []
    for name, q, made in cases():
        timed_fit(q, made)  # compiles, loads the cache
        runs = [timed_fit(q, made) for _ in range(args.repeat)]
        fit_s, hold_s, model = min(runs, key=lambda r: r[0])
        reference = min(reference, reference_seconds(0, REFERENCE_EPOCHS))
        rows.append([name, f"{fit_s:.2f}", f"{hold_s:.2f}", fingerprint(model)])
        print(f"{name}: fit {fit_s:.2f} s, hold {hold_s:.2f} s", file=sys.stderr, flush=True)
    for row in rows:
        row.insert(2, f"{float(row[1]) / reference:.2f}")
    header = ["fit", "seconds (best)", "ratio to the reference", "of it holding (s)", "region"]
    text = (
        f"numpy reference of the Rigid Map rule (2,000 nodes, 1,000 samples, {REFERENCE_EPOCHS} "
        f"epochs), best in this run: {reference:.2f} s\n\n" + table(header, rows) + "\n"
    )
    print(text)
    if args.out:
        args.out.write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
