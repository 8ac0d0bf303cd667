"""Command source ``keyboard``: the arrow keys of a terminal nudge pan and tilt; on a
three-servo rig ``[`` and ``]`` turn the limb about its own axis (roll)."""

from __future__ import annotations

import os
import select

from limbctl.errors import ConfigError
from limbctl.teleop.commands import command_from_pan_tilt, command_from_pose
from limbctl.teleop.sources.base import WAKE_INTERVAL_S, CommandSource

#: Degrees one arrow key moves pan or tilt: fine enough to creep up to an edge, coarse enough to
#: cross 90 degrees in 45 presses.
KEY_STEP_DEG = 2.0
#: Most bytes taken per read: a burst of held-down arrow keys (3 bytes each).
READ_CHUNK_BYTES = 64


class KeyboardSource(CommandSource):
    """Arrow keys in the terminal nudge pan/tilt by ``step_deg``; ``q`` ends the session.

    Up/down raise/lower the limb (tilt), left/right turn it (pan; left is +pan, toward +y).
    On a three-servo rig (``twist``), ``]`` turns the roll by +``step_deg`` and ``[`` by
    -``step_deg``; on two servos those keys are refused (counted, with the reason).
    ``tty_path`` is the terminal to read (the controlling terminal by default).
    """

    name = "keyboard"
    latest_only = True
    _KEYS = {b"\x1b[A": (0, 1), b"\x1b[B": (0, -1), b"\x1b[C": (-1, 0), b"\x1b[D": (1, 0)}
    _ROLL_KEYS = {b"[": -1, b"]": 1}

    def __init__(
        self,
        step_deg: float = KEY_STEP_DEG,
        start_deg: tuple[float, float] = (0.0, 0.0),
        tty_path: str = "/dev/tty",
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
            # key by key from now on (no line buffering): keys pressed before the reader thread
            # runs are kept, not held back in a half-typed line
            self._saved = termios.tcgetattr(fd)
            tty.setcbreak(fd)
        except termios.error as exc:
            os.close(fd)
            raise ConfigError(f"{tty_path} is not a terminal; use --source stdin") from exc
        self._fd = fd
        self.step_deg = step_deg
        self.pan_deg, self.tilt_deg = start_deg
        self.roll_deg = 0.0

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

    def _run(self) -> None:
        pending = b""
        try:
            while not self._stop.is_set():
                ready, _, _ = select.select([self._fd], [], [], WAKE_INTERVAL_S)
                if not ready:
                    continue
                pending += os.read(self._fd, READ_CHUNK_BYTES)
                # split the bytes into keys: an escape sequence is three bytes, others one
                while pending:
                    size = 3 if pending[:1] == b"\x1b" else 1
                    if len(pending) < size:
                        break
                    key, pending = pending[:size], pending[size:]
                    if key in (b"q", b"\x04"):
                        return
                    turn = self._ROLL_KEYS.get(key)
                    if turn is not None and not self.twist:
                        self.stats.reject(
                            "roll keys need a three-servo rig (this one has no roll joint to "
                            "turn the limb about its own axis)",
                            key,
                        )
                        continue
                    move = (0, 0) if turn is not None else self._KEYS.get(key)
                    if move is None:
                        continue
                    self.pan_deg = min(max(self.pan_deg + move[0] * self.step_deg, -180.0), 180.0)
                    self.tilt_deg = min(max(self.tilt_deg + move[1] * self.step_deg, -90.0), 90.0)
                    if self.twist:
                        step = (turn or 0) * self.step_deg
                        self.roll_deg = min(max(self.roll_deg + step, -180.0), 180.0)
                        self.offer(command_from_pose(self.pan_deg, self.tilt_deg, self.roll_deg))
                    else:
                        self.offer(command_from_pan_tilt(self.pan_deg, self.tilt_deg))
        finally:
            self._release()
