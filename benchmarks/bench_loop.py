"""Teleop loop rate on the simulator, and the gate's share of a cycle.

Runs the real control loop (limbctl.teleop.loop.run) through the real dynamixel-sdk against the
embedded simulator for ``--seconds`` per case, with a replayed command stream that sweeps in and
out of the region, and reports the achieved rate, cycle-time percentiles, overruns and the gate's
share of the cycle. The peer in the same run is the same loop with a pass-through gate (a model
that contains everything), so the ratio isolates what the Rigid Map gate costs. Two rigs: two
servos (the bean's models) and three (``sim3``: a fitted bay-and-band region, the sweep turning
roll too), each against its own peer.

One loop run's gate p50 moves by up to 2x between runs of the same tree on a shared machine, so
the cases run ``--repeats`` rounds, interleaved, and each figure is the median over rounds with
its spread (min-max). The gate is also timed alone (no bus, no simulator): the same commands
stepped through each case's gate, median and p99 per call, and their ratios to the pass-through
gate's in the same round.

    python benchmarks/bench_loop.py [--seconds 10] [--repeats 3] [--out docs/bench_loop.md]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from calib.profile import default_sim_profile
from limbctl.envelope import Cone, RigidMap
from limbctl.envelope.synthetic import PolygonRegion, to_quaternions
from limbctl.geometry.gimbal import pose_quat
from limbctl.jobs import gate_for
from limbctl.session import open_rig
from limbctl.teleop.loop import LoopConfig, run
from limbctl.teleop.sources import ReplaySource

#: Each rig's peer: the same loop with a model that contains everything.
PEERS = {"sim": "pass-through (peer)", "sim3": "three servos: pass-through (peer)"}


def write_stream(path: Path, seconds: float, rate_hz: float = 100.0, roll: bool = False) -> None:
    """A Lissajous sweep (pan +-100, tilt -50..70 deg; ``roll``: roll +-60 deg too) at
    ``rate_hz``, stamped with "t"."""
    n = int(seconds * rate_hz)
    with open(path, "w", encoding="utf-8") as fh:
        for i in range(n):
            t = i / rate_hz
            line = {
                "t": t,
                "pan": 100.0 * math.sin(2 * math.pi * t / 8.0),
                "tilt": 10.0 + 60.0 * math.sin(2 * math.pi * t / 5.0),
            }
            if roll:
                line["roll"] = 60.0 * math.sin(2 * math.pi * t / 3.0)
            fh.write(json.dumps(line) + "\n")


def three_servo_region() -> np.ndarray:
    """A 60 s traced teaching (N, 4) of a random outline with a bay and a notch under a twist band
    varying with pan and tilt (``tests.teleop.bays``, the seed bench_reach's timing uses)."""
    sys.path.append(str(Path(__file__).resolve().parents[1]))  # after a PYTHONPATH tree
    from tests.teleop.bays import OutlineBandRegion, teaching

    rng = np.random.default_rng(1500)
    return teaching(OutlineBandRegion.random(rng), 60.0, rng)


def run_case(model_path: Path, stream: Path, seconds: float, rig: str) -> dict:
    profile = default_sim_profile(rig)
    gate = gate_for(model_path, profile, 200.0, 120.0)
    source = ReplaySource(stream)
    source.twist = profile.roll is not None  # a three-servo rig's commands keep their roll
    with open_rig(profile=profile) as session:
        session.rig.configure()
        session.rig.set_torque(True)
        with source:
            summary = run(session.rig, gate, source, LoopConfig(rate_hz=200.0, duration_s=seconds))
    cycles = np.asarray(summary.cycle_times_s)
    gates = np.asarray(summary.gate_times_s)
    return {
        "rate_hz": summary.rate_hz,
        "p50_ms": 1e3 * float(np.percentile(cycles, 50)),
        "p99_ms": 1e3 * float(np.percentile(cycles, 99)),
        "max_ms": 1e3 * float(cycles.max()),
        "gate_p50_us": 1e6 * float(np.percentile(gates, 50)),
        "gate_p99_us": 1e6 * float(np.percentile(gates, 99)),
        "gate_share": float(gates.sum() / cycles.sum()),
        "overruns": summary.overruns,
        "cycles": summary.cycles,
        "bus_errors": summary.bus_errors,
    }


def gate_alone(model_path: Path, stream: Path, rig: str) -> tuple[float, float]:
    """Median and p99 seconds of one ``Gate.step`` over the stream's commands, no bus involved
    (the p99: the routing cycles, a few per cent of them on a held edge)."""
    gate = gate_for(model_path, default_sim_profile(rig), 200.0, 120.0)
    with open(stream, encoding="utf-8") as fh:
        keys = ("pan", "tilt", "roll") if rig == "sim3" else ("pan", "tilt")
        poses = [tuple(math.radians(c[k]) for k in keys) for c in map(json.loads, fh)]
    # the loop starts from the limb's pose, which is safe: here, the stream's first safe pose
    gate.start(*next(p for p in poses if gate.is_safe(*p)))
    targets = [pose_quat(*p) for p in poses]
    times = np.empty(len(targets))
    for k, q in enumerate(targets):
        t0 = time.perf_counter()
        gate.step(q)
        times[k] = time.perf_counter() - t0
    return float(np.median(times)), float(np.percentile(times, 99))


def spread(values: list[float], scale: float = 1.0, digits: int = 0) -> str:
    """``median (min-max)`` of ``values`` times ``scale``."""
    v = scale * np.asarray(values)
    return f"{np.median(v):.{digits}f} ({v.min():.{digits}f}-{v.max():.{digits}f})"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seconds", type=float, default=10.0, help="seconds per case and round")
    parser.add_argument(
        "--repeats", type=int, default=3, help="rounds of every case, interleaved (median shown)"
    )
    parser.add_argument("--out", type=Path, default=Path("docs/bench_loop.md"))
    args = parser.parse_args(argv)

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        streams = {"sim": tmp / "stream.jsonl", "sim3": tmp / "stream3.jsonl"}
        write_stream(streams["sim"], args.seconds + 5)
        write_stream(streams["sim3"], args.seconds + 5, roll=True)
        region = PolygonRegion()
        rng = np.random.default_rng(0)
        q_train = to_quaternions(region.sample(1000, rng))
        # 3000 samples put the learned edge past the reach of the evidence, so it is held to it:
        # an edge of thousands of short arcs, the router's slowest case
        q_held = to_quaternions(region.sample(3000, np.random.default_rng(2)))
        # each case: its model and rig (two servos, or three: sweeps roll too)
        models = {
            PEERS["sim"]: (Cone(half_angle_deg=180.0), "sim"),
            "cone 60 deg (analytic)": (Cone(half_angle_deg=60.0), "sim"),
            "Rigid Map (bean, 1000 samples)": (RigidMap(seed=0).fit(q_train), "sim"),
            "Rigid Map (bean, 3000 samples, held edge)": (RigidMap(seed=0).fit(q_held), "sim"),
            PEERS["sim3"]: (Cone(half_angle_deg=180.0), "sim3"),
            "three servos: Rigid Map (bay and band, 60 s traced)": (
                RigidMap(twist=True, seed=0).fit(three_servo_region()),
                "sim3",
            ),
        }
        paths, rigs = {}, {}
        for name, (model, rig) in models.items():
            paths[name], rigs[name] = tmp / f"{len(paths)}.npz", rig
            sim = default_sim_profile(rig)
            meta = {"rig": sim.name, "calibration": sim.calibration.to_dict()}
            model.save(paths[name], metadata=meta)
        rounds: dict[str, list[dict]] = {name: [] for name in models}
        alone: dict[str, list[float]] = {name: [] for name in models}
        alone_p99: dict[str, list[float]] = {name: [] for name in models}
        for k in range(args.repeats):
            for name, path in paths.items():
                print(f"round {k + 1}/{args.repeats}: {name} ...", file=sys.stderr)
                rig = rigs[name]
                rounds[name].append(run_case(path, streams[rig], args.seconds, rig))
                median, p99 = gate_alone(path, streams[rig], rig)
                alone[name].append(median)
                alone_p99[name].append(p99)

    load = os.getloadavg()
    lines = [
        "# Teleop loop on the simulator",
        "",
        f"Command: `python benchmarks/bench_loop.py --seconds {args.seconds:g} --repeats "
        f"{args.repeats}` ({platform.machine()}, {os.cpu_count()} cores, load average "
        f"{load[0]:.1f}/{load[1]:.1f}/{load[2]:.1f} at the end of the run).",
        "",
        "The real loop (one sync read, gate, one sync write per cycle) through the real "
        "dynamixel-sdk against `firmware-sim` in its own process, 200 Hz target, a replayed "
        "sweep that leaves the region on every side. Peer: the same loop with a model that "
        f"contains everything. Each case ran {args.repeats} rounds of {args.seconds:g} s, "
        "interleaved; each cell is the median over rounds and, in brackets, its range "
        "(overruns: the sum).",
        "",
        "| model | rate Hz | p50 ms | p99 ms | max ms | overruns | gate p50 us | gate p99 us "
        "| gate share % | p99 vs peer |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for name, rs in rounds.items():
        peer = PEERS[rigs[name]]
        ratio = [r["p99_ms"] / p["p99_ms"] for r, p in zip(rs, rounds[peer])]
        lines.append(
            f"| {name} | {spread([r['rate_hz'] for r in rs], digits=1)} | "
            f"{spread([r['p50_ms'] for r in rs], digits=2)} | "
            f"{spread([r['p99_ms'] for r in rs], digits=2)} | "
            f"{spread([r['max_ms'] for r in rs], digits=1)} | "
            f"{sum(r['overruns'] for r in rs)} | {spread([r['gate_p50_us'] for r in rs])} | "
            f"{spread([r['gate_p99_us'] for r in rs])} | "
            f"{spread([r['gate_share'] for r in rs], 100.0, 1)} | {spread(ratio, digits=2)}x |"
        )
    lines += [
        "",
        "## The gate alone",
        "",
        "Each case's gate stepped through the same commands (the stream's poses) with no bus "
        "and no simulator, once per round after its loop run: the median time of one step, "
        "and its ratio to the pass-through gate's in the same round, and the p99 of a step "
        "with its ratio to the peer's (median and range over rounds). These are the figures to "
        "compare between trees: they do not wait on the simulator's process.",
        "",
        "| model | gate step us | vs pass-through | gate step p99 us | p99 vs pass-through |",
        "|---|---|---|---|---|",
    ]
    for name, ts in alone.items():
        peer = PEERS[rigs[name]]
        ratio = [t / p for t, p in zip(ts, alone[peer])]
        tail = alone_p99[name]
        tail_ratio = [t / p for t, p in zip(tail, alone_p99[peer])]
        lines.append(
            f"| {name} | {spread(ts, 1e6, 1)} | {spread(ratio, digits=2)}x | "
            f"{spread(tail, 1e6, 0)} | {spread(tail_ratio, digits=1)}x |"
        )
    lines += [
        "",
        "Target: 200 Hz held with p99 cycle time under 5 ms. The simulator shares the two cores "
        "with the loop (and with anything else running), so these figures are upper bounds on "
        "what a quiet machine with real servos would need.",
    ]
    text = "\n".join(lines) + "\n"
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
