"""A command in a real 160 x 40 terminal: a detached tmux pane, its keys sent, its text read."""

from __future__ import annotations

import contextlib
import shlex
import subprocess
import time
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path

from tests.system_tools import require

ROOT = Path(__file__).resolve().parents[2]
COLUMNS, ROWS = 160, 40  # the terminal the user had
#: Longest wait (s) for the pane to show something: generous on a loaded 2-core machine.
WAIT_S = 60.0
#: How often (s) the pane is read while waiting for text.
POLL_S = 0.05


class Pane:
    """One tmux session of one pane running ``command`` (a shell line) in the repository."""

    def __init__(self, name: str) -> None:
        self.name = name

    def keys(self, *keys: str) -> None:
        """Send keys as tmux names them ("Up", "q", "?", "Space")."""
        subprocess.run(["tmux", "send-keys", "-t", self.name, *keys], check=True)

    def text(self, history: bool = False) -> str:
        """The pane's text (with ``history``: everything scrolled off too)."""
        command = ["tmux", "capture-pane", "-p", "-J", "-t", self.name]
        command += ["-S", "-"] if history else []
        return subprocess.run(command, check=True, capture_output=True, text=True).stdout

    def status(self) -> str:
        """The last non-empty line: the status line refreshed in place."""
        lines = [line for line in self.text().splitlines() if line.strip()]
        return lines[-1] if lines else ""

    def wait_for(self, condition: Callable[[str], bool], message: str, timeout: float = WAIT_S):
        """Read the pane until ``condition(text)`` holds; fail with ``message`` and the text."""
        deadline = time.monotonic() + timeout
        while True:
            text = self.text()
            if condition(text):
                return text
            if time.monotonic() > deadline:
                raise AssertionError(f"{message}; the pane shows:\n{text}")
            time.sleep(POLL_S)


@contextlib.contextmanager
def tmux_pane(command: str, env: dict[str, str] | None = None) -> Iterator[Pane]:
    """Run ``command`` in a new detached tmux session (COLUMNS x ROWS), killed on exit; the pane
    stays open after the command ends, its last line ``EXIT <status>``."""
    require("tmux")
    name = f"limbctl-{uuid.uuid4().hex[:8]}"
    exports = "".join(f"export {k}={shlex.quote(v)}; " for k, v in (env or {}).items())
    line = f"cd {shlex.quote(str(ROOT))}; {exports}{command}; echo EXIT $?; sleep 3600"
    subprocess.run(
        ["tmux", "new-session", "-d", "-s", name, "-x", str(COLUMNS), "-y", str(ROWS), line],
        check=True,
    )
    try:
        yield Pane(name)
    finally:
        subprocess.run(["tmux", "kill-session", "-t", name], check=False)
