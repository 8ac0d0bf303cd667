"""The programs some tests drive (Chromium, its driver, tmux): :func:`ensure`, at the session's
start, installs them as root with ``apt-get`` or says in one line what to install, and each test
needing a missing one skips with that line (:func:`require`)."""

from __future__ import annotations

import contextlib
import fcntl
import os
import shutil
import subprocess
import tempfile
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path

import pytest

#: The programs tests run, each with the Debian package that installs it.
TOOLS = {"chromium": "chromium", "chromedriver": "chromium-driver", "tmux": "tmux"}
#: What the tests need each program for (said in the line when one is missing).
NEEDED_BY = {
    "chromium": "the live view's browser tests",
    "chromedriver": "the live view's browser tests",
    "tmux": "the keyboard tests in a real terminal",
}
#: Held while one test run installs, so two runs started together do not both call apt-get.
LOCK = Path(tempfile.gettempdir()) / "limbctl-tests-install.lock"
#: Longest an install may take (s): chromium is ~100 MB to download and unpack.
INSTALL_TIMEOUT_S = 900.0

#: The line a test needing a missing program skips with (None: nothing is missing).
_missing_line: str | None = None


def missing(path: str | None = None) -> list[str]:
    """The programs of :data:`TOOLS` not found on ``path`` (default: ``$PATH``), in its order."""
    return [name for name in TOOLS if shutil.which(name, path=path) is None]


def packages(names: Sequence[str]) -> list[str]:
    """The Debian packages that install the programs ``names``, each once, in order."""
    return list(dict.fromkeys(TOOLS[name] for name in names))


def what_to_install(names: Sequence[str], why: str = "") -> str:
    """The one line saying what is missing, what needs it and how to install it."""
    needs = sorted({NEEDED_BY[name] for name in names})
    return (
        f"limbctl tests: {', '.join(names)} not found{why}; {' and '.join(needs)} skip until "
        f"they are installed: run `apt-get install {' '.join(packages(names))}` as root "
        "(Debian/Ubuntu), or put them on PATH"
    )


def apt_get_install(names: Sequence[str]) -> subprocess.CompletedProcess:
    """Run ``apt-get update`` and ``apt-get install -y`` of the packages of ``names``."""
    env = {**os.environ, "DEBIAN_FRONTEND": "noninteractive"}
    for args in (["update", "-qq"], ["install", "-y", "-qq", *packages(names)]):
        done = subprocess.run(
            ["apt-get", *args], env=env, capture_output=True, text=True, timeout=INSTALL_TIMEOUT_S
        )
        if done.returncode != 0:
            break
    return done


@contextlib.contextmanager
def _install_lock() -> Iterator[None]:
    with open(LOCK, "a+b") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)


def ensure(
    path: str | None = None,
    root: bool | None = None,
    install: Callable[[Sequence[str]], subprocess.CompletedProcess] = apt_get_install,
    say: Callable[[str], None] = print,
) -> str | None:
    """Install the missing programs with ``install`` where this process may (``root``; default:
    root with ``apt-get`` on ``path``); None when all are found, else the one line saying what to
    install (and why installing failed), kept for :func:`require`."""
    global _missing_line
    absent = missing(path)
    if root is None:
        root = os.geteuid() == 0 and shutil.which("apt-get", path=path) is not None
    if absent and root:
        with _install_lock():
            absent = missing(path)  # another run may have installed them meanwhile
            if absent:
                say(
                    f"limbctl tests: installing {' '.join(packages(absent))} with apt-get for "
                    f"{' and '.join(sorted({NEEDED_BY[n] for n in absent}))} (once per machine)..."
                )
                try:
                    done = install(absent)
                    failed = done.returncode != 0
                    detail = (done.stderr or done.stdout or "").strip().splitlines()[-1:]
                except (OSError, subprocess.TimeoutExpired) as exc:
                    failed, detail = True, [str(exc)]
                still = missing(path)
                if failed or still:
                    why = (
                        ": installing them failed" + (f" ({detail[0]})" if detail else "")
                        if failed
                        else ": apt-get installed them, yet they are not on PATH"
                    )
                    _missing_line = what_to_install(still or absent, why)
                    say(_missing_line)
                    return _missing_line
                absent = still
    _missing_line = what_to_install(absent) if absent else None
    if _missing_line:
        say(_missing_line)
    return _missing_line


def require(*names: str) -> None:
    """Skip the calling test, with the session's one line, when a program it needs is missing."""
    absent = [name for name in names if shutil.which(name) is None]
    if absent:
        pytest.skip(_missing_line or what_to_install(absent))


def find(name: str) -> str:
    """The full path of program ``name``; skips the calling test (one line) when it is missing."""
    require(name)
    return shutil.which(name)
