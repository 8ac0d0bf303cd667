"""A digest of every goal the gate writes over fixed sweeps: does a change keep the gate's output?

Run it on two trees and compare the digests (equal: the same poses, bit for bit, cycle by cycle):

    PYTHONPATH=OTHER_CHECKOUT .venv/bin/python benchmarks/gate_trace.py
    .venv/bin/python benchmarks/gate_trace.py

Cases: two servos, bench_loop's sweep (pan +-100, tilt -50..70 deg) through Rigid Maps of the
bean (1000 samples, and 3000 whose edge is held to the evidence: the router's busiest case);
three servos, the same sweep with roll +-60 deg through Rigid Maps fitted to 60 s traced
teachings of random bay-and-band regions (``tests.teleop.bays``). Each line: the case, its
digest, how many cycles routed, and the gate step's p50 / p99 (us, wall clock: noisy, for a
glance only; bench_loop is the timing benchmark).
"""

from __future__ import annotations

import hashlib
import math
import sys
import time
from pathlib import Path

import numpy as np

from calib.profile import default_sim_profile
from limbctl.envelope import RigidMap
from limbctl.envelope.synthetic import PolygonRegion, to_quaternions
from limbctl.geometry.gimbal import pose_quat
from limbctl.teleop.gate import Gate, GateLimits

#: Cycles of each sweep: 15 s at 200 Hz, five tilt periods.
CYCLES = 3000
#: Seeds of the three-servo regions (bench_loop's is 1500; the tests use 0-99).
THREE_SERVO_SEEDS = (1500, 1501, 1502)


def sweep(roll: bool) -> list[np.ndarray]:
    """Commanded orientations (4,) of the sweep, one per 5 ms cycle."""
    out = []
    for i in range(CYCLES):
        t = i / 200.0
        pose = [
            math.radians(100.0 * math.sin(2 * math.pi * t / 8.0)),
            math.radians(10.0 + 60.0 * math.sin(2 * math.pi * t / 5.0)),
        ]
        if roll:
            pose.append(math.radians(60.0 * math.sin(2 * math.pi * t / 3.0)))
        out.append(pose_quat(*pose))
    return out


def trace(model, rig: str, commands: list[np.ndarray]) -> tuple[str, int, float, float]:
    """Digest of the written poses, cycles routed, step p50 and p99 (us)."""
    profile = default_sim_profile(rig)
    step = math.radians(120.0) / 200.0  # limbctl teleop's defaults: 120 deg/s at 200 Hz
    gate = Gate(model, GateLimits.for_profile(profile, step, max(3 * step, math.radians(1.0))))
    # the first safe pose of a coarse grid (pan, tilt; roll 0), as a limb placed inside
    grid = [(p, t) for p in range(-60, 61, 10) for t in range(-40, 61, 10)]
    extra = (0.0,) if rig == "sim3" else ()
    start = next(
        pose
        for pose in ((math.radians(p), math.radians(t), *extra) for p, t in grid)
        if gate.is_safe(*pose)
    )
    gate.start(*start)
    digest, times, routed = hashlib.sha1(), [], 0
    for q in commands:
        t0 = time.perf_counter()
        result = gate.step(q)
        times.append(time.perf_counter() - t0)
        digest.update(np.asarray(result.pose, dtype=np.float64).tobytes())
        routed += gate.router._engaged is not None
    us = 1e6 * np.asarray(times)
    return digest.hexdigest(), routed, float(np.median(us)), float(np.percentile(us, 99))


def main() -> int:
    sys.path.append(str(Path(__file__).resolve().parents[1]))  # after a PYTHONPATH tree
    from tests.teleop.bays import OutlineBandRegion, teaching

    bean = PolygonRegion()
    bean_seeds = {"two servos, bean 1000": (1000, 0), "two servos, bean 3000 (held)": (3000, 2)}
    for name, (count, seed) in bean_seeds.items():
        model = RigidMap(seed=0).fit(
            to_quaternions(bean.sample(count, np.random.default_rng(seed)))
        )
        print(name, *trace(model, "sim", sweep(False)), flush=True)
    for seed in THREE_SERVO_SEEDS:
        rng = np.random.default_rng(seed)
        model = RigidMap(twist=True, seed=0).fit(teaching(OutlineBandRegion.random(rng), 60.0, rng))
        print(f"three servos, bay and band {seed}", *trace(model, "sim3", sweep(True)), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
