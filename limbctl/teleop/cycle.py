"""What the control loop returns: a :class:`Cycle` a cycle, a :class:`TeleopSummary` a session."""

from __future__ import annotations

import enum
import math
from collections import Counter, deque
from dataclasses import dataclass, field

import numpy as np

from limbctl.geometry.gimbal import (
    pan_tilt_roll_scalar,
    pan_tilt_to_quat,
    pose_quat_scalar,
    quat_to_pan_tilt,
)
from limbctl.geometry.twist import decompose_one
from limbctl.servo.health import Dropout
from limbctl.teleop.gate import GateResult

#: Latest cycle and gate times kept for the percentiles: over 8 minutes at 200 Hz, bounded.
TIMING_WINDOW = 100_000
#: Health notices kept for the summary: the latest ones; a flapping cable must not grow memory.
NOTICE_WINDOW = 1000
#: A command's roll is read within [-PI, PI] (rad), nearest the written roll: a whole turn.
PI = math.pi


def _degrees(pose: tuple[float, ...]) -> list[float]:
    return [round(math.degrees(v), 4) for v in pose]


def _quaternion(q: np.ndarray) -> list[float]:
    return [round(float(v), 6) for v in q]


def _pose_quaternion(pose: tuple[float, ...]) -> np.ndarray:
    """The orientation (4,) of joint angles (rad): (pan, tilt) or (pan, tilt, roll)."""
    if len(pose) == 3:
        return pose_quat_scalar(*pose)
    return pan_tilt_to_quat(np.float64(pose[0]), np.float64(pose[1]))


def _twist_deg(q: np.ndarray) -> float:
    """The twist (deg) of ``q`` about the rest axis: ``q = swing(d) twist(tau)``."""
    return round(math.degrees(decompose_one(q)[1]), 4)


def orientation_fields(
    command_q: np.ndarray | None, pose: tuple[float, ...] | None
) -> dict[str, object]:
    """The commanded and written orientation in one form for every rig, from the command's
    orientation ``command_q`` (4,) (w, x, y, z) and the gate's joint angles ``pose`` (2,) or (3,)
    (rad), either None: ``cmd``/``out``: joint angles (deg); ``cmd_q``/``out_q``: orientations
    (w, x, y, z); on three servos ``cmd_twist``/``out_twist`` (deg). None where missing."""
    joints = 3 if pose is not None and len(pose) == 3 else 2
    cmd = None
    if command_q is not None:
        if joints == 3:
            current = pose if pose is not None else (0.0, 0.0, 0.0)
            cmd = _degrees(pan_tilt_roll_scalar(command_q, current[0], current[2], -PI, PI))
        else:
            cmd = _degrees(tuple(float(v) for v in quat_to_pan_tilt(command_q)))
    out_q = None if pose is None else _pose_quaternion(pose)
    row: dict[str, object] = {
        "cmd": cmd,
        "cmd_q": None if command_q is None else _quaternion(command_q),
        "out": None if pose is None else _degrees(pose),
        "out_q": None if out_q is None else _quaternion(out_q),
    }
    if joints == 3:
        row["cmd_twist"] = None if command_q is None else _twist_deg(command_q)
        row["out_twist"] = None if out_q is None else _twist_deg(out_q)
    return row


def describe_orientation(
    joints_deg: list[float] | None, twist_deg: float | None, q: list[float] | None
) -> str:
    """One orientation of :func:`orientation_fields` as text (``none`` when there is none)."""
    if joints_deg is None:
        return "none"
    names = ("pan", "tilt", "roll")
    text = " ".join(f"{name} {v:+.1f}" for name, v in zip(names, joints_deg)) + " deg"
    text += "" if twist_deg is None else f", twist {twist_deg:+.1f} deg"
    return text + ", q [" + ", ".join(f"{v:.4f}" for v in q) + "]"


class CycleState(enum.Enum):
    """Where the loop stands after a cycle."""

    RUNNING = "running"  # the loop goes on
    FINISHED = "finished"  # a clean end: the source ended, the duration passed, or stop was set
    FAULT = "fault"  # a bus fault or servo alarm; the rig was left in the configured safe state


@dataclass(frozen=True)
class CycleTimings:
    """How long a cycle's work took (s): ``cycle_s`` read, gate and write; ``gate_s`` the gate."""

    cycle_s: float
    gate_s: float


@dataclass(frozen=True)
class Cycle:
    """What one control cycle did.

    Attributes
    ----------
    index, t : int, float
        Complete cycles before this one (the first is 0); its start (s after the loop's).
    complete : bool
        The cycle ran to its end (only complete cycles are counted and logged).
    command_deg, command_q : tuple of float, ndarray (4,), or None
        The command followed, (pan, tilt) deg; its orientation (w, x, y, z), complete cycles.
    result, present : GateResult, tuple of float, or None
        The gate's answer (None: ended before it ran); the pose read (rad; None: read failed).
    ended_by, fault : str
        Why the loop ended (empty while running); the fault and the safe state it left.
    refused, notices, refused_reasons : int, tuple of str
        Lines refused so far; the health monitor's words; why each line since the last was.
    """

    index: int
    t: float
    state: CycleState
    complete: bool = False
    command_deg: tuple[float, float] | None = None
    command_q: np.ndarray | None = None
    result: GateResult | None = None
    present: tuple[float, float] | None = None
    written: bool = False
    timings: CycleTimings | None = None
    ended_by: str = ""
    fault: str = ""
    refused: int = 0
    notices: tuple[str, ...] = ()
    refused_reasons: tuple[str, ...] = ()


@dataclass
class TeleopSummary:
    """How a teleop session went; ``exit_code`` is what the CLI returns."""

    cycles: int = 0
    goals_written: int = 0
    outcomes: Counter = field(default_factory=Counter)
    commands: int = 0
    skipped: int = 0
    rejected: int = 0
    bus_errors: int = 0
    failed_cycles: int = 0
    overruns: int = 0
    cycle_times_s: deque = field(default_factory=lambda: deque(maxlen=TIMING_WINDOW))
    gate_times_s: deque = field(default_factory=lambda: deque(maxlen=TIMING_WINDOW))
    ended_by: str = ""
    fault: str = ""
    exit_code: int = 0
    elapsed_s: float = 0.0
    notices: deque = field(default_factory=lambda: deque(maxlen=NOTICE_WINDOW))
    dropouts: list[Dropout] = field(default_factory=list)
    # one line per refusal reason with its count and first examples (set when the loop ends)
    refusal_lines: list[str] = field(default_factory=list)
    # the latest command's orientation (4,) and the latest pose written (rad, one per joint)
    last_command_q: np.ndarray | None = None
    last_written: tuple[float, ...] | None = None

    def wrote(self, pose: tuple[float, ...]) -> None:
        """Count a goal written to the servos, ``pose`` (rad, one per joint)."""
        self.goals_written += 1
        self.last_written = pose

    @property
    def all_refused(self) -> bool:
        """Lines came in and every one was refused: nothing the user sent was followed."""
        return self.commands == 0 and self.rejected > 0

    @property
    def rate_hz(self) -> float:
        return self.cycles / self.elapsed_s if self.elapsed_s > 0 else 0.0

    def percentile_ms(self, p: float, gate: bool = False) -> float:
        values = self.gate_times_s if gate else self.cycle_times_s
        return 1e3 * float(np.percentile(values, p)) if values else float("nan")

    def lines(self) -> list[str]:
        outcome = ", ".join(f"{o.value} {n}" for o, n in sorted(self.outcomes.items(), key=str))
        return [
            f"ended by           {self.ended_by}" + (f": {self.fault}" if self.fault else ""),
            f"cycles             {self.cycles} in {self.elapsed_s:.1f} s ({self.rate_hz:.1f} Hz)",
            f"cycle time         p50 {self.percentile_ms(50):.2f} ms, "
            f"p99 {self.percentile_ms(99):.2f} ms, overruns {self.overruns}",
            f"gate time          p50 {self.percentile_ms(50, True):.3f} ms, "
            f"p99 {self.percentile_ms(99, True):.3f} ms",
            f"commands           {self.commands} accepted ({self.skipped} skipped as stale), "
            f"{self.rejected} refused",
            *(f"  {line}" for line in self.refusal_lines),
            f"gate outcomes      {outcome or 'none'}",
            f"goals written      {self.goals_written}",
            f"bus errors         {self.bus_errors} ({self.failed_cycles} cycles lost)",
            f"servo dropouts     {self._dropouts()}",
            *self._orientation_lines(),
        ]

    def _orientation_lines(self) -> list[str]:
        """The latest command and the latest written pose, in full (:func:`orientation_fields`)."""
        row = orientation_fields(self.last_command_q, self.last_written)
        return [
            "last command       "
            + describe_orientation(row["cmd"], row.get("cmd_twist"), row["cmd_q"]),
            "last written       "
            + describe_orientation(row["out"], row.get("out_twist"), row["out_q"]),
        ]

    def _dropouts(self) -> str:
        if not self.dropouts:
            return "none"
        still = " so far (still silent)"
        return "; ".join(
            f"servo {d.servo_id} {d.duration_s:.3f} s{still if d.ongoing else ''}"
            for d in self.dropouts
        )
