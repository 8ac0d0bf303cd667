"""The warm fit's CPU time by stage and by batch kernel, on several revisions in one run.

Run: ``.venv/bin/python benchmarks/bench_fit_cpu.py --revs ef55d5d HEAD`` (writes
docs/bench_fit_cpu.md).

Each revision is checked out into a temporary git worktree and imported from there (as
``before_after.sh`` does). Per round, each revision in turn runs one child process that fits
the 60 s teaching of bench_fit (``bench_envelope.hand_samples``) and reports, by CPU time
(``time.process_time``: what a fit costs whatever else the shared machine runs; a parallel
kernel's threads add up):

- the whole fit (median of :data:`FITS` fits) and its stages as bench_fit instruments them;
- the fit's batch kernels on their inputs of that fit, each timed :data:`KERNEL_REPEATS` times,
  with ``NUMBA_NUM_THREADS=1`` so a parallel kernel's code is compared with a serial one's on
  one thread; and a hash of every kernel's outputs (equal hashes: byte-identical answers).

The table gives each figure's median over the rounds and its ratio to the first revision.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
import types
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: Fits timed per child process (the median counts): three keep a child under a minute.
FITS = 3
#: Timings of each kernel per child (the median counts).
KERNEL_REPEATS = 7
#: The kernels timed, (module, name): the fit's loops over arcs, windows and points.
KERNELS = (
    ("limbctl.region.grid_kernels", "build_grid"),
    ("limbctl.region.direct_kernels", "query_batch"),
    ("limbctl.region.trace_kernels", "station_moves"),
    ("limbctl.region.shape_kernels", "nearest_arcs"),
    ("limbctl.region.shape_kernels", "widest_bearing_gaps"),
)


def child() -> dict:
    """In a revision's tree: the stages' and kernels' CPU milliseconds and the outputs' hashes."""
    import importlib

    import numpy as np

    sys.path.insert(0, str(Path.cwd() / "benchmarks"))
    import bench_fit as bf
    from bench_envelope import hand_samples

    import limbctl.region.edge_traced as edge_traced
    from limbctl.envelope.synthetic import to_quaternions

    q = to_quaternions(hand_samples(60.0, 0))
    calls: dict[str, list] = {name: [] for _, name in KERNELS}
    owners = [(importlib.import_module(m), name) for m, name in KERNELS]
    owners.append((edge_traced, "station_moves"))  # imported there by name
    originals = {name: getattr(importlib.import_module(m), name) for m, name in KERNELS}
    for owner, name in owners:

        def record(*args, _name=name):
            calls[_name].append(args)
            return originals[_name](*args)

        setattr(owner, name, record)
    bf.fit_seconds(q, 0)  # compiles (cached after the first run) and records the inputs
    for owner, name in owners:
        setattr(owner, name, originals[name])
    bf.time = types.SimpleNamespace(perf_counter=time.process_time)
    result = {"whole fit": 1e3 * statistics.median(bf.fit_seconds(q, 0) for _ in range(FITS))}
    stages: dict[str, list[float]] = {}
    for _ in range(FITS):
        for name, seconds in bf.stage_seconds(q, 0)[0].items():
            stages.setdefault(name, []).append(seconds)
    result.update({f"stage: {k}": 1e3 * statistics.median(v) for k, v in stages.items()})
    hashes = {}
    for _, name in KERNELS:
        digest = hashlib.sha256()
        for args in calls[name]:
            out = originals[name](*args)
            for array in out if isinstance(out, tuple) else (out,):
                digest.update(np.ascontiguousarray(array).tobytes())
        hashes[name] = digest.hexdigest()[:12]
        times = []
        for _ in range(KERNEL_REPEATS):
            start = time.process_time()
            for args in calls[name]:
                originals[name](*args)
            times.append(time.process_time() - start)
        result[f"kernel: {name} ({len(calls[name])} calls)"] = 1e3 * statistics.median(times)
    return {"ms": result, "hashes": hashes}


def run_child(tree: Path) -> dict:
    env = {**os.environ, "PYTHONPATH": str(tree), "NUMBA_NUM_THREADS": "1"}
    done = subprocess.run(
        [sys.executable, str(Path(__file__).resolve()), "--child"],
        cwd=tree,
        env=env,
        capture_output=True,
        text=True,
        check=True,
    )
    return json.loads(done.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--revs", nargs="+", default=["ef55d5d", "HEAD"])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "bench_fit_cpu.md")
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        print(json.dumps(child()))
        return
    work = Path(tempfile.mkdtemp(prefix="bench_fit_cpu-"))
    trees = {}
    for rev in args.revs:
        sha = subprocess.run(
            ["git", "-C", str(ROOT), "rev-parse", "--short", rev],
            check=True,
            capture_output=True,
            text=True,
        ).stdout.strip()
        trees[rev] = work / sha
        subprocess.run(
            ["git", "-C", str(ROOT), "worktree", "add", "-f", "--detach", str(trees[rev]), sha],
            check=True,
            capture_output=True,
        )
    loads = [os.getloadavg()[0]]
    try:
        for tree in trees.values():
            run_child(tree)  # compiles into the tree's own cache
        found: dict[str, list[dict]] = {rev: [] for rev in args.revs}
        for _ in range(args.rounds):
            for rev, tree in trees.items():
                found[rev].append(run_child(tree))
                loads.append(os.getloadavg()[0])
    finally:
        for tree in trees.values():
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(tree)])
    first = args.revs[0]
    names = list(found[first][0]["ms"])
    median = {
        rev: {n: statistics.median(r["ms"].get(n, float("nan")) for r in runs) for n in names}
        for rev, runs in found.items()
    }
    heads = " | ".join(f"{rev} (ms)" for rev in args.revs)
    lines = [
        "# The warm fit's CPU time by stage and kernel, revisions side by side",
        "",
        f"Produced by `.venv/bin/python benchmarks/bench_fit_cpu.py --revs {' '.join(args.revs)}`"
        f" ({args.rounds} rounds, revisions interleaved; 2 CPU cores shared with other work, "
        f"load average {min(loads):.1f}-{max(loads):.1f}). CPU milliseconds (user + system, "
        "all threads), medians over the rounds; kernels with `NUMBA_NUM_THREADS=1`. See the "
        "script's docstring; why the figures moved: docs/decisions/first_run.md.",
        "",
        f"| what | {heads} | ratio to {first} |",
        "|---|" + "---|" * (len(args.revs) + 1),
    ]
    for n in names:
        cells = " | ".join(f"{median[rev][n]:.1f}" for rev in args.revs)
        ratios = ", ".join(f"{median[rev][n] / median[first][n]:.2f}" for rev in args.revs[1:])
        lines.append(f"| {n} | {cells} | {ratios} |")
    same = all(r["hashes"] == found[first][0]["hashes"] for runs in found.values() for r in runs)
    lines += [
        "",
        "Kernel outputs byte-identical on every revision and round: "
        + (
            "yes."
            if same
            else "**no**: " + json.dumps({r: v[0]["hashes"] for r, v in found.items()})
        ),
        "",
    ]
    args.out.write_text("\n".join(lines))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
