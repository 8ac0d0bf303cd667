"""A region of limb directions on S^2: closed loops of great-circle arcs, each widened by its
``margin_e`` (rad). Projection is exact (the arc minimising ``angle(p, e) - margin_e``); queries
run in :mod:`limbctl.region.mesh_kernels`, ``*_reference`` answer by brute force."""

from __future__ import annotations

from dataclasses import dataclass, field
from operator import attrgetter

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from limbctl.errors import InvalidInputError
from limbctl.region import direct_kernels, grid_kernels
from limbctl.region import mesh_kernels as bk
from limbctl.region.loops import loops_to_edges


@dataclass
class DirectionMesh:
    """The learned region in direction space (all angles in radians).

    Attributes
    ----------
    vertices : (V, 3) unit directions of the boundary loops.
    edges : (E, 2) int64 boundary arcs (short great-circle arcs), the region on the left of
        a -> b seen from outside the sphere; they form closed loops.
    margins : (E,) float64, each arc's widening (rad), >= 0.
    axis : (3,) unit axis of the lookup grid; grid_shape : its (n_theta, n_phi) cells.
    cell_* : the lookup grid, None until :meth:`build_lookup` (queries then answer from the
        arcs alone, :mod:`limbctl.region.direct_kernels`, the same).
    """

    vertices: np.ndarray
    edges: np.ndarray
    margins: np.ndarray
    axis: np.ndarray
    grid_shape: np.ndarray
    cell_inside: np.ndarray | None = None
    cell_deep: np.ndarray | None = None
    cell_start: np.ndarray | None = None
    cell_edges: np.ndarray | None = None
    cell_keys: np.ndarray | None = None
    _far_inside: bool | None = field(default=None, repr=False, compare=False)

    @classmethod
    def from_loops(
        cls,
        loops: list[np.ndarray],
        margins: float | list[np.ndarray],
        cells_per_radian: float = 60.0,
        lookup: bool = True,
    ) -> DirectionMesh:
        """Region bounded by closed ``loops`` (each (M, 3) directions, region on the left).
        ``margins``: one widening (rad) for every arc, or per loop (M,), entry ``i`` for arc
        ``i -> i + 1``. ``lookup``: build the grid now (``cells_per_radian`` of polar angle)."""
        keep = [i for i, lp in enumerate(loops) if len(lp) >= 3]
        if not keep:
            raise InvalidInputError(
                "the taught directions do not span an area (need at least 3 distinct, "
                "not all on one great circle, near each other); teach more poses"
            )
        loops = [np.asarray(loops[i], dtype=np.float64) for i in keep]
        if isinstance(margins, (int, float, np.floating)):
            widen = np.full(sum(lp.shape[0] for lp in loops), float(margins))
        else:
            widen = np.concatenate([np.asarray(margins[i], dtype=np.float64) for i in keep])
        if widen.shape[0] != sum(lp.shape[0] for lp in loops) or not np.all(widen >= 0.0):
            raise InvalidInputError("margins: need one finite value >= 0 per boundary arc")
        d, edges = loops_to_edges(loops)
        d = np.ascontiguousarray(d / np.linalg.norm(d, axis=1, keepdims=True))
        edges = np.ascontiguousarray(edges, dtype=np.int64)
        widen = np.ascontiguousarray(widen)
        axis = d.mean(axis=0)
        axis /= np.linalg.norm(axis)
        n_theta = max(8, int(np.ceil(np.pi * cells_per_radian)))
        grid_shape = np.array([n_theta, 2 * n_theta], dtype=np.int64)
        mesh = cls(d, edges, widen, axis, grid_shape)
        return mesh.build_lookup() if lookup else mesh

    def build_lookup(self) -> DirectionMesh:
        """Build the lookup grid if it is not built yet; returns the mesh."""
        if self.cell_inside is None:
            inside = cell_centres_inside(self.vertices, self.edges, self.axis, self.grid_shape)
            deep, start, cell_edges, cell_keys = grid_kernels.build_grid(
                self.vertices, self.edges, self.margins, self.axis, self.grid_shape, inside
            )
            self.cell_inside, self.cell_deep = inside, deep
            self.cell_start, self.cell_edges, self.cell_keys = start, cell_edges, cell_keys
        return self

    @classmethod
    def alpha_shape(cls, directions: np.ndarray, alpha: float, margin: float) -> DirectionMesh:
        """The plain alpha shape of ``directions`` (V, 3) (circumradius <= ``alpha``)."""
        d = np.asarray(directions, dtype=np.float64)
        d = d / np.linalg.norm(d, axis=1, keepdims=True)
        tri = alpha_triangles(d, alpha)
        edges = boundary_edges(tri) if tri.shape[0] else np.empty((0, 2), dtype=np.int64)
        return cls.from_edges(d, edges, margin)

    @classmethod
    def from_edges(cls, d: np.ndarray, edges: np.ndarray, margin: float) -> DirectionMesh:
        """Region bounded by directed ``edges`` (E, 2) over directions ``d`` (closed loops)."""
        nxt = {int(a): int(b) for a, b in edges}
        loops, seen = [], set()
        for a in nxt:
            if a in seen:
                continue
            loop = []
            while a not in seen:
                seen.add(a)
                loop.append(a)
                a = nxt[a]
            loops.append(d[loop])
        return cls.from_loops(loops, margin)

    @property
    def max_margin(self) -> float:
        """The largest widening (rad): how far beyond its loops the region can reach."""
        return float(self.margins.max()) if self.margins.size else 0.0

    def contains(self, d: np.ndarray) -> np.ndarray:
        """(N,) bool for directions ``d`` (N, 3)."""
        d = np.ascontiguousarray(d, dtype=np.float64)
        if self.cell_inside is None:
            return self._direct(d, project=False)[0]
        return bk.contains_batch(*self.kernel_args(), d)

    def project(self, d: np.ndarray) -> np.ndarray:
        """Each direction itself if inside, else the nearest direction of the widened region."""
        d = np.ascontiguousarray(d, dtype=np.float64)
        if self.cell_inside is None:
            return self._direct(d, project=True)[1]
        return bk.project_batch(*self.kernel_args(), d)

    def contains_from_arcs(self, d: np.ndarray) -> np.ndarray:
        """:meth:`contains` from the arcs alone, grid built or not: the same answers."""
        return self._direct(np.ascontiguousarray(d, dtype=np.float64), project=False)[0]

    def _direct(self, d: np.ndarray, project: bool) -> tuple[np.ndarray, np.ndarray]:
        """Containment (N,) and projection (N, 3) (if ``project``) of ``d`` (N, 3) from the arcs."""
        if self._far_inside is None:
            self._far_inside = bool(
                inside_reference(-self.axis[None, :], self.vertices, self.edges)[0]
            )
        return direct_kernels.query_batch(
            self.vertices, self.edges, self.margins, self.axis, self._far_inside, d, project
        )

    def kernel_args(self) -> tuple:
        """The arrays the query kernels take, in their order (the grid built if need be)."""
        return _ARRAYS(self.build_lookup())

    def arrays(self) -> dict[str, np.ndarray]:
        """Everything needed to rebuild the mesh without recomputation (for saving)."""
        return {
            f"mesh_{name}": value for name, value in zip(_NAMES, self.kernel_args(), strict=True)
        }

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray]) -> DirectionMesh:
        """Inverse of :meth:`arrays`."""
        return cls(
            *(
                np.ascontiguousarray(arrays[f"mesh_{name}"], dtype=dtype)
                for name, dtype in zip(_NAMES, _DTYPES, strict=True)
            )
        )


#: The saved arrays (``mesh_<name>``) and the kernels' arguments, in the kernels' order.
_NAMES = ("vertices", "edges", "margins", "axis", "grid_shape", "cell_inside", "cell_deep")
_NAMES += ("cell_start", "cell_edges", "cell_keys")
_DTYPES = (np.float64, np.int64, np.float64, np.float64, np.int64, np.bool_, np.bool_)
_DTYPES += (np.int64, np.int64, np.float64)
_ARRAYS = attrgetter(*_NAMES)


def cell_centres_inside(
    vertices: np.ndarray, edges: np.ndarray, axis: np.ndarray, grid_shape: np.ndarray
) -> np.ndarray:
    """Whether each grid cell's centre lies inside the loops (n_theta * n_phi,) bool: per column,
    the parity of boundary crossings towards ``-axis``, against whether ``-axis`` is inside."""
    n_theta, n_phi = int(grid_shape[0]), int(grid_shape[1])
    u, v = bk._frame(axis)
    a = vertices[edges[:, 0]]
    b = vertices[edges[:, 1]]
    theta_c = (np.arange(n_theta) + 0.5) * np.pi / n_theta
    far_inside = bool(inside_reference(-axis[None, :], vertices, edges)[0])
    out = np.empty((n_theta, n_phi), dtype=bool)
    for j in range(n_phi):
        phi = -np.pi + (j + 0.5) * 2.0 * np.pi / n_phi
        e = np.cos(phi) * u + np.sin(phi) * v
        n = -np.sin(phi) * u + np.cos(phi) * v
        an = a @ n
        bn = b @ n
        cross = (an > 0.0) != (bn > 0.0)
        # the arc meets the meridian plane at x = (1 - t) a + t b, t = a.n / (a.n - b.n)
        t = an[cross] / (an[cross] - bn[cross])
        x = (1.0 - t)[:, None] * a[cross] + t[:, None] * b[cross]
        xe = x @ e
        theta_x = np.sort(np.arctan2(xe, x @ axis)[xe > 0.0])
        beyond = theta_x.size - np.searchsorted(theta_x, theta_c, side="right")
        out[:, j] = far_inside != (beyond % 2 == 1)
    return out.ravel()


def fan_area(p: np.ndarray, vertices: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Sum (N,) over boundary arcs a -> b of the signed area of the spherical triangle (p, a, b):
    for a region of area ``A``, ``A`` when ``-p`` is outside and ``A - 4 pi`` inside."""
    a = vertices[edges[:, 0]]
    b = vertices[edges[:, 1]]
    cross = np.cross(a, b)
    ab = np.sum(a * b, axis=1)
    total = np.zeros(p.shape[0])
    for start in range(0, p.shape[0], 2048):
        q = p[start : start + 2048]
        ang = 2.0 * np.arctan2(q @ cross.T, 1.0 + q @ a.T + ab[None, :] + q @ b.T)
        total[start : start + 2048] = ang.sum(axis=1)
    return total


def inside_reference(p: np.ndarray, vertices: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """(N,) bool: directions ``p`` (N, 3) inside the region of ``edges`` (:func:`fan_area`)."""
    return fan_area(-p, vertices, edges) < 0.0


def spherical_delaunay(d: np.ndarray) -> np.ndarray:
    """Delaunay triangles (T, 3) of unit directions ``d`` (V, 3), counter-clockwise from outside:
    the hull with the mean's antipode added (one hemisphere closes), faces touching it dropped."""
    mean = d.mean(axis=0)
    pole = -mean / np.linalg.norm(mean) if np.linalg.norm(mean) > 1e-9 else -d[0]
    pts = np.vstack([d, pole])
    try:
        hull = ConvexHull(pts)
    except QhullError as exc:
        raise InvalidInputError(f"taught directions are degenerate: {exc}") from None
    tri = hull.simplices[(hull.simplices < d.shape[0]).all(axis=1)]
    a, b, c = pts[tri[:, 0]], pts[tri[:, 1]], pts[tri[:, 2]]
    # counter-clockwise from outside: det(a, b, c) = a . (b x c) > 0
    flip = np.einsum("ij,ij->i", a, np.cross(b, c)) < 0
    tri[flip] = tri[flip][:, [0, 2, 1]]
    return np.ascontiguousarray(tri, dtype=np.int64)


def circumradius(d: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Angular circumradius (rad) of spherical triangles ``tri`` (T, 3) over vertices ``d``."""
    a, b, c = d[tri[:, 0]], d[tri[:, 1]], d[tri[:, 2]]
    # the circumcentre is the unit normal of the plane through a, b, c: (b - a) x (c - a)
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    return np.arccos(np.clip(np.abs(np.einsum("ij,ij->i", n, a)), -1.0, 1.0))


def alpha_triangles(d: np.ndarray, alpha: float) -> np.ndarray:
    """The Delaunay triangles of ``d`` whose circumradius is at most ``alpha`` (rad)."""
    tri = spherical_delaunay(d)
    return tri[circumradius(d, tri) <= alpha]


def boundary_edges(tri: np.ndarray) -> np.ndarray:
    """Directed edges (E, 2) used by exactly one triangle, the triangle on their left."""
    directed = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    key = np.sort(directed, axis=1)
    _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    return np.ascontiguousarray(directed[counts[inverse.ravel()] == 1], dtype=np.int64)
