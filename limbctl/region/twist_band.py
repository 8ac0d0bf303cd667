"""The twist band over the swing region: how far the limb may turn about its own axis, by direction.

The band over direction ``d`` is the arc of twists ``|wrap(tau - c(d))| <= h(d)``: a centre ``c``
and a half-width ``h`` (rad; ``h = pi`` is a free twist), never two limits that could straddle
+-pi. Both are kept on a square grid in the azimuthal equidistant plane about the band's axis,
``(x, y) = theta (d.u, d.v) / |(d.u, d.v)|`` with ``theta`` the angle from the axis, and read
bilinearly (:func:`limbctl.region.twist_kernels.band_at`).

Fitting, per grid node, from the samples within ``BAND_RADIUS_DEG`` (docs/region.md, "Twist band"):

1. *First reading*: heights over the node of the upper and lower hulls of (position, twist).
2. *Second reading*: the weighted least-squares plane through each first-read limit's stops.
3. *Envelope*: widened to bounded upward curvature ``ENVELOPE_CURVATURE`` (:func:`_raised`).
4. *Evidence cap*: narrowed to the taught twists' support (:mod:`limbctl.region.twist_evidence`)."""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial import ConvexHull, QhullError, cKDTree

from limbctl.errors import InvalidInputError
from limbctl.geometry.quat import tangent_frame
from limbctl.geometry.twist import wrap
from limbctl.region import twist_fit_kernels as fk
from limbctl.region import twist_kernels as tk
from limbctl.region.twist_evidence import cap_limits, curvature_floors, inside_hull

#: Grid spacing (deg) of the band's nodes: a 1 deg/deg limit errs by its curvature over 1.5 deg.
BAND_STEP_DEG = 1.5
#: Neighbourhood (deg) a node reads its band from: ~25 samples a stop; at 4 deg ~20 % unsurrounded.
BAND_RADIUS_DEG = 8.0
#: Highest (lowest) twists a node's hull is taken over: 2024 triangles; 16 missed stops.
HULL_TOP = 24
#: Largest empty arc (deg) of neighbours' twists that leaves the twist free: full turns gap a few.
FREE_GAP_DEG = 10.0
#: Samples this close (deg) to a first-read limit are its stop's: the first reading errs ~1 deg.
STOP_BAND_DEG = 1.5
#: Weight width (deg, one sigma) of the second reading's plane: ~10 stops of each side within it.
REFINE_SIGMA_DEG = 5.0
#: Steepest limit (rad/rad) either reading believes: shoulders 0.5-0.7; 3 erred beside sparse stops.
MAX_SLOPE = 1.0
#: The first reading's grid is this many times coarser: it only sorts samples into stops (x4 fewer).
FIRST_COARSENESS = 2
#: Nodes kept beyond the farthest taught direction (grid steps): the swing region's margins.
GRID_PAD = 4
#: Largest upward curvature (rad^-1) of the envelope: the shoulder's limits curve up to ~1.
ENVELOPE_CURVATURE = 0.75
#: Largest sag (deg) where stops lie far apart: stops lie 1 deg inside, the issue asks 2 deg inside.
ENVELOPE_SAG_DEG = 0.5
#: Flattest curvature (rad^-1) of the sag cap: keeps 0.5 deg for stops up to 26 deg apart.
ENVELOPE_CURVATURE_MIN = 0.35
#: Sag factor at most ``ENVELOPE_STOP_SPAN r^2 / 2``, r to the nearest stop: 4 over-reaches as 1.
ENVELOPE_STOP_SPAN = 4.0
#: Re-reads of the cap's stops against the capped band (curved seed 1: 2.10 -> 0.64 deg past truth).
STOP_REREADS = 1
#: Nodes per block when all the envelope's facets are evaluated (memory: block x facets floats).
ENVELOPE_BLOCK = 512
#: Nearest facets tried per node before all: the one over it is among 16 for all but a few.
ENVELOPE_CANDIDATES = 16


class TwistBand:
    """Twist band over directions (see the module docstring): ``frame`` (3, 3), rows the plane's
    axis, u, v (right-handed); ``grid`` (3,), ``(x0, y0, step)`` of the node grid (rad); ``centre``,
    ``half`` (nx, ny), band centre (unwrapped, rad) and half-width (rad, in [0, pi]) at each node.
    """

    def __init__(
        self, frame: np.ndarray, grid: np.ndarray, centre: np.ndarray, half: np.ndarray
    ) -> None:
        self.frame = np.ascontiguousarray(frame, dtype=np.float64)
        self.grid = np.ascontiguousarray(grid, dtype=np.float64)
        self.centre = np.ascontiguousarray(centre, dtype=np.float64)
        self.half = np.ascontiguousarray(half, dtype=np.float64)
        #: (nodes (M, 3), upper cut (M,), lower cut (M,)) rad of the last fit's cap; None loaded.
        self.cuts: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None

    @classmethod
    def fit(cls, d: np.ndarray, tau: np.ndarray, axis: np.ndarray, reach: float) -> TwistBand:
        """Learn the band from taught directions ``d`` (N, 3) and twists ``tau`` (N,) (rad).
        ``axis`` (3,) is the plane's axis (the swing region's); ``reach`` (rad) how far beyond the
        taught directions the grid must extend (the swing region's largest margin)."""
        d = np.ascontiguousarray(d, dtype=np.float64)
        tau = np.ascontiguousarray(tau, dtype=np.float64)
        u, v = tangent_frame(np.asarray(axis, dtype=np.float64))
        frame = np.stack([axis, u, v])
        xy = plane_xy(d, frame)
        step = math.radians(BAND_STEP_DEG)
        pad = reach + GRID_PAD * step
        lo = xy.min(axis=0) - pad
        n = np.ceil((xy.max(axis=0) + pad - lo) / step).astype(int) + 1
        coarse = cls._first(d, tau, frame, lo, step * FIRST_COARSENESS, n // FIRST_COARSENESS + 2)
        nodes = _grid_nodes(frame, lo, step, n)
        start, members = _neighbours(nodes, d)
        ref, half = coarse.at(nodes)
        band = cls(frame, np.array([lo[0], lo[1], step]), ref.reshape(n), half.reshape(n))
        band._refine(coarse, nodes, start, members, d, tau)
        return band

    @classmethod
    def _first(cls, d, tau, frame, lo, step, n) -> TwistBand:
        """The first reading (the module docstring, step 1) on a grid ``step`` (rad) apart."""
        nodes = _grid_nodes(frame, lo, step, n)
        start, members = _neighbours(nodes, d)
        centre, half = fk.fit_nodes(
            nodes, start, members, d, tau, HULL_TOP, math.radians(FREE_GAP_DEG), MAX_SLOPE
        )
        fitted = np.isfinite(centre)
        if not fitted.any():
            raise InvalidInputError(
                "samples: no twist band could be learned (too few samples around any direction: "
                "teach the twist both ways at many directions)"
            )
        if not fitted.all():
            # nodes the samples do not surround: the nearest fitted node's band
            _, nearest = cKDTree(nodes[fitted]).query(nodes[~fitted])
            centre[~fitted] = centre[fitted][nearest]
            half[~fitted] = half[fitted][nearest]
        centre = unwrap_grid(centre.reshape(n[0], n[1]))
        return cls(frame, np.array([lo[0], lo[1], step]), centre, half.reshape(n[0], n[1]))

    def _refine(
        self,
        first: TwistBand,
        nodes: np.ndarray,
        start: np.ndarray,
        members: np.ndarray,
        d: np.ndarray,
        tau: np.ndarray,
    ) -> None:
        """Second reading of both limits (the module docstring, step 2) from the ``first``."""
        c1, h1 = first.at(d)
        # each sample's twist unwrapped against the (continuous) first centre over it
        limit = c1 + wrap(tau - c1)
        near = math.radians(STOP_BAND_DEG)
        ref = self.centre.ravel()
        half = self.half.ravel()
        sigma = math.radians(REFINE_SIGMA_DEG)
        limits = []
        stops = []
        for sign in (1.0, -1.0):
            stop = (sign * (limit - c1) >= h1 - near) & (h1 < math.pi)
            stops.append(stop)
            first_read = sign * half
            rel = fk.refine_nodes(nodes, start, members, d, limit, stop, ref, sigma, MAX_SLOPE)
            limits.append(np.where(np.isfinite(rel), rel, first_read))
        up, lo = limits
        # step 3: widened to the envelope of every sample (relative to the node's centre)
        xy = plane_xy(d, self.frame)
        x0, y0, step = self.grid
        nx, ny = self.centre.shape
        gx, gy = np.meshgrid(x0 + step * np.arange(nx), y0 + step * np.arange(ny), indexing="ij")
        node_xy = np.column_stack([gx.ravel(), gy.ravel()])
        bounded = half < math.pi
        up = np.where(bounded, np.fmax(up, envelope_heights(xy, limit, node_xy) - ref), up)
        lo = np.where(bounded, np.fmin(lo, -envelope_heights(xy, -limit, node_xy) - ref), lo)
        # step 4: never past what the taught twists support (limbctl.region.twist_evidence)
        args = (bounded, nodes, start, members, d, limit, ref)
        within = inside_hull(xy, node_xy)
        floors = curvature_floors(xy, limit, node_xy, ref)
        capped = cap_limits(up, lo, *args, tuple(stops), within, floors)
        for _ in range(STOP_REREADS):
            # the stops re-read against the capped band: a bridged dip's bottom holds its stops
            c2, h2 = self._with_limits(ref, half, *capped[:2]).at(d)
            off = wrap(limit - c2)
            stops = [(off >= h2 - near) & (h2 < math.pi), (-off >= h2 - near) & (h2 < math.pi)]
            capped = cap_limits(up, lo, *args, tuple(stops), within, floors)
        up, lo, cut_up, cut_lo = capped
        self.cuts = (nodes, cut_up, cut_lo)
        new = self._with_limits(ref, half, up, lo)
        self.centre, self.half = new.centre, new.half

    def _with_limits(self, ref, half, up, lo) -> TwistBand:
        """This band's grid with limits ``up``, ``lo`` (M,) about the node centres ``ref`` (M,)
        (rad); nodes whose ``half`` (M,) is pi stay free, crossed limits keep the centre."""
        ok = up >= lo
        centre = np.where(ok, ref + 0.5 * (up + lo), ref)
        half = np.where(ok & (half < math.pi), 0.5 * (up - lo), half)
        return TwistBand(
            self.frame,
            self.grid,
            centre.reshape(self.centre.shape),
            np.clip(half, 0.0, math.pi).reshape(self.half.shape),
        )

    def at(self, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Centre and half-width (N,), (N,) (rad) over directions ``d`` (N, 3) (the kernel)."""
        d = np.ascontiguousarray(np.atleast_2d(d), dtype=np.float64)
        return tk.band_batch(d, self.frame, self.grid, self.centre, self.half)

    def kernel_args(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The arrays the kernels take: ``(frame, grid, centre, half)``."""
        return (self.frame, self.grid, self.centre, self.half)

    def arrays(self) -> dict[str, np.ndarray]:
        """Everything needed to answer without refitting (for saving)."""
        return {
            "twist_frame": self.frame,
            "twist_grid": self.grid,
            "twist_centre": self.centre,
            "twist_half": self.half,
        }

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray]) -> TwistBand:
        """Inverse of :meth:`arrays`."""
        return cls(
            arrays["twist_frame"],
            arrays["twist_grid"],
            arrays["twist_centre"],
            arrays["twist_half"],
        )


def envelope_heights(xy: np.ndarray, t: np.ndarray, node_xy: np.ndarray) -> np.ndarray:
    """Heights (M,) at plane points ``node_xy`` (M, 2) (rad) of a function lying on or above every
    sample ``(xy, t)`` ((N, 2), (N,), rad): the smallest one whose upward curvature is at most
    ENVELOPE_CURVATURE (``k |x|^2 / 2`` plus the upper concave hull of ``t - k |x|^2 / 2``), raised
    where its stops lie far apart so that it sags below their plane by at most ENVELOPE_SAG_DEG, or
    as a curvature of ENVELOPE_CURVATURE_MIN would (:func:`_raised`). Points outside the samples'
    convex hull take the height at the nearest point inside; NaN everywhere when the samples span no
    area."""
    k = ENVELOPE_CURVATURE
    # lifted: s_i = t_i - k |x_i|^2 / 2
    lifted = t - 0.5 * k * np.sum(xy * xy, axis=1)
    try:
        hull = ConvexHull(np.column_stack([xy, lifted]))
        rim = ConvexHull(xy).equations
    except (QhullError, ValueError):
        return np.full(node_xy.shape[0], np.nan)
    # facets a x + b y + c s + e = 0 with outward normal up (c > 0): s = -(a x + b y + e) / c
    up = hull.equations[:, 2] > 1e-9
    eq = hull.equations[up]
    facets = (-eq[:, :2] / eq[:, 2:3], -eq[:, 3] / eq[:, 2], xy[hull.simplices[up]])
    # inside the samples' convex hull: on the inner side of every rim line (a . x + e <= 0)
    rows = np.flatnonzero(np.all(node_xy @ rim[:, :2].T + rim[:, 2] <= 1e-12, axis=1))
    out = np.full(node_xy.shape[0], np.nan)
    if rows.size:
        p = node_xy[rows]
        height, factor = _over_facets(p, *facets)
        # h(x) = hull(x) + k |x|^2 / 2
        out[rows] = height + 0.5 * k * np.sum(p * p, axis=1)
        out[rows] += _raised(p, factor, xy, t, np.unique(hull.simplices[up]), facets)
    if rows.size and rows.size < out.size:
        outside = np.setdiff1d(np.arange(out.size), rows)
        _, nearest = cKDTree(node_xy[rows]).query(node_xy[outside])
        out[outside] = out[rows[nearest]]
    return out


def _over_facets(
    p: np.ndarray, slope: np.ndarray, offset: np.ndarray, corners: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Height (M,) of the hull's facets ``slope . x + offset`` ((F, 2), (F,)) at points ``p``
    (M, 2) inside it (the least plane, at the facet over each point) and the sag factor
    (:func:`_sag_factor`, (M,), rad^2) of that facet's corners ``corners`` (F, 3, 2) there."""
    count = min(ENVELOPE_CANDIDATES, slope.shape[0])
    _, cand = cKDTree(corners.mean(axis=1)).query(p, k=count)
    cand = cand.reshape(p.shape[0], count)
    heights = np.einsum("mj,mkj->mk", p, slope[cand]) + offset[cand]
    facet = cand[np.arange(p.shape[0]), np.argmin(heights, axis=1)]
    missed = np.flatnonzero(~_over_any(p, corners[cand]))
    for first in range(0, missed.size, ENVELOPE_BLOCK):
        block = missed[first : first + ENVELOPE_BLOCK]
        facet[block] = np.argmin(p[block] @ slope.T + offset, axis=1)
    height = np.einsum("mj,mj->m", p, slope[facet]) + offset[facet]
    return height, _sag_factor(p, corners[facet])


def _raised(
    p: np.ndarray,
    factor: np.ndarray,
    xy: np.ndarray,
    t: np.ndarray,
    corners: np.ndarray,
    facets: tuple[np.ndarray, np.ndarray, np.ndarray],
) -> np.ndarray:
    """How far (M,) (rad) the envelope is raised at points ``p`` (M, 2) over facets of sag factor
    ``factor`` (M,) (rad^2); ``(xy, t)`` the samples, ``corners`` the indices of those on the hull's
    upper facets, ``facets`` the hull's upper facets (as :func:`_over_facets` takes them). The sag
    ``k S`` is capped at ``max(s, k_min S)`` (s = ENVELOPE_SAG_DEG, k_min = ENVELOPE_CURVATURE_MIN),
    ``S`` taken at most ``ENVELOPE_STOP_SPAN r^2 / 2``, ``r`` the distance to the nearest stop
    (docs/region.md, "Twist band")."""
    k = ENVELOPE_CURVATURE

    def raised(f: np.ndarray, r: np.ndarray) -> np.ndarray:
        f = np.fmin(f, 0.5 * ENVELOPE_STOP_SPAN * r * r)
        # sag k S capped at max(s, k_min S)
        return np.fmax(
            k * f - np.fmax(math.radians(ENVELOPE_SAG_DEG), ENVELOPE_CURVATURE_MIN * f), 0.0
        )

    r, _ = cKDTree(xy[corners]).query(p)
    need = np.flatnonzero(raised(factor, r) > 0.0)
    if need.size:
        near = cKDTree(xy).query_ball_point(p[need], r[need])
        judged = np.setdiff1d(
            np.unique(np.concatenate([np.asarray(n, int) for n in near])), corners
        )
        if judged.size:
            h, _ = _over_facets(xy[judged], *facets)
            h += 0.5 * k * np.sum(xy[judged] ** 2, axis=1)
            stops = judged[h - t[judged] <= math.radians(STOP_BAND_DEG)]
            if stops.size:
                r[need] = np.fmin(r[need], cKDTree(xy[stops]).query(p[need])[0])
    return raised(factor, r)


def _sag_factor(p: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """``S(x) = (R^2 - |x - c|^2) / 2`` (M,) (rad^2) at points ``p`` (M, 2) in triangles ``tri``
    (M, 3, 2) with circumcircle (c, R): a function of curvature k through the corners sags
    ``k S(x)`` below their plane; 0 outside the triangle."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    # barycentric weights of p; S = (sum_i l_i |x_i|^2 - |p|^2) / 2
    e1, e2, r = b - a, c - a, p - a
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    safe = np.where(det != 0.0, det, 1.0)
    lb = (r[:, 0] * e2[:, 1] - r[:, 1] * e2[:, 0]) / safe
    lc = (e1[:, 0] * r[:, 1] - e1[:, 1] * r[:, 0]) / safe
    la = 1.0 - lb - lc
    sq = np.sum(tri * tri, axis=2)
    s = 0.5 * (la * sq[:, 0] + lb * sq[:, 1] + lc * sq[:, 2] - np.sum(p * p, axis=1))
    return np.where(det != 0.0, np.fmax(s, 0.0), 0.0)


def _over_any(p: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Whether each point ``p`` (M, 2) lies in any of its triangles ``tri`` (M, K, 3, 2)."""
    a, b, c = tri[:, :, 0], tri[:, :, 1], tri[:, :, 2]
    q = p[:, None, :]

    def cross(u: np.ndarray, v: np.ndarray, w: np.ndarray) -> np.ndarray:
        # z of (v - u) x (w - u)
        return (v[..., 0] - u[..., 0]) * (w[..., 1] - u[..., 1]) - (v[..., 1] - u[..., 1]) * (
            w[..., 0] - u[..., 0]
        )

    area = cross(a, b, c)
    s = np.sign(area)
    tol = 1e-12 * np.abs(area)
    inside = (
        (s * cross(a, b, q) >= -tol) & (s * cross(b, c, q) >= -tol) & (s * cross(c, a, q) >= -tol)
    )
    return np.any(inside & (area != 0.0), axis=1)


def _grid_nodes(frame: np.ndarray, lo: np.ndarray, step: float, n: np.ndarray) -> np.ndarray:
    """Directions (n0 n1, 3) of the plane grid from ``lo`` (2,), ``step`` (rad) apart, row major."""
    gx = lo[0] + step * np.arange(n[0])
    gy = lo[1] + step * np.arange(n[1])
    return plane_to_direction(
        np.stack(np.meshgrid(gx, gy, indexing="ij"), axis=-1).reshape(-1, 2), frame
    )


def _neighbours(nodes: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Samples within BAND_RADIUS_DEG of each node, CSR: ``members[start[i]:start[i + 1]]``."""
    # chord of the neighbourhood's angle; pairs (node, sample) within it, by node
    chord = 2.0 * math.sin(0.5 * math.radians(BAND_RADIUS_DEG))
    pairs = cKDTree(nodes).sparse_distance_matrix(cKDTree(d), chord, output_type="ndarray")
    order = np.argsort(pairs["i"], kind="stable")
    members = np.ascontiguousarray(pairs["j"][order], dtype=np.int64)
    counts = np.bincount(pairs["i"], minlength=nodes.shape[0])
    return np.concatenate([[0], np.cumsum(counts)]).astype(np.int64), members


def plane_xy(d: np.ndarray, frame: np.ndarray) -> np.ndarray:
    """Azimuthal equidistant coordinates (N, 2) (rad) of unit directions ``d`` (N, 3) about
    ``frame[0]``: ``theta (d.u, d.v) / |(d.u, d.v)|``, ``theta = atan2(|(d.u, d.v)|, d.axis)``."""
    d = np.atleast_2d(np.asarray(d, dtype=np.float64))
    su, sv, ca = d @ frame[1], d @ frame[2], d @ frame[0]
    s = np.hypot(su, sv)
    theta = np.arctan2(s, ca)
    scale = np.where(s > 1e-15, theta / np.where(s > 0, s, 1.0), 0.0)
    return np.stack([scale * su, scale * sv], axis=-1)


def plane_to_direction(xy: np.ndarray, frame: np.ndarray) -> np.ndarray:
    """Inverse of :func:`plane_xy`: unit directions (N, 3) of plane points (N, 2) (rad)."""
    theta = np.hypot(xy[:, 0], xy[:, 1])
    # d = cos(theta) axis + sin(theta) (x u + y v) / theta
    scale = np.where(theta > 1e-15, np.sin(theta) / np.where(theta > 0, theta, 1.0), 1.0)
    return (
        np.cos(theta)[:, None] * frame[0]
        + (scale * xy[:, 0])[:, None] * frame[1]
        + (scale * xy[:, 1])[:, None] * frame[2]
    )


def unwrap_grid(centre: np.ndarray) -> np.ndarray:
    """Centres (nx, ny) unwrapped: the first column along x, then every row along y from it,
    so neighbouring nodes never differ by more than pi."""
    out = np.array(centre, dtype=np.float64)
    out[:, 0] = np.unwrap(out[:, 0])
    return np.unwrap(out, axis=1)
