"""Whether the taught samples support the edge the region will learn: the recorder's check, run
in a worker process once the guide would say READY (which it withholds while a stretch is not).
"""

from __future__ import annotations

import concurrent.futures
import multiprocessing
import time
from collections.abc import Callable
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from typing import TYPE_CHECKING

import numpy as np

from limbctl.geometry import jit

if TYPE_CHECKING:  # the region package loads in the worker only, when a check runs
    from limbctl.region.evidence import Stretch

#: Seconds between checks while recording: a check costs ~1-2 s, so the worker idles half the time.
CHECK_EVERY_S = 5.0
#: Fewest samples worth a check: below this the guide is still in its start phase.
MIN_SAMPLES = 200


def unsupported_stretches(d: np.ndarray) -> tuple[Stretch, ...]:
    """The stretches a region learned from directions ``d`` (N, 3) leaves unsupported, or none
    (settled ones included: :attr:`limbctl.region.evidence.Stretch.settled`)."""
    from limbctl.errors import LimbctlError
    from limbctl.region import TaughtRegion

    if d.shape[0] < MIN_SAMPLES:
        return ()
    try:
        region = TaughtRegion().fit(d, lookup=False)
    except (LimbctlError, ValueError):
        return ()
    return region.unsupported_edge


class EdgeSupport:
    """Checks, in a worker process, whether the samples so far support the learned edge (module
    level ``check(d (N, 3)) -> tuple of Stretch``); :attr:`stretches` None until one ends."""

    def __init__(self, check: Callable[[np.ndarray], tuple[Stretch, ...]] | None = None):
        self.stretches: tuple[Stretch, ...] | None = None
        self._check = check or unsupported_stretches
        self._pool: ProcessPoolExecutor | None = None
        self._pending: Future | None = None
        self._checked_at = -float("inf")

    def __enter__(self) -> EdgeSupport:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Stop the worker (a check under way is dropped)."""
        if self._pool is not None:
            self._pool.shutdown(wait=False, cancel_futures=True)
            self._pool = None
        self._pending = None

    @property
    def possible(self) -> bool:
        """Whether a check can run now without compiling: either rig's training kernels cached."""
        return any(jit.prepared(jit.stage("train", twist)) for twist in (False, True))

    def check_later(self, d: np.ndarray) -> None:
        """Start a check of directions ``d`` (N, 3) when due; collect a finished one."""
        self._collect()
        now = time.monotonic()
        if self._pending is not None or now - self._checked_at < CHECK_EVERY_S:
            return
        if not self.possible:
            return
        self._checked_at = now
        self._pending = self._worker().submit(self._check, np.array(d))

    def check_now(self, d: np.ndarray) -> tuple[Stretch, ...] | None:
        """Check every sample ``d`` (N, 3) and wait; none checked until the kernels are cached."""
        if not self.possible:
            return self.stretches
        if self._pending is not None:
            self._pending.cancel()
            self._pending = None
        try:
            self.stretches = self._worker().submit(self._check, np.array(d)).result()
        except BrokenProcessPool:
            # the worker could not start or died (e.g. a program read from stdin): unchecked
            self._pool = None
        return self.stretches

    def _collect(self) -> None:
        if self._pending is not None and self._pending.done():
            try:
                self.stretches = self._pending.result()
            except concurrent.futures.CancelledError:
                pass
            except BrokenProcessPool:
                self._pool = None  # the worker died: the next check starts another
            self._pending = None

    def _worker(self) -> ProcessPoolExecutor:
        if self._pool is None:
            # spawn: a fork would copy the recorder's fsync thread mid-lock
            self._pool = ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn"))
        return self._pool
