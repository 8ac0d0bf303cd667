"""The three-servo demo's end-to-end figures, beside the two-servo demo run the same way.

Run: ``.venv/bin/python benchmarks/bench_twist_demo.py --seconds 60 --seeds 0``
(writes docs/bench_twist_demo.md).

For each seed, :func:`limbctl.demo.run_demo` runs the whole flow on the simulator twice: on the
two-servo rig (``sim``, the peer) and on the three-servo rig (``sim3``: the hand teaches a swing
outline with a shoulder-like twist band over it, ``limbctl/data/demo_region3.yaml``; a
``RigidMap(twist=True)`` learns it; a stream sweeping far outside in swing and twist, roll
+-150 deg, is gated). From each run's own files it reports:

- goals: goal packets the simulator received (its goal log);
- worst excursion: the largest rotation (deg) by which a goal lies outside the learned region
  (three servos: bounded by the nearer of ``correct(q)`` and the region orientations the gate
  wrote, :func:`limbctl.eval.twist_demo.twist_excursions`; two servos: the demo's own measure,
  the direction's angle to the region);
- held: the share of the true region's orientations lying 2 deg or more inside (swing and
  twist; :func:`limbctl.demo.true_twist_probes`) that the learned region contains;
- loop rate: cycles per second of the teleop loop (telemetry rows over their time span), and
  its ratio to the two-servo peer's in the same run;
- outside the truth: the share of the learned region (directions on a 1 deg lattice of its
  swing region, each with a twist drawn uniformly in its band) lying outside the true region
  (:func:`over_reach`): a region that held the truth by reaching far beyond it would show here;
- largest gap: the longest time (ms) between two samples of the teaching. The recorder catches
  up after a stall with back-to-back reads, so the samples column hides a hole; a hole of
  ~0.3 s or more in the edge trace can cost several percent of the true region
  (docs/decisions/twist.md, "A low-coverage teaching");
- fit: the whole fit of each run's own 60 s teaching (``RigidMap(twist=True)`` on the
  three-servo recording, ``RigidMap()`` on the two-servo one, as ``limbctl train`` builds them),
  timed after both demos, interleaved, the best of FIT_REPEATS, and the ratio three / two servos
  (the issue: at most 2).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

from limbctl.demo import goal_log_excursions, run_demo, true_twist_probes
from limbctl.envelope import load_model
from limbctl.eval.twist_demo import coverage, twist_excursions, written_orientations
from limbctl.session import demo_region_path
from limbctl.teach.dataset import load_dataset

ROOT = Path(__file__).resolve().parents[1]
#: Timed fits of each teaching (the best counts: the machine is shared).
FIT_REPEATS = 3


def over_reach(model: object, region_yaml: Path, seed: int = 0) -> float:
    """Share of the learned region lying outside the true one: the directions of a 1 deg lattice
    of the learned swing region, each with a twist drawn uniformly in the learned band there,
    judged by the REGION.yaml's outline and band (pan, tilt in deg as the simulator reads them)."""
    from firmware_sim.hand import Hand
    from limbctl.geometry.gimbal import direction_to_pan_tilt
    from limbctl.region.twist_region import lattice

    region = model.region
    d = lattice(region.band, np.radians(1.0))
    d = d[region.swing.mesh.contains(d)]
    c, h = region.band.at(d)
    tau = np.degrees(c + h * np.random.default_rng(seed).uniform(-1.0, 1.0, len(d)))
    truth = Hand.from_yaml(region_yaml)
    pan, tilt = np.degrees(direction_to_pan_tilt(d))
    inside = truth.region.contains_many(pan, tilt) & np.array(
        [truth.band.contains(p, t, x) for p, t, x in zip(pan, tilt, tau, strict=True)]
    )
    return float(1.0 - inside.mean()) if len(d) else float("nan")


def fit_seconds(q2: np.ndarray, q3: np.ndarray, seed: int) -> tuple[float, float]:
    """Best seconds of the whole fit of the two-servo and the three-servo teaching, interleaved."""
    from limbctl.envelope import RigidMap

    best = [np.inf, np.inf]
    for _ in range(FIT_REPEATS):
        for k, (q, twist) in enumerate(((q2, False), (q3, True))):
            started = time.perf_counter()
            RigidMap(twist=True, seed=seed).fit(q) if twist else RigidMap(seed=seed).fit(q)
            best[k] = min(best[k], time.perf_counter() - started)
    return best[0], best[1]


def loop_rate_hz(telemetry: Path) -> float:
    """Cycles per second over the telemetry's time span."""
    times = [json.loads(line)["t"] for line in telemetry.read_text().splitlines()]
    return (len(times) - 1) / (times[-1] - times[0]) if len(times) > 1 else 0.0


def one(rig: str, seconds: float, seed: int, keep: Path | None = None) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "demo"
        started = time.perf_counter()
        with contextlib.redirect_stdout(io.StringIO()):
            status = run_demo(out, seconds, seed, rig=rig)
        wall = time.perf_counter() - started
        if keep is not None:
            # the run's files (teaching, model, logs), to analyse a surprising figure later
            shutil.copytree(out, keep / f"{rig}_seed{seed}", dirs_exist_ok=True)
        model = load_model(out / "model.npz")
        dataset = load_dataset(out / "teach.limb")
        taught = dataset.quaternions
        gap_ms = 1e3 * float(np.diff(dataset.t).max()) if len(dataset.t) > 1 else float("nan")
        over = float("nan")
        if rig == "sim3":
            excursion = twist_excursions(
                out / "goals.jsonl", model, written_orientations(out / "telemetry.jsonl")
            )
            probes = true_twist_probes(demo_region_path().with_name("demo_region3.yaml"))
            held = coverage(model, probes)
            over = over_reach(model, demo_region_path().with_name("demo_region3.yaml"), seed)
        else:
            excursion = goal_log_excursions(out / "goals.jsonl", model)
            held = float("nan")
        return {
            "rig": rig,
            "seed": seed,
            "status": status,
            "goals": len(excursion),
            "worst_deg": float(excursion.max()) if len(excursion) else 0.0,
            "held": held,
            "over": over,
            "taught": taught,
            "gap_ms": gap_ms,
            "rate_hz": loop_rate_hz(out / "telemetry.jsonl"),
            "wall_s": wall,
        }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--seeds", default="0")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "bench_twist_demo.md")
    parser.add_argument("--keep", type=Path, default=None, help="copy each run's files here")
    args = parser.parse_args()
    rows = []
    for seed in (int(s) for s in args.seeds.split(",")):
        peer = one("sim", args.seconds, seed, args.keep)
        three = one("sim3", args.seconds, seed, args.keep)
        three["ratio"] = three["rate_hz"] / peer["rate_hz"] if peer["rate_hz"] else float("nan")
        peer["fit_s"], three["fit_s"] = fit_seconds(peer["taught"], three["taught"], seed)
        three["fit_ratio"] = three["fit_s"] / peer["fit_s"]
        rows += [peer, three]
    load = os.getloadavg()
    lines = [
        "# The three-servo demo, end to end",
        "",
        f"`python benchmarks/bench_twist_demo.py --seconds {args.seconds:g} --seeds "
        f"{args.seeds}` (teaching {args.seconds:g} s per run; load average at the end "
        f"{load[0]:.1f} / {load[1]:.1f} on {os.cpu_count()} cores, shared with other work).",
        "",
        "| rig | seed | exit | samples | largest gap (ms) | goals | worst excursion (deg) "
        "| true region held (2 deg in) | learned region outside the truth | loop rate (Hz) "
        "| rate vs two servos | fit (s) | fit vs two servos |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        held = "-" if np.isnan(r["held"]) else f"{100 * r['held']:.2f} %"
        over = "-" if np.isnan(r["over"]) else f"{100 * r['over']:.2f} %"
        ratio = f"{r['ratio']:.2f}" if "ratio" in r else "(peer)"
        fit_ratio = f"**{r['fit_ratio']:.2f}**" if "fit_ratio" in r else "(peer)"
        lines.append(
            f"| {r['rig']} | {r['seed']} | {r['status']} | {len(r['taught'])} "
            f"| {r['gap_ms']:.0f} | {r['goals']} "
            f"| {r['worst_deg']:.3f} | {held} | {over} | {r['rate_hz']:.1f} | {ratio} "
            f"| {r['fit_s']:.2f} | {fit_ratio} |"
        )
    lines += [
        "",
        "The bound a written goal may lie outside the learned region: 0.072 deg with two "
        "servos, 0.108 deg with three (`limbctl.teleop.gate.written_tolerance_deg`). The "
        "issue asks for at most 0.1 deg, and for the learned region to hold 99 % or more of "
        "the true region's orientations 2 deg inside, and for the three-servo fit to take at "
        "most twice the two-servo fit of a 60 s teaching (fit columns: each run's own "
        f"teaching, the best of {FIT_REPEATS}, interleaved after the demos). A teaching "
        "recorded under heavy load holds fewer samples than 60 s at 125 Hz (samples column) "
        "and longer gaps between them (largest gap column).",
    ]
    args.out.write_text("\n".join(lines) + "\n", encoding="utf-8")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
