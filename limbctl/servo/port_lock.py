"""One controller per serial port: who holds a port that limbctl could not ``flock``."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

#: Where Linux lists every file lock: ``N: FLOCK ADVISORY WRITE PID MAJ:MIN:INODE START END``.
PROC_LOCKS = Path("/proc/locks")


@dataclass(frozen=True)
class PortHolder:
    """A process (``pid``, ``command`` line or ``"?"``) that holds a serial port."""

    pid: int
    command: str

    def describe(self) -> str:
        """``'pid 1234 (limbctl teleop --model m.npz)'``; ``'this process'`` for our own pid."""
        who = "this process, " if self.pid == os.getpid() else ""
        return f"{who}pid {self.pid} ({self.command})"


def command_line(pid: int) -> str:
    """The command line of ``pid`` with its arguments, or ``'?'`` when it cannot be read."""
    try:
        raw = Path(f"/proc/{pid}/cmdline").read_bytes()
    except OSError:
        return "?"
    words = [w.decode(errors="replace") for w in raw.split(b"\0") if w]
    return " ".join(words) if words else "?"


def _flock_pids(device: os.stat_result) -> list[int]:
    """Pids holding a FLOCK on the file ``device`` (from /proc/locks)."""
    try:
        lines = PROC_LOCKS.read_text().splitlines()
    except OSError:
        return []
    # /proc/locks names the file as MAJOR:MINOR:INODE of the filesystem it lives on, in hex
    wanted = (os.major(device.st_dev), os.minor(device.st_dev), device.st_ino)
    pids = []
    for line in lines:
        fields = line.split()
        if "->" in fields or len(fields) < 6 or fields[1] != "FLOCK":
            continue  # '->' marks a waiter, not a holder
        try:
            major, minor, inode = fields[5].split(":")
            where = (int(major, 16), int(minor, 16), int(inode))
            pid = int(fields[4])
        except ValueError:
            continue
        if where == wanted:
            pids.append(pid)
    return pids


def _opener_pids(device: os.stat_result) -> list[int]:
    """Pids of the processes that have the character device ``device`` open (/proc/PID/fd)."""
    pids = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            fds = list((entry / "fd").iterdir())
        except OSError:
            continue  # another user's process, or it ended
        for fd in fds:
            try:
                st = fd.stat()
            except OSError:
                continue
            if st.st_rdev == device.st_rdev and st.st_ino == device.st_ino:
                pids.append(int(entry.name))
                break
    return pids


def port_holders(port: str | os.PathLike) -> list[PortHolder]:
    """The processes holding the lock of ``port`` (followed), else those having it open."""
    try:
        device = os.stat(os.path.realpath(port))
    except OSError:
        return []
    pids = _flock_pids(device) or _opener_pids(device)
    return [PortHolder(pid, command_line(pid)) for pid in dict.fromkeys(pids)]


def describe_holders(port: str | os.PathLike) -> str:
    """Who holds ``port``, for a message: ``'pid 1234 (limbctl teleop ...)'`` or a fallback."""
    holders = port_holders(port)
    if not holders:
        return "another process (its pid could not be read from /proc)"
    return ", ".join(holder.describe() for holder in holders)
