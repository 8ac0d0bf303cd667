"""CPU cost of the simulated world: plain-float stepping versus the same physics on numpy arrays.

Run: ``.venv/bin/python benchmarks/bench_world.py`` (writes docs/bench_world.md).

The servo layer steps the world in 1 ms substeps, so one simulated second is 1000 calls of
``World.step``. Measured here, in one run, as CPU time per simulated second:

- torque on, both joints tracking a sinusoidal setpoint;
- torque off, the irregular region's hand backdriving both joints;
- the peer: the torque-on update of ``World._substep`` written on (2,) numpy arrays (the obvious
  vectorised form), checked to produce the same trajectory.

The budget is 20 ms of CPU per simulated second per process.
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np

from firmware_sim import world as w
from firmware_sim.hand import Hand
from firmware_sim.world import DEFAULT_JOINTS, World

ROOT = Path(__file__).resolve().parents[1]
PAN, TILT = DEFAULT_JOINTS


def setpoints(k: int) -> dict[int, float]:
    """Raw ticks for both joints at step ``k``: a 0.5 Hz sweep of +-40 deg and +-25 deg."""
    phase = 2.0 * math.pi * 0.5 * k * 0.001
    return {1: PAN.raw_tick(math.radians(40.0) * math.sin(phase)),
            2: TILT.raw_tick(math.radians(25.0) * math.sin(phase))}  # fmt: skip


class NumpyTracking:
    """The torque-on branch of ``World._substep`` on (2,) arrays: the peer."""

    def __init__(self) -> None:
        self.zero = np.array([PAN.zero_tick, TILT.zero_tick])
        self.direction = np.array([PAN.direction, TILT.direction], dtype=np.float64)
        self.lo = np.radians([PAN.stop_min_deg, TILT.stop_min_deg])
        self.hi = np.radians([PAN.stop_max_deg, TILT.stop_max_deg])
        self.free = np.zeros(2)
        self.velocity = np.zeros(2)
        self.angle = np.zeros(2)
        self.load = np.zeros(2)

    def step(self, h: float, drive: dict[int, float]) -> None:
        target = self.direction * (np.array([drive[1], drive[2]]) - self.zero) * w.RAD_PER_TICK
        omega = w.TRACKING_OMEGA_RAD_S
        accel = np.clip(omega * (omega * (target - self.free) - 2.0 * self.velocity),
                        -w.MAX_ACCEL_RAD_S2, w.MAX_ACCEL_RAD_S2)  # fmt: skip
        new_velocity = np.clip(self.velocity + accel * h, -w.MAX_SPEED_RAD_S, w.MAX_SPEED_RAD_S)
        accel = (new_velocity - self.velocity) / h
        self.free = self.free + new_velocity * h
        self.velocity = new_velocity
        self.angle = np.clip(self.free, self.lo, self.hi)
        stiffness = w.STIFFNESS_PCT_PER_DEG * 180.0 / math.pi
        self.load = np.clip(stiffness * (self.free - self.angle)
                            + w.INERTIA_PCT_PER_RAD_S2 * accel
                            + w.VISCOUS_PCT_PER_RAD_S * new_velocity,
                            -w.LOAD_LIMIT_PCT, w.LOAD_LIMIT_PCT)  # fmt: skip


def cpu_ms_per_sim_second(step, seconds: float) -> float:
    steps = round(seconds * 1000)
    start = time.process_time()
    for k in range(steps):
        step(k)
    return (time.process_time() - start) * 1000.0 / seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=20.0, help="simulated seconds per case")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "bench_world.md")
    args = parser.parse_args()

    held = World(seed=0)
    held.step(0.001, {1: held.raw_tick(1), 2: held.raw_tick(2)})  # take hold where it rests
    peer = NumpyTracking()
    peer.free[:] = peer.angle[:] = [math.radians(a) for a in held.joint_angles_deg().values()]
    # same physics: the two trajectories agree before timing anything
    for k in range(2000):
        held.step(0.001, setpoints(k))
        peer.step(0.001, setpoints(k))
    gap = max(abs(held.raw_tick(1) - PAN.raw_tick(peer.angle[0])),
              abs(held.raw_tick(2) - TILT.raw_tick(peer.angle[1])))  # fmt: skip
    assert gap < 1e-6, f"peer diverged by {gap} ticks"

    on = cpu_ms_per_sim_second(lambda k: held.step(0.001, setpoints(k)), args.seconds)
    numpy_on = cpu_ms_per_sim_second(lambda k: peer.step(0.001, setpoints(k)), args.seconds)
    hand = Hand.from_yaml(ROOT / "examples" / "regions" / "irregular.yaml", seed=0)
    free = World(hand=hand, seed=0)
    off = cpu_ms_per_sim_second(lambda k: free.step(0.001, {1: None, 2: None}), args.seconds)
    setpoint_cost = cpu_ms_per_sim_second(lambda k: setpoints(k), args.seconds)

    rows = [
        ("World.step, torque on, tracking", on),
        ("World.step, torque off, irregular.yaml hand", off),
        ("peer: same tracking on numpy arrays", numpy_on),
        ("(the benchmark's setpoint generator alone)", setpoint_cost),
    ]
    lines = [
        "# Simulated world stepping cost",
        "",
        f"`benchmarks/bench_world.py --seconds {args.seconds:g}`: CPU ms per simulated second "
        "(1000 steps of 1 ms), one process. Budget: 20 ms.",
        "",
        "| case | CPU ms / simulated s | x real time |",
        "| --- | ---: | ---: |",
    ]
    lines += [f"| {name} | {ms:.2f} | {1000.0 / ms:.0f} |" for name, ms in rows]
    lines += [
        "",
        f"Plain floats versus numpy arrays for the same update: numpy is {numpy_on / on:.1f}x "
        "slower at two joints (per-call array overhead dominates the arithmetic).",
        "",
    ]
    args.out.write_text("\n".join(lines))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
