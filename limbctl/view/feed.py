"""Feeding the board while teaching: a pose tap on the limb and a scene feeder thread."""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from limbctl.errors import LimbctlError
from limbctl.view.region import MIN_FIT_SAMPLES, FitProcess, RegionFit
from limbctl.view.state import Board, GuideFigure, HardLimits, Live, PanTilt, Scene, thin_samples
from limbctl.view.twist import TwistGauge, TwistMap, taught_gauge

#: How often the scene is republished (s) when no fit finishes: twice the page's promised 1 Hz.
SCENE_PERIOD_S = 0.5
#: Least time between the starts of two fits (s): a fit takes 0.1-0.25 s (docs/bench_fit.md).
REFIT_PERIOD_S = 0.25
#: Longest wait (s) for the feeder thread to finish when stopped.
JOIN_TIMEOUT_S = 10.0


class PoseTap:
    """A limb (``read_pose() -> (pan, tilt[, roll])``, rad; other attributes pass through) that
    also shows every pose it reads on the board, with the page's ``mode`` and ``note``."""

    def __init__(self, limb: Any, board: Board, mode: str, note: str = "") -> None:
        self._limb = limb
        self._board = board
        self.mode = mode
        self.note = note
        self._poses: list[tuple[float, float]] = []
        #: The twist taught so far (a three-servo limb), the gauge's range.
        self.twist_map: TwistMap | None = None
        self._gauge: TwistGauge | None = None
        self._last: tuple[float, ...] | None = None
        self._fault = ""

    def read_pose(self) -> tuple[float, ...]:
        """Read, keep and publish the limb's pose (rad); a failed read shows as a fault."""
        try:
            pose = self._limb.read_pose()
        except LimbctlError as exc:
            self._fault = str(exc)
            self._publish()
            raise
        self._fault = ""
        self._poses.append((pose[0], pose[1]))
        self._last = tuple(pose)
        self._publish()
        return pose

    def set_twist_map(self, twist: TwistMap) -> None:
        """The twist taught so far, the gauge's range (call from the thread reading the limb)."""
        self.twist_map = twist
        if self._last is not None:
            self._publish()

    def _publish(self) -> None:
        """Publish the last pose (with a three-servo twist gauge), the count and the fault."""
        pose = self._last
        if pose is not None and len(pose) == 3:
            self._gauge = taught_gauge(self.twist_map, *pose)
        self._board.publish_live(
            Live(
                self.mode,
                PanTilt.of_rad(self._poses[-1]) if self._poses else None,
                len(self._poses),
                fault=self._fault,
                note=self.note,
                twist=self._gauge,
            )
        )

    @property
    def count(self) -> int:
        """Poses read so far."""
        return len(self._poses)

    def samples(self) -> np.ndarray:
        """The poses read so far, shape (N, 2), radians (pan, tilt)."""
        poses = self._poses[: len(self._poses)]
        return np.array(poses, dtype=np.float64).reshape(-1, 2)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._limb, name)


class SceneFeeder:
    """Publishes the scene from its own thread: ``samples()`` so far (N, 2) (rad, pan and tilt), the
    region fitted in a separate process (``fit``; False: samples only), limits and guide."""

    def __init__(
        self,
        board: Board,
        samples: Callable[[], np.ndarray],
        limits: HardLimits | None = None,
        fit: bool = True,
    ) -> None:
        self.board = board
        self._samples = samples
        self.limits = limits
        self._guide: tuple[tuple[GuideFigure, ...], str] = ((), "")
        self._twist: TwistMap | None = None
        self._fit_wanted = fit
        self._fits: FitProcess | None = None
        waiting = "the first fit is running" if fit else "not fitted"
        self.latest = RegionFit((), 0, 0.0, problem=waiting)
        self.fits_done = 0
        #: When each fit was collected and published (monotonic s): the region's redraw times.
        self.fit_times: list[float] = []
        #: How long each of those fits took in the fit process (s), its waits for CPU included.
        self.fit_seconds: list[float] = []
        self._fitted_count = -1
        self._last_start = -math.inf
        #: A fit is due and waits only for REFIT_PERIOD_S since the last start to pass.
        self._refit_waiting = False
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def __enter__(self) -> SceneFeeder:
        self._thread = threading.Thread(target=self._run, name="limbctl-view-scene", daemon=True)
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(JOIN_TIMEOUT_S)
        self._fit_wanted = False
        if self._fits is not None:
            self._fits.close()
        self.publish_once()

    def set_guide(self, figures: tuple[GuideFigure, ...], advice: str) -> None:
        """The guide's newest figures and advice, shown with the next scene (any thread)."""
        self._guide = (tuple(figures), advice)

    def set_twist(self, twist: TwistMap) -> None:
        """The twist taught so far, shown with the next scene (any thread)."""
        self._twist = twist

    def _run(self) -> None:
        while not self._stop.is_set():
            wake = time.monotonic() + SCENE_PERIOD_S
            self.publish_once()
            fits = self._fits
            if fits is not None and fits.busy:
                # until the next scene is due, or earlier: as soon as the running fit is done
                fits.wait(wake - time.monotonic())
                continue
            remaining = self.wake_time(wake) - time.monotonic()
            if remaining > 0.0:
                self._stop.wait(remaining)

    def wake_time(self, scene_due: float) -> float:
        """When the idle feeder wakes next (monotonic s): ``scene_due`` or sooner for a fit."""
        if self._refit_waiting:
            return min(scene_due, self._last_start + REFIT_PERIOD_S)
        return scene_due

    def publish_once(self) -> Scene:
        """Collect a finished fit, start the next if due, and publish the scene; returns it."""
        pan_tilt_rad = self._samples()
        if self._fit_wanted and self._fits is None and len(pan_tilt_rad) >= MIN_FIT_SAMPLES:
            # started once there is something to fit: by then the recorder has switched torque
            # off and is sampling, and a process starting up cannot delay that first write
            self._fits = FitProcess()
        fits = self._fits
        self._refit_waiting = False
        if fits is not None and fits.alive:
            done = fits.result()
            if done is not None:
                self.latest = done
                self.fits_done += 1
                self.fit_times.append(time.monotonic())
                self.fit_seconds.append(done.seconds)
            now = time.monotonic()
            due = (
                not fits.busy
                and len(pan_tilt_rad) >= MIN_FIT_SAMPLES
                and len(pan_tilt_rad) != self._fitted_count
            )
            self._refit_waiting = due and now - self._last_start < REFIT_PERIOD_S
            if due and not self._refit_waiting:
                fits.submit(pan_tilt_rad)
                self._fitted_count = len(pan_tilt_rad)
                self._last_start = now
        samples_deg = np.degrees(pan_tilt_rad)
        figures, advice = self._guide
        scene = Scene(
            samples_deg=thin_samples(samples_deg),
            loops=self.latest.loops,
            limits=self.limits,
            region_note=self.latest.note,
            guide=figures,
            guide_text=advice,
            twist=self._twist,
        )
        self.board.publish_scene(scene)
        return scene
