"""Writers of the loop's cycle values: the telemetry file and the status line."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import IO

import numpy as np

from limbctl.geometry.gimbal import pan_tilt_to_quat, quat_to_pan_tilt
from limbctl.geometry.gimbal3 import pan_tilt_roll_scalar, pose_quat_scalar
from limbctl.geometry.twist import decompose_one
from limbctl.teleop.cycle import Cycle, TeleopSummary
from limbctl.teleop.gate import Outcome

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
    """The commanded and written orientation in one form for every rig.

    Parameters
    ----------
    command_q : ndarray (4,) or None
        The command's orientation (w, x, y, z).
    pose : tuple of float or None
        The gate's joint angles (rad): 2 on a two-servo rig, 3 (pan, tilt, roll) on three.

    Returns
    -------
    dict
        ``cmd`` and ``out``: joint angles (deg), as many as the rig has joints (the command's
        roll is the joint's for that orientation, nearest the written roll); ``cmd_q`` and
        ``out_q``: the orientations (w, x, y, z); on a three-servo rig also ``cmd_twist`` and
        ``out_twist``: the twist about the limb's rest axis (deg, swing-twist; not the roll).
        A missing value is None.
    """
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


class Telemetry:
    """One JSON line per complete cycle: command, gated pose, written goal, present pose (deg),
    and the reasons of the lines refused since the previous cycle.

    Every rig writes one form (:func:`orientation_fields`): ``cmd`` and ``out`` hold one angle
    per joint (pan, tilt and, on three servos, roll), ``cmd_q`` and ``out_q`` the full
    orientations, and a three-servo rig adds ``cmd_twist`` and ``out_twist``.
    """

    def __init__(self, stream: IO[str]) -> None:
        self._stream = stream

    def write(self, cycle: Cycle) -> None:
        """Log one complete cycle (see :class:`~limbctl.teleop.cycle.Cycle`)."""
        result = cycle.result
        command_q = cycle.command_q
        if command_q is None and cycle.command_deg is not None:  # a cycle built by hand
            command_q = pan_tilt_to_quat(*np.radians(cycle.command_deg))
        row = {
            "t": round(cycle.t, 6),
            **orientation_fields(command_q, None if result is None else result.pose),
            "outcome": None if result is None else result.outcome.value,
            "written": cycle.written,
            "present": None
            if cycle.present is None
            else [round(math.degrees(v), 4) for v in cycle.present],
            "cycle_ms": round(1e3 * cycle.timings.cycle_s, 3) if cycle.timings else None,
            "refused": list(cycle.refused_reasons),
        }
        self._stream.write(json.dumps(row) + "\n")


def open_telemetry(path: str | Path | None) -> IO[str] | None:
    """Open a telemetry file for line-buffered writing (None: no telemetry)."""
    if path is None:
        return None
    return open(path, "w", buffering=1, encoding="utf-8")


#: Seconds between status lines on a terminal (refreshed in place) and in a log (one per line).
STATUS_EVERY_TTY_S = 0.5
STATUS_EVERY_LOG_S = 5.0


class StatusLine:
    """A one-line status refreshed in place on a terminal, or appended now and then to a log."""

    def __init__(self, stream: IO[str]) -> None:
        self._stream = stream
        self._tty = stream.isatty()
        self._every = STATUS_EVERY_TTY_S if self._tty else STATUS_EVERY_LOG_S
        self._last = 0.0

    def update(self, cycle: Cycle, summary: TeleopSummary) -> None:
        """Print the status if the last one is old enough (``cycle.t`` is the clock)."""
        if cycle.t - self._last >= self._every:
            self._last = cycle.t
            self.show(summary, cycle.t)

    def close(self, summary: TeleopSummary) -> None:
        """Print the final status (and end the refreshed line on a terminal)."""
        self.show(summary, summary.elapsed_s)
        if self._tty:
            self._stream.write("\n")

    def show(self, summary: TeleopSummary, elapsed: float) -> None:
        n = max(1, sum(summary.outcomes.values()))
        share = {o: 100.0 * summary.outcomes[o] / n for o in Outcome}
        rate = summary.cycles / elapsed if elapsed > 0 else 0.0
        self._stream.write(
            ("\r" if self._tty else "")
            + f"{elapsed:7.1f} s  {rate:6.1f} Hz  pass {share[Outcome.PASSED]:5.1f}%  "
            f"corr {share[Outcome.CORRECTED]:5.1f}%  clamp {share[Outcome.CLAMPED]:4.1f}%  "
            f"held {share[Outcome.HELD]:5.1f}%  refused {summary.rejected}  "
            f"bus errors {summary.bus_errors}   " + ("" if self._tty else "\n")
        )
        self._stream.flush()
