"""The wire's speed on the strict simulator: the teleop loop's rate by baud, and scan times.

1. The real loop (limbctl.teleop.loop.run, 200 Hz target, a pass-through gate) through the real
   dynamixel-sdk against the embedded simulator with its servos at each baud rate for
   ``--seconds``. The peer in the same run is the wire's arithmetic: one cycle puts
   ``limbctl.servo.cycle.cycle_wire_bytes(2)`` bytes on the wire, 10 bits each, so the loop
   cannot run faster than ``baud / (10 * bytes)`` Hz; the table gives measured / expected with
   expected = min(200 Hz, that bound).
2. ``limbctl motors scan`` (limbctl.servo.scan.scan) over every baud rate on a bus of two
   factory-fresh servos and on the simulated rig: seconds per baud rate.

    python benchmarks/bench_wire.py [--seconds 10] [--out docs/bench_wire.md]
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import tempfile
from pathlib import Path

import numpy as np

from benchmarks.bench_loop import write_stream
from calib.profile import default_sim_profile
from firmware_sim import SimulatedBus
from limbctl.envelope import Cone
from limbctl.jobs import gate_for
from limbctl.servo.cycle import BITS_PER_BYTE, cycle_wire_bytes, wire_budget
from limbctl.servo.scan import scan
from limbctl.session import open_rig
from limbctl.teleop.loop import LoopConfig, run
from limbctl.teleop.sources import ReplaySource

RATE_HZ = 200.0
BAUDS = (57_600, 115_200, 1_000_000, 4_000_000)
#: Latency timer the loop assumes (ms): an FTDI adapter's default.
LATENCY_TIMER_MS = 16.0


def loop_case(model: Path, stream: Path, baud: int, seconds: float) -> dict:
    profile = default_sim_profile()
    gate = gate_for(model, profile, RATE_HZ, 120.0)
    # the FTDI's default latency timer: on a machine as loaded as a shared CI box the
    # simulator's replies can come 30 ms late, and a shorter wait takes a late reply for the
    # next request's
    with open_rig(baud=baud, latency_timer_ms=LATENCY_TIMER_MS) as session:
        session.rig.configure()
        session.rig.set_torque(True)
        bus = session.rig.bus
        fast = bool(bus.fast_sync_read)
        with ReplaySource(stream) as source:
            summary = run(
                session.rig, gate, source, LoopConfig(rate_hz=RATE_HZ, duration_s=seconds)
            )
    count = cycle_wire_bytes(len(profile.ids), fast)
    # the wire's bound: baud / (10 bits * bytes) cycles a second
    bound = baud / (BITS_PER_BYTE * count)
    expected = min(RATE_HZ, bound)
    cycles = np.asarray(summary.cycle_times_s)
    return {
        "baud": baud,
        "bytes": count,
        "bound_hz": bound,
        "rate_hz": summary.rate_hz,
        "ratio": summary.rate_hz / expected,
        "p50_ms": 1e3 * float(np.percentile(cycles, 50)),
        "warned": bool(wire_budget(RATE_HZ, baud, len(profile.ids), fast)),
    }


def scan_case(label: str, **sim_options) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        with SimulatedBus(link=Path(tmp) / "tty", **sim_options) as sim:
            result = scan(sim.port, latency_timer_ms=2.0)
    return {"label": label, "seconds": result.seconds, "report": result.report()}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--out", type=Path, default=Path("docs/bench_wire.md"))
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        sim = default_sim_profile()
        model = Path(tmp) / "all.npz"
        metadata = {"rig": sim.name, "calibration": sim.calibration.to_dict()}
        Cone(half_angle_deg=180.0).save(model, metadata=metadata)  # the pass-through gate
        stream = Path(tmp) / "sweep.jsonl"
        write_stream(stream, args.seconds + 5.0)
        loops = [loop_case(model, stream, baud, args.seconds) for baud in BAUDS]
    scans = [
        scan_case("two factory-fresh servos (both ID 1 at 57600)", factory=2),
        scan_case("the simulated rig (IDs 1, 2 at 4000000)", ids=(1, 2)),
    ]
    load = ", ".join(f"{v:.1f}" for v in os.getloadavg())
    lines = [
        "# The wire on the strict simulator",
        "",
        f"Command: `python benchmarks/bench_wire.py --seconds {args.seconds:g}` "
        f"({platform.machine()}, {os.cpu_count()} cores, load average {load} at the end).",
        "",
        "## Teleop loop rate by baud",
        "",
        "The real loop at a 200 Hz target against the embedded simulator whose servos run at "
        "each baud rate (bytes take 10 bit times each on the modelled wire). Peer: the wire's "
        "arithmetic, expected = min(200 Hz, baud / (10 x bytes per cycle)). Latency timer "
        f"{LATENCY_TIMER_MS:g} ms (an FTDI's default).",
        "",
        "| baud | bytes a cycle | wire bound Hz | measured Hz | measured / expected | "
        "p50 cycle ms | limbctl warns |",
        "|---|---|---|---|---|---|---|",
    ]
    for c in loops:
        lines.append(
            f"| {c['baud']} | {c['bytes']} | {c['bound_hz']:.1f} | {c['rate_hz']:.1f} | "
            f"{c['ratio']:.2f} | {c['p50_ms']:.2f} | {'yes' if c['warned'] else 'no'} |"
        )
    lines += ["", "## Scan: seconds per baud rate", ""]
    for s in scans:
        cells = ", ".join(f"{baud}: {sec:.2f}" for baud, sec in s["seconds"].items())
        lines += [f"- {s['label']}: {cells}", "", "```", s["report"], "```", ""]
    args.out.write_text("\n".join(lines) + "\n", encoding="utf-8")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
