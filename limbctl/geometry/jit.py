"""The one way limbctl compiles a numba kernel: :func:`njit`, cached soundly or not at all.
The cache folder is named after :func:`source_key` (every kernel source and numba's version, not
only the kernel's own file); with no writable folder kernels compile in memory, said once."""

from __future__ import annotations

import contextlib
import fcntl
import functools
import hashlib
import os
import shutil
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path

import numba
from numba.core import caching

#: The subpackages whose ``.py`` files the cache key hashes: every kernel and constant it freezes.
KERNEL_PACKAGES = ("geometry", "region", "envelope")
#: Hex digits of the sha256 naming a cache folder: 64 bits never collide, paths stay short.
KEY_DIGITS = 16

_PACKAGE = Path(__file__).resolve().parents[1]


@functools.cache
def source_key() -> str:
    """The sha256 (KEY_DIGITS hex) of every kernel package's ``.py`` files and numba's version."""
    digest = hashlib.sha256()
    for package in KERNEL_PACKAGES:
        for path in sorted((_PACKAGE / package).rglob("*.py")):
            digest.update(path.relative_to(_PACKAGE).as_posix().encode())
            digest.update(b"\0")
            digest.update(path.read_bytes())
            digest.update(b"\0")
    digest.update(numba.__version__.encode())
    return digest.hexdigest()[:KEY_DIGITS]


def cache_candidates() -> list[Path]:
    """The cache folders tried, in order: ``$NUMBA_CACHE_DIR``, the package, ``$XDG_CACHE_HOME``."""
    key = source_key()
    found = []
    if os.environ.get("NUMBA_CACHE_DIR"):
        found.append(Path(os.environ["NUMBA_CACHE_DIR"]) / f"limbctl-{key}")
    found.append(_PACKAGE / "__pycache__" / f"numba-{key}")
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    found.append(Path(base) / "limbctl" / f"numba-{key}")
    return found


def _writable(folder: Path) -> bool:
    """True when ``folder`` exists or can be made, and a file can be written in it."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
        tempfile.TemporaryFile(dir=folder).close()
    except OSError:
        return False
    return True


def _drop_other_keys(folder: Path) -> None:
    """Remove the package's cache folders of other source keys: no source can match them again."""
    if folder.parent != _PACKAGE / "__pycache__":
        return
    for other in folder.parent.glob("numba-*"):
        if other != folder and other.is_dir():
            shutil.rmtree(other, ignore_errors=True)


@functools.cache
def cache_dir() -> Path | None:
    """The folder this process caches kernels in (decided once), or None to compile in memory."""
    tried = cache_candidates()
    for folder in tried:
        if _writable(folder):
            _drop_other_keys(folder)
            return folder
    print(
        "limbctl: no writable folder for compiled kernels (tried "
        + ", ".join(str(f) for f in tried)
        + "); compiling in memory, so every start compiles again: set NUMBA_CACHE_DIR to a "
        "writable folder to keep them",
        file=sys.stderr,
    )
    return None


class _KeyedLocator(caching._SourceFileBackedLocatorMixin, caching._CacheLocator):
    """numba's cache locator for one kernel: a subfolder of :func:`cache_dir` per source folder."""

    def __init__(self, py_func, py_file):
        self._py_file = py_file
        self._lineno = py_func.__code__.co_firstlineno
        root = cache_dir()
        assert root is not None, "a keyed locator needs a cache folder"
        self._cache_path = str(root / self.get_suitable_cache_subpath(py_file))

    def get_cache_path(self):
        return self._cache_path

    @classmethod
    def from_function(cls, py_func, py_file):
        if cache_dir() is None:
            return None
        return super().from_function(py_func, py_file)


class _KeyedImpl(caching.CompileResultCacheImpl):
    _locator_classes = [_KeyedLocator]


class _KeyedCache(caching.FunctionCache):
    """numba's per-function cache, found only through :class:`_KeyedLocator`."""

    _impl_class = _KeyedImpl


def njit(function: Callable | str | None = None, /, **options) -> Callable:
    """Compile ``function`` with numba (nopython), cached under :func:`cache_dir`; as ``@njit``,
    ``@njit("f8(f8[:])")`` (eager) or ``@njit(**options)`` (``cache`` ignored)."""
    options.pop("cache", None)
    signatures = None
    if function is not None and not callable(function):
        signatures, function = function, None

    def decorate(py_func: Callable):
        dispatcher = numba.njit(**options)(py_func)
        if cache_dir() is not None:
            # numba's enable_caching with our locator; a function with no source file: in memory
            with contextlib.suppress(RuntimeError):
                dispatcher._cache = _KeyedCache(py_func)
        if signatures is not None:
            for signature in signatures if isinstance(signatures, list) else [signatures]:
                dispatcher.compile(signature)
            dispatcher.disable_compile()
        return dispatcher

    return decorate(function) if function is not None else decorate


#: What a warm-up compiles ahead and a command marks once in the cache: training and the gate,
#: of a two-servo rig and (``-twist``) of a three-servo rig.
STAGES = ("train", "gate", "train-twist", "gate-twist")


def stage(name: str, twist: bool) -> str:
    """The stage ``name`` (``train`` or ``gate``) of a rig with (``twist``) or without a roll."""
    found = f"{name}-twist" if twist else name
    if found not in STAGES:
        raise ValueError(f"unknown stage {name!r}; choose from train, gate")
    return found


def _marker(stage: str) -> Path | None:
    if stage not in STAGES:
        raise ValueError(f"unknown stage {stage!r}; choose from {', '.join(STAGES)}")
    folder = cache_dir()
    return None if folder is None else folder / f"prepared-{stage}"


def prepared(stage: str) -> bool:
    """Whether the kernels of ``stage`` (of :data:`STAGES`) are in the cache (never in memory)."""
    marker = _marker(stage)
    return marker is not None and marker.exists()


def mark_prepared(stage: str) -> None:
    """Note that the kernels of ``stage`` are in the cache (nothing when there is none)."""
    marker = _marker(stage)
    if marker is not None:
        try:
            marker.touch()
        except OSError:
            pass  # a cache folder made read-only meanwhile: the next run says "preparing" again


@contextlib.contextmanager
def warming(wait: Callable[[], None] | None = None):
    """Hold the cache's warm-up lock while the body compiles; yields whether it got it (False: no
    cache, or held elsewhere and no ``wait``; with one, ``wait()`` then block)."""
    folder = cache_dir()
    if folder is None:
        yield False
        return
    with open(folder / "warming.lock", "a+b") as lock:
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            if wait is None:
                yield False
                return
            wait()
            fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            yield True
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)
