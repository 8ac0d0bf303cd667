"""The taught region in three dimensions: a swing outline (:class:`~limbctl.region.taught.
TaughtRegion`) and a :class:`~limbctl.region.twist_band.TwistBand` over it; ``correct(q)`` is the
nearest orientation on SO(3). Directions within ``SINGULAR_MARGIN`` of -x are refused."""

from __future__ import annotations

import math

import numpy as np

from limbctl.errors import ConfigError, InvalidInputError
from limbctl.geometry.quat import as_quaternions
from limbctl.geometry.twist import SINGULAR_MARGIN, compose, decompose
from limbctl.region import twist_kernels as tk
from limbctl.region.correct_kernels import PARALLEL_ROWS
from limbctl.region.params import RegionParams
from limbctl.region.shape import thin
from limbctl.region.taught import TaughtRegion
from limbctl.region.twist_band import TwistBand, plane_to_direction
from limbctl.region.twist_evidence import UnsupportedPlace, band_unsupported

#: Rows from which ``correct`` runs on the thread pool: a row costs 30-50 us (a search on SO(3)),
#: so 2000 rows take ~0.1 s on one thread; a control cycle asks tens, and on the pool they would
#: contend with the simulator or the bus for the two cores. (``contains`` costs about what the
#: two-servo correction does and takes the pool from ``correct_kernels.PARALLEL_ROWS``.)
PARALLEL_CORRECT_ROWS = 2000
#: Seed spacing (deg): about the search's first step (``STEP_START``); ~3500 on the shoulder.
SEED_STEP_DEG = 4.0


class TwistRegion:
    """Swing outline and twist band (see the module docstring); ``params``: settings of the swing
    region (the defaults when None)."""

    def __init__(self, params: RegionParams | None = None) -> None:
        self.swing = TaughtRegion(params)
        self.band: TwistBand | None = None
        self.seeds = np.zeros((0, 4))
        #: Places the last fit's teaching could not support (largest cut first); empty loaded.
        self.unsupported: tuple[UnsupportedPlace, ...] = ()

    @property
    def params(self) -> RegionParams:
        """The swing region's settings."""
        return self.swing.params

    @property
    def edge(self) -> str:
        """The swing region's edge strategy taken."""
        return self.swing.edge

    @property
    def verdicts(self) -> tuple:
        """The swing region's edge verdicts of the last fit."""
        return self.swing.verdicts

    @property
    def mesh(self):
        """The swing region's direction mesh (None until fitted)."""
        return self.swing.mesh

    @property
    def support_index(self) -> np.ndarray | None:
        """Rows of the fitted samples the swing region was built on."""
        return self.swing.support_index

    def fit(self, q: np.ndarray) -> TwistRegion:
        """Learn the region from taught orientations ``q`` (N, 4); InvalidInputError for bad
        quaternions, fewer than 3, or directions within SINGULAR_MARGIN of -x."""
        q, _ = as_quaternions(q, name="samples")
        if q.shape[0] < 3:
            raise InvalidInputError(f"samples: need at least 3, got {q.shape[0]}")
        d, tau = decompose(q)
        near = np.flatnonzero(d[:, 0] < -math.cos(SINGULAR_MARGIN))
        if near.size:
            raise InvalidInputError(
                f"samples: row {int(near[0])} points the limb within "
                f"{math.degrees(SINGULAR_MARGIN):.0f} deg of -x, where twist is undefined; "
                "teach a region that keeps away from pointing backwards"
            )
        self.swing = TaughtRegion(self.swing.params).fit(d)
        mesh = self.swing.mesh
        self.band = TwistBand.fit(d, tau, mesh.axis, mesh.max_margin)
        self.unsupported = band_unsupported(self.band, d, mesh.contains_from_arcs)
        self.seeds = boundary_seeds(self)
        return self

    def _args(self) -> tuple:
        if self.band is None or self.swing.mesh is None:
            raise ConfigError("this region is not built: call fit(samples) or load a model")
        return self.swing.mesh.kernel_args(), self.band.kernel_args()

    def contains(self, q: np.ndarray) -> np.ndarray | bool:
        """Whether each orientation ((N, 4) or (4,)) lies in the region, swing and twist."""
        mesh, band = self._args()
        arr = np.asarray(q, dtype=np.float64) if isinstance(q, np.ndarray) else None
        if arr is not None and arr.shape == (4,):
            one = tk.contains_single(arr, mesh, band)
            if one < 0:
                as_quaternions(q)
            return bool(one == 1)
        arr, single = as_quaternions(q)
        kernel = tk.contains_batch if arr.shape[0] > PARALLEL_ROWS else tk.contains_serial
        inside = kernel(arr, mesh, band) == 1
        return bool(inside[0]) if single else inside

    def correct(self, q: np.ndarray) -> np.ndarray:
        """``q`` itself inside; outside, the nearest orientation of the region on SO(3)."""
        mesh, band = self._args()
        seeds, seed_dirs = self.seeds, self._seed_dirs
        arr = np.asarray(q, dtype=np.float64) if isinstance(q, np.ndarray) else None
        if arr is not None and arr.shape == (4,):
            out, status = tk.correct_single(arr, mesh, band, seeds, seed_dirs)
            if status < 0:
                as_quaternions(q)
            return out
        arr, single = as_quaternions(q)
        kernel = tk.correct_batch if arr.shape[0] > PARALLEL_CORRECT_ROWS else tk.correct_serial
        out, _ = kernel(arr, mesh, band, seeds, seed_dirs)
        return out[0] if single else out

    @property
    def seeds(self) -> np.ndarray:
        """Boundary orientations (M, 4) the nearest-orientation search starts from."""
        return self._seeds

    @seeds.setter
    def seeds(self, value: np.ndarray) -> None:
        self._seeds = np.ascontiguousarray(value, dtype=np.float64).reshape(-1, 4)
        self._seed_dirs = np.ascontiguousarray(decompose(self._seeds)[0]).reshape(-1, 3)

    def arrays(self) -> dict[str, np.ndarray]:
        """The swing mesh's, the band's and the seeds' arrays (for saving)."""
        self._args()
        return {**self.swing.arrays(), **self.band.arrays(), "twist_seeds": self.seeds}

    @classmethod
    def from_arrays(
        cls, arrays: dict[str, np.ndarray], params: RegionParams, edge: str
    ) -> TwistRegion:
        """Inverse of :meth:`arrays`, with the swing settings and edge taken when fitted."""
        region = cls(params)
        region.swing = TaughtRegion.from_arrays(arrays, params, edge)
        region.band = TwistBand.from_arrays(arrays)
        region.seeds = arrays["twist_seeds"]
        return region


def boundary_seeds(region: TwistRegion) -> np.ndarray:
    """Orientations (M, 4) on the region's boundary about SEED_STEP_DEG apart: both band limits
    over a lattice of the swing region, and twists across the band along the swing edge."""
    band, mesh = region.band, region.swing.mesh
    step = math.radians(SEED_STEP_DEG)
    inside = lattice(band, step)
    inside = inside[mesh.contains_from_arcs(inside)]
    c, h = band.at(inside)
    bounded = h < math.pi
    stops = [compose(inside[bounded], c[bounded] + sign * h[bounded]) for sign in (-1.0, 1.0)]
    edge = edge_points(mesh, step)
    return np.concatenate([*stops, across_band(band, edge, step)])


def boundary_samples(region: TwistRegion, step_deg: float) -> np.ndarray:
    """A dense sampling (M, 4) of the learned region's boundary, ``step_deg`` apart: the brute
    force :meth:`TwistRegion.correct` is checked against (edge sampled on the mesh arcs)."""
    step = math.radians(step_deg)
    inside = lattice(region.band, step)
    inside = inside[region.swing.mesh.contains(inside)]
    c, h = region.band.at(inside)
    stops = [compose(inside, c + sign * h) for sign in (-1.0, 1.0)]
    return np.concatenate([*stops, across_band(region.band, edge_points(region.mesh, step), step)])


def lattice(band: TwistBand, step: float) -> np.ndarray:
    """Directions (K, 3) on a ``step`` (rad) square lattice of the band's plane, over its grid."""
    x0, y0, grid_step = band.grid
    nx, ny = band.centre.shape
    gx = np.arange(x0, x0 + grid_step * (nx - 1), step)
    gy = np.arange(y0, y0 + grid_step * (ny - 1), step)
    xy = np.stack(np.meshgrid(gx, gy, indexing="ij"), axis=-1).reshape(-1, 2)
    return plane_to_direction(xy, band.frame)


def edge_points(mesh, step: float) -> np.ndarray:
    """Points (K, 3) along every arc of the swing mesh's edge, at most ``step`` (rad) apart."""
    a = mesh.vertices[mesh.edges[:, 0]]
    b = mesh.vertices[mesh.edges[:, 1]]
    arc = np.arccos(np.clip(np.sum(a * b, axis=1), -1.0, 1.0))
    n = np.maximum(1, np.ceil(arc / step).astype(int))
    rows = np.repeat(np.arange(a.shape[0]), n)
    f = (np.arange(rows.size) - np.repeat(np.cumsum(n) - n, n)) / np.repeat(n, n)
    p = (1.0 - f)[:, None] * a[rows] + f[:, None] * b[rows]
    p /= np.linalg.norm(p, axis=1, keepdims=True)
    return p[thin(p, step)] if p.shape[0] > 1 else p


def across_band(band: TwistBand, d: np.ndarray, step: float) -> np.ndarray:
    """Orientations over ``d`` (K, 3), twists across the band ``step`` (rad) apart, limits too."""
    c, h = band.at(d)
    k = np.ceil(2.0 * h / step).astype(int) + 1
    rows = np.repeat(np.arange(d.shape[0]), k)
    frac = np.concatenate([np.linspace(-1.0, 1.0, m) for m in k]) if k.size else np.zeros(0)
    return compose(d[rows], c[rows] + h[rows] * frac)
