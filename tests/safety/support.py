"""Shared pieces of the safety campaign (tests/safety/, benchmarks/soak.py): real parts plus
observers."""

from __future__ import annotations

import functools
import json
import math
import threading
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calib import default_sim_profile
from firmware_sim import SimulatedBus
from limbctl.envelope import RigidMap
from limbctl.envelope.synthetic import BEAN, PolygonRegion, to_quaternions
from limbctl.errors import BusError
from limbctl.geometry.quat import direction_angle, limb_direction, swing_from_direction
from limbctl.servo.bus import ServoBus
from limbctl.servo.profiles import joint_tick_limits
from limbctl.servo.rig import Rig
from limbctl.teleop import gate
from limbctl.teleop.gate import Gate, GateLimits, GateResult, Outcome
from limbctl.teleop.loop import LoopConfig, Telemetry, run
from limbctl.teleop.sources import CommandSource

PROFILE = default_sim_profile()


def written_tolerance_deg(limits: GateLimits) -> float:
    """How far (deg) a written goal may lie outside the region under ``limits``."""
    extra = math.degrees(limits.region_tolerance) - gate.REGION_TOLERANCE_DEG
    return gate.written_tolerance_deg() + extra


def gate_limits(rate_hz: float = 200.0, max_speed_deg_s: float = 120.0) -> GateLimits:
    """The sim rig's hard limits and the slew limits ``limbctl teleop`` would use."""
    step = math.radians(max_speed_deg_s) / rate_hz
    return GateLimits.for_profile(PROFILE, step, max(3.0 * step, math.radians(1.0)))


@functools.cache
def bean_model(seed: int = 0, nodes: int = 300, samples: int = 2400) -> RigidMap:
    """A Rigid Map taught the kidney-shaped BEAN region (cached: fits take seconds)."""
    region = PolygonRegion(BEAN)
    q = to_quaternions(region.sample(samples, np.random.default_rng(seed)))
    return RigidMap(nodes=nodes, seed=seed).fit(q)


class RecordingGate(Gate):
    """The real :class:`Gate`, keeping every result it returned (``results``)."""

    def __init__(self, envelope, limits: GateLimits) -> None:
        super().__init__(envelope, limits)
        self.results: list[GateResult] = []

    def step(self, target_q: np.ndarray) -> GateResult:
        result = super().step(target_q)
        self.results.append(result)
        return result

    def hold(self, reason: str) -> GateResult:
        result = super().hold(reason)
        self.results.append(result)
        return result

    def produced_ticks(self, rig: Rig) -> list[tuple[int, int]]:
        """Goal ticks (pan, tilt) of every pose the gate let through, in order."""
        goals = (rig.goal_for(*r.pose) for r in self.results if r.outcome is not Outcome.HELD)
        return [g.ticks for g in goals]


class PacedSource(CommandSource):
    """A source feeding ``per_poll`` lines to the real parser per :meth:`poll` (per cycle)."""

    name = "paced"

    def __init__(self, lines: Sequence[str | bytes], per_poll: int = 1) -> None:
        super().__init__()
        self._lines = list(lines)
        self._next = 0
        self._per_poll = per_poll

    def start(self) -> None:  # no reader thread: poll feeds
        return None

    def poll(self, timeout: float = 0.0):
        for line in self._lines[self._next : self._next + self._per_poll]:
            self.feed(line)
        self._next = min(len(self._lines), self._next + self._per_poll)
        return super().poll(0.0)

    @property
    def finished(self) -> bool:
        return self._next >= len(self._lines) and self._queue.empty()


@dataclass(frozen=True)
class LoggedGoal:
    """One goal packet as the simulator received it."""

    t: float
    ticks: tuple[int, int]  # (pan, tilt) goals after this packet
    limb_dir: np.ndarray  # (3,) where the limb points once it reaches them (true geometry)


def goal_log_poses(path: Path, start_offset: int = 0) -> list[LoggedGoal]:
    """Goal packets of the simulator's goal log from byte ``start_offset``, one per ``t``."""
    goals: dict[int, int] = {}
    poses: dict[float, LoggedGoal] = {}
    with open(path, "rb") as fh:
        fh.seek(start_offset)
        for raw in fh:
            row = json.loads(raw)
            goals[row["id"]] = row["goal"]
            if PROFILE.pan.id in goals and PROFILE.tilt.id in goals:
                ticks = (goals[PROFILE.pan.id], goals[PROFILE.tilt.id])
                poses[row["t"]] = LoggedGoal(row["t"], ticks, np.asarray(row["limb_dir"]))
    return list(poses.values())


def packet_values(goal_log: Path, key: str) -> np.ndarray:
    """Each goal packet's ``key`` in the simulator's goal log, one row per packet: the last line
    of each ``t`` (a sync write's lines share it; earlier ones mix old and new goals)."""
    by_time = {}
    for line in goal_log.read_text().splitlines():
        row = json.loads(line)
        by_time[row["t"]] = row[key]
    return np.asarray(list(by_time.values()))


def packet_directions(goal_log: Path) -> np.ndarray:
    """The limb direction (M, 3) each goal packet commanded, of unit length."""
    d = packet_values(goal_log, "limb_dir")
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def excursion_deg(model, directions: np.ndarray) -> np.ndarray:
    """Angle (deg) each limb direction (N, 3) lies outside ``model``'s region (0 inside)."""
    d = np.atleast_2d(np.asarray(directions, dtype=np.float64))
    d = d / np.linalg.norm(d, axis=1, keepdims=True)
    q = swing_from_direction(d)
    inside = np.asarray(model.contains(q), dtype=bool)
    nearest = limb_direction(model.correct(q))
    return np.where(inside, 0.0, np.degrees(direction_angle(d, nearest)))


def assert_goals_safe(
    logged: list[LoggedGoal], model, limits: GateLimits, produced: list[tuple[int, int]]
) -> float:
    """Promise 1 on what reached the servos (every goal the gate's, inside the hard limits and
    the region); returns the largest excursion (deg). A servo dropping off between a read and
    the sync write mixes two consecutive gated poses: such a pair may lie a joint step out."""
    exact, pairs = set(produced), list(zip(produced, produced[1:]))
    mixes = {(b[0], a[1]) for a, b in pairs} | {(a[0], b[1]) for a, b in pairs}
    lo_pan, hi_pan = joint_tick_limits(PROFILE.pan)
    lo_tilt, hi_tilt = joint_tick_limits(PROFILE.tilt)
    mixed = []
    for goal in logged:
        if goal.ticks not in exact:
            assert goal.ticks in mixes, f"goal {goal} reached a servo but the gate never made it"
            mixed.append(goal)
        pan, tilt = goal.ticks
        assert lo_pan <= pan <= hi_pan and lo_tilt <= tilt <= hi_tilt, f"{goal} past hard limits"
    assert len(mixed) <= 2, f"{len(mixed)} mixed poses: a lost servo kept receiving writes"
    if not logged:
        return 0.0
    exact_dirs = np.array([g.limb_dir for g in logged if g.ticks in exact]).reshape(-1, 3)
    worst = float(excursion_deg(model, exact_dirs).max()) if len(exact_dirs) else 0.0
    assert worst <= written_tolerance_deg(limits), f"a goal lies {worst:.4f} deg outside"
    if mixed:
        worst_mix = float(excursion_deg(model, np.array([g.limb_dir for g in mixed])).max())
        bound = written_tolerance_deg(limits) + math.degrees(limits.max_joint_step)
        assert worst_mix <= bound, f"a mixed pose lies {worst_mix:.4f} deg outside"
    return worst


@contextmanager
def configured_rig(port: str, **bus_options) -> Iterator[Rig]:
    """The sim rig on ``port`` through the real SDK (``ServoBus`` ``bus_options``): configured,
    torque on."""
    with ServoBus.from_profile(PROFILE, port=port, **bus_options) as bus:
        rig = Rig(PROFILE, bus)
        rig.configure()
        rig.set_torque(True)
        yield rig


@contextmanager
def live_rig(goal_log: Path | None = None, **sim_options) -> Iterator[tuple[SimulatedBus, Rig]]:
    """The simulated rig through the real SDK: configured, torque on, at rest."""
    with SimulatedBus(ids=PROFILE.ids, goal_log=goal_log, **sim_options) as sim:
        with configured_rig(sim.port) as rig:
            yield sim, rig


def wait_for(condition, timeout_s: float, what: str):
    """Poll ``condition`` until it returns something true, or fail after ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    while True:
        value = condition()
        if value:
            return value
        assert time.monotonic() < deadline, f"timed out after {timeout_s} s waiting for {what}"
        time.sleep(0.01)


def settle(rig: Rig, pose: tuple[float, ...], timeout_s: float = 20.0) -> None:
    """Drive the limb ungated (set-up only) to ``pose`` (rad per joint) and wait for it; a read
    lost while the machine stalled the simulator is polled again (set-up, not what is tested)."""
    rig.write_pose(*pose)
    tol = math.radians(0.5)

    def reached() -> bool:
        try:
            present = rig.read_pose()
        except BusError:
            return False
        return all(abs(a - b) < tol for a, b in zip(present, pose, strict=True))

    wait_for(reached, timeout_s, f"the limb to reach {pose}")


class Gathered:
    """What another thread hands over (``items``, in order), and waits on it: the cycles a
    loop's ``on_cycle`` gets, the lines a source is fed."""

    def __init__(self) -> None:
        self.items: list = []
        self.changed = threading.Condition()

    def __call__(self, item) -> None:
        with self.changed:
            self.items.append(item)
            self.changed.notify_all()

    def waits(self, found, timeout_s: float):
        """``found()`` once it is true (judged with the lock held), or False after ``timeout_s``."""
        with self.changed:
            return self.changed.wait_for(found, timeout_s)


class CycleCounter(Gathered):
    """A telemetry stream keeping its rows (``items``), to wait for cycles."""

    def write(self, text: str) -> int:
        self(json.loads(text))
        return len(text)

    def flush(self) -> None:
        return None

    def wait_cycles(self, count: int, timeout_s: float = 20.0) -> None:
        ok = self.waits(lambda: len(self.items) >= count, timeout_s)
        assert ok, f"the loop did not run {count} cycles within {timeout_s} s"


class LoopThread:
    """The real loop in a thread, so a test can act while it runs; its rows in ``cycles``."""

    def __init__(self, rig: Rig, gate: RecordingGate, source, config: LoopConfig) -> None:
        self.gate = gate
        self.cycles = CycleCounter()
        self.stop = threading.Event()
        self.summary = None
        self.error: BaseException | None = None
        self._thread = threading.Thread(
            target=self._run, args=(rig, config, source), name="teleop-loop"
        )

    def _run(self, rig, config, source) -> None:
        try:
            self.summary = run(
                rig, self.gate, source, config, telemetry=Telemetry(self.cycles), stop=self.stop
            )
        except BaseException as exc:  # raised again by join/__exit__
            self.error = exc
            raise

    def __enter__(self) -> LoopThread:
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self.stop.set()
        self.join()

    def join(self, timeout_s: float = 60.0) -> None:
        self._thread.join(timeout=timeout_s)
        assert not self._thread.is_alive(), f"the loop did not end within {timeout_s} s"
        if self.error is not None:
            raise self.error
