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
  its ratio to the two-servo peer's in the same run.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from limbctl.demo import goal_log_excursions, run_demo, true_twist_probes
from limbctl.envelope import load_model
from limbctl.eval.twist_demo import coverage, twist_excursions, written_orientations
from limbctl.session import demo_region_path

ROOT = Path(__file__).resolve().parents[1]


def loop_rate_hz(telemetry: Path) -> float:
    """Cycles per second over the telemetry's time span."""
    times = [json.loads(line)["t"] for line in telemetry.read_text().splitlines()]
    return (len(times) - 1) / (times[-1] - times[0]) if len(times) > 1 else 0.0


def one(rig: str, seconds: float, seed: int) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "demo"
        started = time.perf_counter()
        with contextlib.redirect_stdout(io.StringIO()):
            status = run_demo(out, seconds, seed, rig=rig)
        wall = time.perf_counter() - started
        model = load_model(out / "model.npz")
        if rig == "sim3":
            excursion = twist_excursions(
                out / "goals.jsonl", model, written_orientations(out / "telemetry.jsonl")
            )
            probes = true_twist_probes(demo_region_path().with_name("demo_region3.yaml"))
            held = coverage(model, probes)
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
            "rate_hz": loop_rate_hz(out / "telemetry.jsonl"),
            "wall_s": wall,
        }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--seeds", default="0")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "bench_twist_demo.md")
    args = parser.parse_args()
    rows = []
    for seed in (int(s) for s in args.seeds.split(",")):
        peer = one("sim", args.seconds, seed)
        three = one("sim3", args.seconds, seed)
        three["ratio"] = three["rate_hz"] / peer["rate_hz"] if peer["rate_hz"] else float("nan")
        rows += [peer, three]
    load = os.getloadavg()
    lines = [
        "# The three-servo demo, end to end",
        "",
        f"`python benchmarks/bench_twist_demo.py --seconds {args.seconds:g} --seeds "
        f"{args.seeds}` (teaching {args.seconds:g} s per run; load average at the end "
        f"{load[0]:.1f} / {load[1]:.1f} on {os.cpu_count()} cores, shared with other work).",
        "",
        "| rig | seed | exit | goals | worst excursion (deg) | true region held (2 deg in) "
        "| loop rate (Hz) | rate vs two servos |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        held = "-" if np.isnan(r["held"]) else f"{100 * r['held']:.2f} %"
        ratio = f"{r['ratio']:.2f}" if "ratio" in r else "(peer)"
        lines.append(
            f"| {r['rig']} | {r['seed']} | {r['status']} | {r['goals']} | {r['worst_deg']:.3f} "
            f"| {held} | {r['rate_hz']:.1f} | {ratio} |"
        )
    lines += [
        "",
        "The bound a written goal may lie outside the learned region: 0.072 deg with two "
        "servos, 0.108 deg with three (`limbctl.teleop.gate3.written_tolerance_deg3`). The "
        "issue asks for at most 0.1 deg, and for the learned region to hold 99 % or more of "
        "the true region's orientations 2 deg inside.",
    ]
    args.out.write_text("\n".join(lines) + "\n", encoding="utf-8")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
