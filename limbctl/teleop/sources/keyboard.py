"""Command source ``keyboard``: the keys of a terminal steer the limb."""

from __future__ import annotations

import math
import os
import select
import sys
import time
from typing import IO, Any

import numpy as np

from limbctl.errors import ConfigError
from limbctl.teleop.commands import Command, command_from_pan_tilt, command_from_pose
from limbctl.teleop.gate import Outcome
from limbctl.teleop.keys import (
    DEFAULT_STEP_DEG,
    KEYS,
    SEQUENCES,
    Action,
    HeldKey,
    key_guide,
    next_step,
    split_keys,
)
from limbctl.teleop.sources.base import WAKE_INTERVAL_S, CommandSource

#: Most bytes taken per read: a burst of held-down arrow keys (3 bytes each).
READ_CHUNK_BYTES = 64
#: How often (s) the command is repeated: five times within the loop's 0.5 s silence.
KEEPALIVE_S = WAKE_INTERVAL_S
#: Farthest (deg, per joint) the command may lead the written pose moving freely (edge: a step).
MAX_LEAD_DEG = 10.0
#: Grid (deg) for the region's centre: a few thousand candidates, a fraction of a second once.
CENTRE_GRID_DEG = 2.0


def region_centre(envelope: Any) -> tuple[float, float] | None:
    """(pan, tilt) deg of the grid point inside farthest from the edge; None without a mesh."""
    from limbctl.geometry.gimbal import pan_tilt_to_direction, pan_tilt_to_quat

    mesh = getattr(envelope, "mesh", None)
    edge = np.asarray(getattr(mesh, "vertices", ()), dtype=np.float64).reshape(-1, 3)
    if len(edge) == 0:
        return None
    # the grid stays off the poles, where pan is undefined
    pans = np.radians(np.arange(-180.0, 180.0, CENTRE_GRID_DEG))
    tilts = np.radians(np.arange(-88.0, 88.0 + CENTRE_GRID_DEG / 2, CENTRE_GRID_DEG))
    pan, tilt = (a.ravel() for a in np.meshgrid(pans, tilts))
    inside = np.asarray(envelope.contains(pan_tilt_to_quat(pan, tilt)), dtype=bool)
    if not inside.any():
        return None
    pan, tilt = pan[inside], tilt[inside]
    # clearance = the angle from each candidate to its nearest edge vertex, arccos(max d . v)
    nearest_cos = (pan_tilt_to_direction(pan, tilt) @ edge.T).max(axis=1)
    best = int(np.argmin(nearest_cos))
    return float(np.degrees(pan[best])), float(np.degrees(tilt[best]))


class KeyboardSource(CommandSource):
    """Keys in the terminal ``tty_path`` steer pan/tilt by ``step_deg``; ``q`` ends the session.
    ``gate`` (optional) gives the written pose the command starts from and never leads by more than
    :data:`MAX_LEAD_DEG`, and the region's centre; ``guide``: where the key guide goes."""

    name = "keyboard"
    latest_only = True
    explains = True

    def __init__(
        self,
        step_deg: float = DEFAULT_STEP_DEG,
        start_deg: tuple[float, float] = (0.0, 0.0),
        tty_path: str = "/dev/tty",
        gate: Any = None,
        guide: IO[str] | None = None,
    ) -> None:
        super().__init__()
        import termios
        import tty

        self._fd = -1
        try:
            fd = os.open(tty_path, os.O_RDONLY | os.O_NOCTTY)
        except OSError as exc:
            raise ConfigError("keyboard source needs a terminal; use --source stdin") from exc
        try:
            # key by key from now on (no line buffering)
            self._saved = termios.tcgetattr(fd)
            tty.setcbreak(fd)
        except termios.error as exc:
            os.close(fd)
            raise ConfigError(f"{tty_path} is not a terminal; use --source stdin") from exc
        self._fd = fd
        self.step_deg = step_deg
        self.pan_deg, self.tilt_deg = start_deg
        self.roll_deg = 0.0  # a three-servo rig's roll (``twist``), moved by the roll keys
        self.holding = False
        self._gate = gate
        self._guide = guide
        self._centre = region_centre(gate.envelope) if gate is not None else None
        self._held = HeldKey()
        self._command: Command | None = None
        self._offered_at = 0.0
        # the newest command the loop took and, once the gate stopped one short, (it, written deg)
        self._taken: Command | None = None
        self._stopped: tuple[Command, tuple[float, float]] | None = None
        # the (pan, tilt) deg written when the gate's latest answer stopped the command short
        self._at_edge: tuple[float, float] | None = None
        self._snapped: Command | None = None  # the written pose sent back with no key pressed
        self._pushing: tuple[str, ...] = ()

    def poll(self, timeout: float = 0.0) -> list[Command]:
        """The loop's poll; the newest command taken is the one the next result answers."""
        commands = super().poll(timeout)
        if commands:
            self._taken = commands[-1]
        return commands

    def feel(self, gate: object, result: object, bus_ok: bool) -> tuple[str, ...]:
        """Learn, after each cycle, where the gate stopped the command taken (if it did)."""
        taken = self._taken
        if taken is None or taken is self._snapped or result.outcome is Outcome.HELD:
            return ()  # the limb's own pose sent back says nothing about the edge
        stopped = getattr(result, "corrected", False) or getattr(result, "clamped", False)
        written = (math.degrees(result.pose[0]), math.degrees(result.pose[1]))
        self._at_edge = written if stopped else None
        if stopped:
            self._stopped = (taken, written)
        return ()

    def pushing(self) -> tuple[str, ...]:
        """The joint directions the last move key pushes ("+pan", ...); none after another key."""
        return self._pushing

    def _stopped_at(self) -> tuple[float, float] | None:
        """The written (pan, tilt) deg if the gate stopped the present command short of it."""
        stopped = self._stopped
        if stopped is None or self._command is None or stopped[0] is not self._command:
            return None
        return stopped[1]

    def describe(self) -> str:
        """The step, and the hold when on: the status line's words about the keyboard."""
        text = f"step {self.step_deg:g} deg"
        return text + ("  HOLDING: space releases" if self.holding else "  ? keys")

    def close(self) -> None:
        """Stop the reader and give the terminal back as it was; safe to call twice."""
        super().close()
        if self._thread is None:  # never started: the reader's own clean-up did not run
            self._release()

    def _release(self) -> None:
        import termios

        if self._fd >= 0:
            termios.tcsetattr(self._fd, termios.TCSADRAIN, self._saved)
            os.close(self._fd)
            self._fd = -1

    def _say(self, lines: list[str]) -> None:
        if self._guide is not None:
            self._guide.write("\n" + "\n".join(lines) + "\n")
            self._guide.flush()

    def _written_deg(self) -> tuple[float, float] | None:
        pose = self._gate.safe_pose if self._gate is not None else None
        return None if pose is None else (float(np.degrees(pose[0])), float(np.degrees(pose[1])))

    def _run(self) -> None:
        pending = b""
        self._say(key_guide(self.step_deg))
        try:
            while not self._stop.is_set():
                ready, _, _ = select.select([self._fd], [], [], KEEPALIVE_S)
                now = time.monotonic()
                if ready:
                    data = os.read(self._fd, READ_CHUNK_BYTES)
                    if not data:
                        return  # the terminal went away: the input ended
                    keys, pending = split_keys(pending + data)
                    for key in keys:
                        action = SEQUENCES.get(key)
                        if action is Action.QUIT:
                            return
                        if action is not None:
                            self._act(action, now)
                if self._command is not None and not self.holding:
                    if now - self._offered_at >= KEEPALIVE_S:
                        stopped_at = self._stopped_at()
                        if stopped_at is not None:  # no key pushes: the point is the limb's
                            self.pan_deg, self.tilt_deg = stopped_at
                            self._command = self._snapped = self._pose_command()
                            self._pushing = ()
                        self._queue.put(self._command)  # a repeat, not a new command: not counted
                        self._offered_at = now
        finally:
            self._release()

    def _act(self, action: Action, now: float) -> None:
        """Do what one key asks."""
        move = KEYS[action].move
        if move != (0, 0):
            if not self.holding:
                self._move(action, move, now)
            return
        self._held.reset()
        self._pushing = ()
        roll = KEYS[action].roll
        if roll and not self.twist:
            reason = "roll keys need a three-servo rig (this one has no roll joint to turn)"
            self.stats.reject(reason, KEYS[action].label)
        elif roll and not self.holding:  # one step a press, the roll joint's range kept
            self.roll_deg = min(max(self.roll_deg + roll * self.step_deg, -180.0), 180.0)
            self._offer_pose(now)
        elif action in (Action.COARSER, Action.FINER):
            self.step_deg = next_step(self.step_deg, action is Action.COARSER)
        elif action is Action.HOLD:
            # holding: stay where the limb is, then go quiet so the loop holds
            self.holding = not self.holding
            written = self._written_deg()
            if written is not None:
                self.pan_deg, self.tilt_deg = written
                self._offer_pose(now)
        elif action is Action.CENTRE and self._centre is not None and not self.holding:
            self.pan_deg, self.tilt_deg = self._centre
            self._offer_pose(now)
        elif action is Action.HELP:
            self._say(key_guide(self.step_deg))

    def _move(self, action: Action, move: tuple[int, int], now: float) -> None:
        written = self._written_deg()
        at_edge = self._at_edge
        if at_edge is not None:  # the gate stopped the point short: go on from the limb
            self.pan_deg, self.tilt_deg = at_edge
        elif self._command is None and written is not None:
            self.pan_deg, self.tilt_deg = written  # the first move starts where the limb is
        self._pushing = tuple(
            f"{'+' if sign > 0 else '-'}{joint}"
            for joint, sign in zip(("pan", "tilt"), move, strict=True)
            if sign
        )
        distance = self._held.distance(action, now, self.step_deg)
        if at_edge is not None:  # a held key's catch-up never carries the point past the edge
            distance = min(distance, self.step_deg)
        pan = min(max(self.pan_deg + move[0] * distance, -180.0), 180.0)
        tilt = min(max(self.tilt_deg + move[1] * distance, -90.0), 90.0)
        if written is not None:  # never far ahead of the limb along the joint the key moves
            if move[0]:
                pan = min(max(pan, written[0] - MAX_LEAD_DEG), written[0] + MAX_LEAD_DEG)
            if move[1]:
                tilt = min(max(tilt, written[1] - MAX_LEAD_DEG), written[1] + MAX_LEAD_DEG)
        self.pan_deg, self.tilt_deg = pan, tilt
        self._offer_pose(now)

    def _pose_command(self) -> Command:
        if self.twist:
            return command_from_pose(self.pan_deg, self.tilt_deg, self.roll_deg)
        return command_from_pan_tilt(self.pan_deg, self.tilt_deg)

    def _offer_pose(self, now: float) -> None:
        self._command = self._pose_command()
        self._offered_at = now
        self.offer(self._command)


def keyboard_source(gate: Any = None) -> KeyboardSource:
    """The keyboard of the controlling terminal, its guide on standard error."""
    return KeyboardSource(gate=gate, guide=sys.stderr)
