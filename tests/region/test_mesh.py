import numpy as np
import pytest

from limbctl.envelope.synthetic import ConeRegion, PolygonRegion
from limbctl.errors import InvalidInputError
from limbctl.geometry.quat import direction_angle, normalize
from limbctl.region import grid_kernels
from limbctl.region import mesh as dm
from limbctl.region import mesh_kernels as bk
from limbctl.region.evidence import loop_arcs
from limbctl.region.mesh import DirectionMesh
from limbctl.region.mesh_kernels import CONTAIN_TOLERANCE
from tests.region.grid_reference import build_grid_reference
from tests.region.support import circle, nearest_on_edges_reference


def in_triangles_reference(d: np.ndarray, vertices: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """(N,) bool: each direction in at least one spherical triangle (edges included)."""
    a, b, c = vertices[tri[:, 0]], vertices[tri[:, 1]], vertices[tri[:, 2]]
    # inside iff on the left of (or on) all three edge planes: det(a, b, p) >= 0, ...
    left = [d @ np.cross(p, q).T >= 0 for p, q in ((a, b), (b, c), (c, a))]
    return (left[0] & left[1] & left[2] & (d @ (a + b + c).T > 0)).any(axis=1)


def answers_as_reference(mesh: DirectionMesh, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``mesh``'s ``(contains, project)`` of directions ``d`` (N, 3), checked against brute force
    (the projections within 1e-12 and inside the mesh)."""
    inside_mesh = dm.inside_reference(d, mesh.vertices, mesh.edges)
    edge, point, angle = nearest_on_edges_reference(d, mesh.vertices, mesh.edges, mesh.margins)
    margin = mesh.margins[edge]
    inside_ref = inside_mesh | (angle - margin <= CONTAIN_TOLERANCE)
    # outside: from the nearest boundary point, go that arc's margin along the path toward d
    out_ref = d.copy()
    for i in np.flatnonzero(~inside_ref):
        out_ref[i] = bk.slerp_dir(point[i], d[i], angle[i], margin[i])
    inside, out = mesh.contains(d), mesh.project(d)
    np.testing.assert_array_equal(inside, inside_ref)
    np.testing.assert_allclose(out, out_ref, atol=1e-12)
    assert mesh.contains(out).all()
    return inside, out


@pytest.fixture(scope="module", params=["cone", "bean"])
def mesh_and_region(request):
    rng = np.random.default_rng(0)
    region = ConeRegion(np.radians(35.0)) if request.param == "cone" else PolygonRegion()
    d = region.sample(500, rng)
    return DirectionMesh.alpha_shape(d, np.radians(12.0), np.radians(0.3)), region


def test_grid_kernels_match_brute_force_and_project_into_the_region(mesh_and_region):
    mesh, region = mesh_and_region
    test = region.test_directions(3000, np.random.default_rng(1))
    inside, out = answers_as_reference(mesh, test)
    np.testing.assert_array_equal(out[inside], test[inside])
    # an outside direction moves, and never by more than to the nearest mesh vertex
    moved = direction_angle(out[~inside], test[~inside])
    to_vertex = np.min(np.arccos(np.clip(test[~inside] @ mesh.vertices.T, -1, 1)), axis=1)
    assert (moved > 0).all() and (moved <= to_vertex + 1e-9).all()
    # the grid's cells inside: the fan-area reference at their centres
    n_theta, n_phi = mesh.grid_shape
    u, v = bk._frame(mesh.axis)
    i, j = np.divmod(np.arange(n_theta * n_phi), n_phi)
    theta = (i + 0.5) * np.pi / n_theta
    phi = -np.pi + (j + 0.5) * 2.0 * np.pi / n_phi
    centres = np.cos(theta)[:, None] * mesh.axis + np.sin(theta)[:, None] * (
        np.cos(phi)[:, None] * u + np.sin(phi)[:, None] * v
    )
    ref = dm.inside_reference(centres, mesh.vertices, mesh.edges)
    got = dm.cell_centres_inside(mesh.vertices, mesh.edges, mesh.axis, mesh.grid_shape)
    np.testing.assert_array_equal(got, ref)
    assert 0 < got.sum() < got.size


def test_boundary_edges_keep_the_region_on_their_left():
    rng = np.random.default_rng(3)
    d = ConeRegion(np.radians(20.0)).sample(200, rng)
    tri = dm.alpha_triangles(d, np.radians(10.0))
    edges = dm.boundary_edges(tri)
    a, b = d[edges[:, 0]], d[edges[:, 1]]
    # a point just left of each edge's midpoint is in the mesh
    mid, left = normalize(a + b), normalize(np.cross(a, b))
    assert in_triangles_reference(normalize(mid + 1e-6 * left), d, tri).all()
    assert not in_triangles_reference(normalize(mid - 1e-6 * left), d, tri).any()


def test_inside_reference_beyond_a_hemisphere():
    # a cap of 100 deg: points and their antipodes can both be inside
    r = np.radians(100.0)
    mesh = DirectionMesh.from_loops([circle(100.0, 400)], 0.0)
    test = ConeRegion(np.radians(150.0)).test_directions(4000, np.random.default_rng(5))
    truth = direction_angle(test, np.array([1.0, 0, 0])) < r
    far = np.abs(direction_angle(test, np.array([1.0, 0, 0])) - r) > 1e-3
    np.testing.assert_array_equal(mesh.contains(test)[far], truth[far])
    np.testing.assert_array_equal(
        dm.inside_reference(test, mesh.vertices, mesh.edges)[far], truth[far]
    )


def test_per_arc_margins_match_reference_and_bound_the_region():
    rng = np.random.default_rng(7)
    region = PolygonRegion()
    d = region.sample(600, rng)
    base = DirectionMesh.alpha_shape(d, np.radians(10.0), 0.0)
    margins = rng.uniform(0.0, np.radians(1.5), base.edges.shape[0])
    # rebuild through the public constructor: one loop per closed chain of arcs
    runs = loop_arcs(base)
    loops = [base.vertices[base.edges[run, 0]] for run in runs]
    widen = [margins[run] for run in runs]
    mesh = DirectionMesh.from_loops(loops, widen)
    test = region.test_directions(3000, np.random.default_rng(8))
    _, out = answers_as_reference(mesh, test)
    # the region reaches no farther than the largest margin beyond the loops
    plain = DirectionMesh.from_loops(loops, 0.0)
    _, _, gap = nearest_on_edges_reference(out, plain.vertices, plain.edges)
    assert (gap[~plain.contains(out)] <= mesh.max_margin + 1e-9).all()


def test_degenerate_directions_and_bad_margins_are_refused():
    line = normalize([[1.0, 0, 0], [0.99, 0.141, 0], [0.98, 0.199, 0]])
    with pytest.raises(InvalidInputError):
        DirectionMesh.alpha_shape(line, 0.1, 0.0)
    loop = normalize([[1.0, 0, 0], [0.9, 0.3, 0], [0.9, 0, 0.3]])
    with pytest.raises(InvalidInputError, match="margins"):
        DirectionMesh.from_loops([loop], [np.array([0.1, -0.1, 0.0])])
    with pytest.raises(InvalidInputError, match="margins"):
        DirectionMesh.from_loops([loop], [np.array([0.1, 0.1])])


@pytest.mark.parametrize("widest_deg", [None, 3.0])
def test_the_pruned_grid_is_the_brute_force_grid(mesh_and_region, widest_deg):
    # build_grid measures only the arcs its bounds cannot rule out; measuring every arc from
    # every cell's centre must give the same cells, arcs and keys, to the bit; per-arc margins
    # up to 3 deg make the keys and both minimisers differ from the plain angles
    mesh, _ = mesh_and_region
    margins = mesh.margins
    if widest_deg:
        rng = np.random.default_rng(7)
        margins = rng.uniform(0.0, np.radians(widest_deg), mesh.edges.shape[0])
    args = (mesh.vertices, mesh.edges, margins, mesh.axis, mesh.grid_shape, mesh.cell_inside)
    fast = grid_kernels.build_grid(*args)
    slow = build_grid_reference(*args)
    for got, want in zip(fast, slow, strict=True):
        assert got.dtype == want.dtype and np.array_equal(got, want)
    assert fast[0].any() and (~fast[0]).any() and fast[2].size > 0


def test_edge_foot_is_nearest_on_arc_bit_for_bit_and_slerp_dir_moves_by_the_margin():
    rng = np.random.default_rng(7)
    vertices = normalize(rng.normal(size=(60, 3)))
    # a repeated vertex (no great circle), antipodes, and near neighbours
    vertices[1] = vertices[0]
    vertices[3] = -vertices[2]
    vertices[5] = normalize(vertices[4] + 1e-9)
    edges = np.stack([np.arange(0, 60, 2), np.arange(1, 60, 2)], axis=1).astype(np.int64)
    points = normalize(rng.normal(size=(200, 3)))
    # the arcs' own vertices and the poles of their great circles (no foot)
    a, b = vertices[edges[:, 0]], vertices[edges[:, 1]]
    points = np.concatenate([points, a, b, normalize(np.cross(a[2:], b[2:]))])
    out = np.empty(3)
    for p in points:
        for e in range(edges.shape[0]):
            angle = bk.nearest_on_arc(p, vertices[edges[e, 0]], vertices[edges[e, 1]], out)
            got = bk.edge_foot(p, vertices, edges, e)
            assert np.array_equal([angle, *out], list(got), equal_nan=True), (p, e)
    # slerp_dir moves the margin toward the target
    p = np.array([1.0, 0, 0])
    d = np.array([0.0, 1.0, 0])
    out = bk.slerp_dir(p, d, np.pi / 2, 0.1)
    assert direction_angle(out, p) == pytest.approx(0.1, abs=1e-12)
    np.testing.assert_array_equal(bk.slerp_dir(p, d, np.pi / 2, 0.0), p)
