"""The region ``train`` would learn so far, as edge loops, fitted in a separate process (numba
holding the GIL would stall the recorder)."""

from __future__ import annotations

import math
import multiprocessing
import os
import time
from dataclasses import dataclass

import numba
import numpy as np
from scipy.spatial import cKDTree

from limbctl.envelope import RigidMap
from limbctl.errors import LimbctlError
from limbctl.geometry.gimbal import direction_to_pan_tilt, pan_tilt_to_direction
from limbctl.geometry.quat import limb_direction, swing_from_direction
from limbctl.region import TaughtRegion
from limbctl.view.state import EdgeLoop

#: Longest drawn stretch of edge (deg): fine enough that traced and untraced parts show apart.
STRETCH_DEG = 1.0
#: A stretch is traced when a sample lies this close (deg) to its middle (the edge's max offset).
TRACED_WITHIN_DEG = 3.0
#: Fewest samples worth a fit (2 s at 100 Hz): fewer gave slivers or stray arcs.
MIN_FIT_SAMPLES = 200
#: Niceness of the fit process (19, the lowest priority): a refit may wait, the recorder not.
FIT_NICENESS = 19
#: Longest wait (s) for the fit process to start or to finish a fit when asked to stop.
STOP_TIMEOUT_S = 5.0


@dataclass(frozen=True)
class RegionFit:
    """One fit's outcome: the edge loops (empty if none could be fitted) and how it went."""

    loops: tuple[EdgeLoop, ...]
    samples: int
    seconds: float
    edge: str = ""
    problem: str = ""

    @property
    def note(self) -> str:
        """The region's status in words, for the page."""
        if self.problem:
            return f"no region yet from {self.samples} samples: {self.problem}"
        return f"fitted on {self.samples} samples in {self.seconds:.1f} s ({self.edge} edge)"


def mesh_loops(edges: np.ndarray) -> list[np.ndarray]:
    """The closed loops of a region's boundary arcs ``edges`` (E, 2) int, directed ``a -> b``
    (each vertex starts at most one arc), as index arrays in walking order."""
    following = {int(a): int(b) for a, b in np.asarray(edges)}
    loops, seen = [], set()
    for start in following:
        if start in seen:
            continue
        loop = []
        vertex = start
        while vertex not in seen and vertex in following:
            seen.add(vertex)
            loop.append(vertex)
            vertex = following[vertex]
        if len(loop) >= 3:
            loops.append(np.array(loop, dtype=np.int64))
    return loops


def subdivide(loop: np.ndarray, step_rad: float) -> np.ndarray:
    """A closed loop of directions (M, 3) with each arc cut into pieces of at most ``step_rad``
    (normalised chord points, on the great circle)."""
    following = np.roll(loop, -1, axis=0)
    angles = np.arccos(np.clip(np.sum(loop * following, axis=1), -1.0, 1.0))
    pieces = np.maximum(1, np.ceil(angles / step_rad).astype(np.int64))
    points = []
    for a, b, n in zip(loop, following, pieces):
        t = np.arange(n)[:, None] / n
        chord = (1.0 - t) * a + t * b
        points.append(chord / np.linalg.norm(chord, axis=1, keepdims=True))
    return np.vstack(points)


def traced_stretches(loop: np.ndarray, sample_tree: cKDTree, within_rad: float) -> np.ndarray:
    """Whether each stretch ``i -> i + 1`` of a loop (M, 3) has a sample near its middle: (M,)."""
    middle = loop + np.roll(loop, -1, axis=0)
    middle /= np.linalg.norm(middle, axis=1, keepdims=True)
    # chord length of the angle ``within_rad``: 2 sin(angle / 2)
    chord = 2.0 * math.sin(0.5 * within_rad)
    distance, _ = sample_tree.query(middle, k=1, distance_upper_bound=chord)
    return np.isfinite(distance)


def region_loops(
    vertices: np.ndarray, edges: np.ndarray, sample_directions: np.ndarray | None
) -> tuple[EdgeLoop, ...]:
    """A region's boundary, directions ``vertices`` (V, 3) joined by directed arcs ``edges``
    (E, 2), as pan/tilt edge loops traced near ``sample_directions`` (N, 3) (None: all traced)."""
    tree = cKDTree(sample_directions) if sample_directions is not None else None
    out = []
    for index in mesh_loops(edges):
        loop = subdivide(vertices[index], math.radians(STRETCH_DEG))
        if tree is None:
            traced = np.ones(len(loop), dtype=bool)
        else:
            traced = traced_stretches(loop, tree, math.radians(TRACED_WITHIN_DEG))
        pan, tilt = direction_to_pan_tilt(loop)
        out.append(EdgeLoop(np.degrees(np.column_stack([pan, tilt])), traced))
    return tuple(out)


def model_loops(model: RigidMap, sample_directions: np.ndarray | None = None) -> tuple:
    """A fitted Rigid Map's region as edge loops (see :func:`region_loops`)."""
    mesh = getattr(model, "mesh", None)
    if mesh is None:
        return ()
    return region_loops(mesh.vertices, mesh.edges, sample_directions)


def fit_outline(pan_tilt_rad: np.ndarray) -> RegionFit:
    """Fit the default model's region to samples (N, 2) of joint angles (rad) and outline it."""
    samples = np.asarray(pan_tilt_rad, dtype=np.float64).reshape(-1, 2)
    started = time.perf_counter()
    if len(samples) < MIN_FIT_SAMPLES:
        return RegionFit((), len(samples), 0.0, problem=f"need {MIN_FIT_SAMPLES} samples")
    # the directions as train sees them: through the swing quaternion and back
    directions = limb_direction(
        swing_from_direction(pan_tilt_to_direction(samples[:, 0], samples[:, 1]))
    )
    try:
        # RigidMap()'s region; the page draws its loops, the gate's lookup grid is not needed
        region = TaughtRegion().fit(directions, lookup=False)
    except (LimbctlError, ValueError) as exc:
        return RegionFit((), len(samples), time.perf_counter() - started, problem=str(exc))
    loops = region_loops(region.mesh.vertices, region.mesh.edges, directions)
    return RegionFit(loops, len(samples), time.perf_counter() - started, edge=region.edge)


def serve_fits(connection) -> None:
    """The fit process: answer each array of samples with its :class:`RegionFit`, on one thread."""
    numba.set_num_threads(1)
    while True:
        samples = connection.recv()
        if samples is None:
            return
        connection.send(fit_outline(samples))


class FitProcess:
    """:func:`fit_outline` in its own process, one fit at a time."""

    def __init__(self) -> None:
        context = multiprocessing.get_context("spawn")
        self._connection, child = context.Pipe()
        self._process = context.Process(
            target=serve_fits, args=(child,), name="limbctl-view-fit", daemon=True
        )
        self._process.start()
        # lowest priority from its first instant, before its imports take seconds of CPU
        os.setpriority(os.PRIO_PROCESS, self._process.pid, FIT_NICENESS)
        # and only on CPU time nothing else wants (Linux SCHED_IDLE): the recorder first
        os.sched_setscheduler(self._process.pid, os.SCHED_IDLE, os.sched_param(0))
        child.close()
        self.busy = False

    def submit(self, pan_tilt_rad: np.ndarray) -> None:
        """Start fitting samples (N, 2) of joint angles (rad); one fit at a time."""
        if self.busy:
            raise RuntimeError("a fit is already running; wait for its result first")
        self._connection.send(np.ascontiguousarray(pan_tilt_rad, dtype=np.float64))
        self.busy = True

    def wait(self, timeout_s: float) -> bool:
        """Wait up to ``timeout_s`` for the running fit; whether it finished (False: none runs)."""
        return self.busy and self._connection.poll(timeout_s)

    def result(self, timeout_s: float = 0.0) -> RegionFit | None:
        """The running fit's outcome if it is done within ``timeout_s``, else None."""
        if not self.busy or not self._connection.poll(timeout_s):
            return None
        self.busy = False
        return self._connection.recv()

    def close(self) -> None:
        """End the process (a fit in progress is abandoned)."""
        if self._process.is_alive():
            if self.busy:
                self._process.terminate()
            else:
                self._connection.send(None)
            self._process.join(STOP_TIMEOUT_S)
            if self._process.is_alive():
                self._process.kill()
                self._process.join(STOP_TIMEOUT_S)
        self._connection.close()

    @property
    def alive(self) -> bool:
        """Whether the fit process is running."""
        return self._process.is_alive()
