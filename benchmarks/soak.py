"""The long-run soak (promise 5 of docs/safety.md): a million gated cycles with faults sprinkled in.

Two parts, both with every promise checked on every cycle:

1. compressed time: the product model (a Rigid Map taught the BEAN region), the real Gate and
   the Rig's angle -> tick conversion, driven as fast as the CPU allows through a seeded
   schedule of segments: a wandering command stream that leaves the region, a fixed command
   inside and one outside (no creep allowed once reached), silence (the pose must be held to
   the tick), malformed/hostile lines (refused and counted), and bus-fault stretches (the loop
   holds on a failed read, so the gate holds). Resident memory is read from /proc/self/statm.
2. real time: the real control loop against the simulator over the real SDK at 500 Hz for a
   while, the simulator's faults switched every half second (drops, corruption, latency past
   the cycle budget, a servo vanishing briefly); judged by the simulator's goal log, then the
   held pose is compared with the servos' true positions.

Usage (the full soak; about 5-10 minutes on one core)::

    .venv/bin/python benchmarks/soak.py --cycles 1000000 --live-seconds 60 --out docs/soak.md

tests/safety/test_soak.py runs the same code in a reduced form.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import tempfile
import threading
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from calib import default_sim_profile
from limbctl.envelope import RigidMap
from limbctl.envelope.synthetic import BEAN, PolygonRegion, to_quaternions
from limbctl.errors import InvalidInputError
from limbctl.geometry.gimbal import pan_tilt_to_direction
from limbctl.geometry.quat import direction_angle, limb_direction, swing_from_direction
from limbctl.servo.profiles import joint_tick_limits
from limbctl.servo.rig import Rig
from limbctl.teleop.commands import parse_command
from limbctl.teleop.gate import Gate, GateLimits, Outcome

PROFILE = default_sim_profile()
#: Most a half-tick rounding of both joints moves the limb direction (deg).
ROUNDING_DEG = math.sqrt(2.0) * 360.0 / 4096 / 2
BAD_LINES = [
    '{"pan": NaN, "tilt": 0}',
    '{"pan": 1e999, "tilt": 0}',
    '{"pan": 1' + "0" * 400 + ', "tilt": 0}',
    '{"dir": [5e-324, 0, 0]}',
    '{"q": [2, 0, 0, 0]}',
    '{"pan": "10", "tilt": 0}',
    '{"pan": 10, "tilt": 5, "gate": false}',
    "not json",
    "\x00\xff",
]
SEGMENTS = ("walk", "fixed-inside", "fixed-outside", "silent", "bad", "bus-fault")


def rss_bytes() -> int:
    """Resident set size of this process (bytes), from /proc/self/statm."""
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def product_model(seed: int = 0) -> RigidMap:
    """A Rigid Map taught the BEAN region (800 hand-like samples, 300 nodes)."""
    q = to_quaternions(PolygonRegion(BEAN).sample(800, np.random.default_rng(seed)))
    return RigidMap(nodes=300, seed=seed).fit(q)


def limits_for(rate_hz: float = 200.0, max_speed_deg_s: float = 120.0) -> GateLimits:
    step = math.radians(max_speed_deg_s) / rate_hz
    return GateLimits.for_profile(PROFILE, step, max(3.0 * step, math.radians(1.0)))


def excursion_deg(model, d: np.ndarray) -> float:
    """Angle (deg) one limb direction (3,) lies outside ``model``'s region (0 inside)."""
    q = swing_from_direction(d)
    if model.contains(q):
        return 0.0
    return math.degrees(float(direction_angle(d, limb_direction(model.correct(q)))))


@dataclass
class CompressedResult:
    cycles: int = 0
    commands: int = 0
    refused: int = 0
    goals_checked: int = 0
    held_cycles: int = 0
    fault_cycles: int = 0
    segments: int = 0
    worst_excursion_deg: float = 0.0
    tolerance_deg: float = 0.0
    limit_violations: int = 0
    unsafe_goals: int = 0
    hold_checks: int = 0
    held_drift_ticks: int = 0
    rss_after_warmup_mb: float = 0.0
    rss_end_mb: float = 0.0
    rss_growth_mb: float = 0.0
    seconds: float = 0.0


def compressed_soak(cycles: int, seed: int = 0, model=None) -> CompressedResult:
    """Run ``cycles`` gated cycles in process (see the module docstring)."""
    model = model if model is not None else product_model(seed)
    limits = limits_for()
    tolerance = math.degrees(limits.region_tolerance) + ROUNDING_DEG
    rig = Rig(PROFILE)
    gate = Gate(model, limits)
    gate.start(0.0, 0.0)
    rng = np.random.default_rng(seed)
    inside = PolygonRegion(BEAN).sample(256, rng)
    lo_pan, hi_pan = joint_tick_limits(PROFILE.pan)
    lo_tilt, hi_tilt = joint_tick_limits(PROFILE.tilt)
    out = CompressedResult(tolerance_deg=tolerance)
    last_ticks = rig.goal_for(0.0, 0.0).ticks
    warmup = max(1, cycles // 20)
    start = time.perf_counter()
    done = 0
    while done < cycles:
        kind = SEGMENTS[int(rng.integers(len(SEGMENTS)))]
        length = int(min(cycles - done, rng.integers(50, 2000)))
        out.segments += 1
        fixed = None
        if kind == "fixed-inside":
            d = inside[int(rng.integers(len(inside)))]
            fixed = json.dumps({"dir": [float(v) for v in d]})
        elif kind == "fixed-outside":
            pan, tilt = rng.uniform(-115, 115), rng.uniform(-55, 70)
            fixed = json.dumps({"pan": float(pan), "tilt": float(tilt)})
        settled: tuple[int, int] | None = None
        target = None
        for i in range(length):
            line = None
            if kind == "walk" and i % 20 == 0:
                pan, tilt = rng.uniform(-150, 150), rng.uniform(-85, 85)
                line = json.dumps({"pan": float(pan), "tilt": float(tilt)})
            elif kind == "bad" and i % 5 == 0:
                line = BAD_LINES[int(rng.integers(len(BAD_LINES)))]
            elif fixed is not None:
                line = fixed
            if line is not None:
                try:
                    target = parse_command(line).q
                    out.commands += 1
                except InvalidInputError:
                    out.refused += 1
            if kind in ("silent", "bus-fault") or target is None:
                result = gate.hold("silent" if kind == "silent" else "bus failed")
                out.fault_cycles += kind == "bus-fault"
            else:
                result = gate.step(target)
            if result.outcome is Outcome.HELD:
                out.held_cycles += 1
                # a hold writes nothing: the servos keep the last goal; the gate must agree
                now = rig.goal_for(*gate.safe_pose)
                out.hold_checks += 1
                drift = max(abs(now.ticks[0] - last_ticks[0]), abs(now.ticks[1] - last_ticks[1]))
                out.held_drift_ticks = max(out.held_drift_ticks, drift)
            else:
                goal = rig.goal_for(*result.pose)
                ticks = goal.ticks
                if goal.clamped or not (
                    lo_pan <= ticks[0] <= hi_pan and lo_tilt <= ticks[1] <= hi_tilt
                ):
                    out.limit_violations += 1
                pan, tilt = rig.ticks_to_angles(*ticks)
                worst = excursion_deg(model, pan_tilt_to_direction(pan, tilt))
                out.worst_excursion_deg = max(out.worst_excursion_deg, worst)
                out.unsafe_goals += worst > tolerance
                out.goals_checked += 1
                # a fixed command, once reached, must not creep
                if fixed is not None and not result.slewed:
                    if settled is None:
                        settled = ticks
                    else:
                        out.hold_checks += 1
                        drift = max(abs(ticks[0] - settled[0]), abs(ticks[1] - settled[1]))
                        out.held_drift_ticks = max(out.held_drift_ticks, drift)
                last_ticks = ticks
            done += 1
            if done == warmup:
                out.rss_after_warmup_mb = rss_bytes() / 1e6
    out.cycles = done
    out.seconds = time.perf_counter() - start
    out.rss_end_mb = rss_bytes() / 1e6
    out.rss_growth_mb = out.rss_end_mb - out.rss_after_warmup_mb
    return out


@dataclass
class LiveResult:
    cycles: int = 0
    seconds: float = 0.0
    goals_logged: int = 0
    worst_excursion_deg: float = 0.0
    missed_writes: int = 0
    worst_mixed_excursion_deg: float = 0.0
    limit_violations: int = 0
    bus_errors: int = 0
    cycles_lost: int = 0
    faults_injected: int = 0
    vanishes: int = 0
    ended_by: str = ""
    held_error_ticks: int = 0
    rss_growth_mb: float = 0.0
    mixed_bound_deg: float = 0.0


def live_soak(seconds: float, seed: int = 0, model=None, rate_hz: float = 500.0) -> LiveResult:
    """The real loop against the simulator for ``seconds``, faults switched every 0.5 s."""
    from firmware_sim import SimulatedBus
    from limbctl.servo.bus import ServoBus
    from limbctl.teleop.loop import LoopConfig, run
    from limbctl.teleop.sources import ReplaySource

    model = model if model is not None else product_model(seed)
    limits = limits_for(rate_hz, 240.0)
    rng = np.random.default_rng(seed)
    out = LiveResult()
    with tempfile.TemporaryDirectory() as folder:
        log, commands = Path(folder) / "goals.jsonl", Path(folder) / "commands.jsonl"
        n = int(seconds * rate_hz)
        t = np.arange(n) / rate_hz
        pan = 80.0 * np.sin(2 * math.pi * t / 6.0)
        tilt = -5.0 + 45.0 * np.sin(2 * math.pi * t / 2.5)
        with open(commands, "w") as fh:
            for i in range(n):
                fh.write(json.dumps({"pan": float(pan[i]), "tilt": float(tilt[i])}) + "\n")
                if i % 97 == 0:
                    fh.write(BAD_LINES[i % len(BAD_LINES)] + "\n")
        with SimulatedBus(ids=PROFILE.ids, goal_log=log, seed=seed) as sim:
            with ServoBus.from_profile(PROFILE, port=sim.port) as bus:
                rig = Rig(PROFILE, bus)
                rig.configure()
                rig.set_torque(True)
                stop = threading.Event()

                def sprinkle() -> None:
                    plans = [
                        {"drop": 0.05},
                        {"corrupt": 0.03},
                        {"latency_ms": 4.0, "latency_p": 0.2},
                        {},
                    ]
                    while not stop.wait(0.5):
                        plan = plans[int(rng.integers(len(plans)))]
                        sim.set_faults(seed=int(rng.integers(2**31)), **plan)
                        out.faults_injected += bool(plan)
                        if rng.random() < 0.2:
                            sim.vanish(int(rng.integers(1, 3)), 0.02)
                            out.vanishes += 1

                rss0 = rss_bytes()
                thread = threading.Thread(target=sprinkle, name="fault-sprinkler")
                thread.start()
                try:
                    with ReplaySource(commands, rate_hz=rate_hz) as source:
                        config = LoopConfig(rate_hz=rate_hz, max_failed_cycles=50)
                        summary = run(rig, Gate(model, limits), source, config)
                finally:
                    stop.set()
                    thread.join()
                    sim.set_faults()
                out.rss_growth_mb = (rss_bytes() - rss0) / 1e6
                # the held pose: let the servos settle on the last goal, compare with truth
                deadline = time.monotonic() + 5.0
                while time.monotonic() < deadline:
                    truth = sim.truth()["servos"]
                    errors = [abs(s["raw_tick"] - s["setpoint"]) for s in truth.values()]
                    if max(errors) < 2.0:
                        break
                goals = {i: s["goal_position"] for i, s in truth.items()}
                present = rig.read_ticks()
                out.held_error_ticks = max(
                    abs(present[0] - goals[PROFILE.pan.id]),
                    abs(present[1] - goals[PROFILE.tilt.id]),
                )
        out.cycles, out.seconds = summary.cycles, summary.elapsed_s
        out.bus_errors, out.cycles_lost, out.ended_by = (
            summary.bus_errors,
            summary.failed_cycles,
            summary.ended_by,
        )
        # a packet logs one line per servo that got it; a servo that vanished in that instant
        # misses it and the pose mixes two consecutive gated poses (docs/safety.md, promise 1)
        by_time: dict[float, dict] = {}
        heard: dict[float, set] = {}
        for raw in log.read_text().splitlines():
            row = json.loads(raw)
            by_time[row["t"]] = row
            heard.setdefault(row["t"], set()).add(row["id"])
        lo_pan, hi_pan = joint_tick_limits(PROFILE.pan)
        lo_tilt, hi_tilt = joint_tick_limits(PROFILE.tilt)
        goals_now: dict[int, int] = {}
        for raw in log.read_text().splitlines():
            row = json.loads(raw)
            goals_now[row["id"]] = row["goal"]
            g1, g2 = goals_now.get(PROFILE.pan.id), goals_now.get(PROFILE.tilt.id)
            if g1 is not None and g2 is not None:
                out.limit_violations += not (lo_pan <= g1 <= hi_pan and lo_tilt <= g2 <= hi_tilt)
        out.goals_logged = len(by_time)
        for t, row in by_time.items():
            d = np.asarray(row["limb_dir"], dtype=np.float64)
            worst = excursion_deg(model, d / np.linalg.norm(d))
            if heard[t] == set(PROFILE.ids):
                out.worst_excursion_deg = max(out.worst_excursion_deg, worst)
            else:
                out.missed_writes += 1
                out.worst_mixed_excursion_deg = max(out.worst_mixed_excursion_deg, worst)
        out.mixed_bound_deg = math.degrees(limits.region_tolerance + limits.max_joint_step)
    return out


def write_report(path: Path, compressed: CompressedResult, live: LiveResult | None) -> None:
    lines = [
        "# Soak results (benchmarks/soak.py)",
        "",
        "Written by `.venv/bin/python benchmarks/soak.py` on "
        f"{time.strftime('%Y-%m-%d %H:%M')}; see docs/safety.md for what each promise means.",
        "",
        "## Compressed time: Gate + Rig tick conversion + Rigid Map (BEAN), in process",
        "",
        "| figure | value |",
        "|---|---|",
    ]
    lines += [f"| {k.replace('_', ' ')} | {_fmt(v)} |" for k, v in asdict(compressed).items()]
    if live is not None:
        lines += [
            "",
            "## Real time: the control loop on the simulator, faults switched every 0.5 s",
            "",
            "| figure | value |",
            "|---|---|",
        ]
        lines += [f"| {k.replace('_', ' ')} | {_fmt(v)} |" for k, v in asdict(live).items()]
    path.write_text("\n".join(lines) + "\n")


def _fmt(value) -> str:
    return f"{value:.4g}" if isinstance(value, float) else str(value)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cycles", type=int, default=1_000_000, help="compressed-time cycles")
    parser.add_argument("--live-seconds", type=float, default=60.0, help="0 skips the live part")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=Path("docs/soak.md"))
    args = parser.parse_args()
    model = product_model(args.seed)
    compressed = compressed_soak(args.cycles, args.seed, model)
    print(json.dumps(asdict(compressed), indent=1))
    live = live_soak(args.live_seconds, args.seed, model) if args.live_seconds > 0 else None
    if live is not None:
        print(json.dumps(asdict(live), indent=1))
    write_report(args.out, compressed, live)
    print(f"wrote {args.out}")
    ok = compressed.unsafe_goals == 0 and compressed.limit_violations == 0
    ok &= compressed.held_drift_ticks == 0
    if live is not None:
        ok &= live.limit_violations == 0 and live.worst_excursion_deg <= compressed.tolerance_deg
        ok &= live.worst_mixed_excursion_deg <= live.mixed_bound_deg + ROUNDING_DEG
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
