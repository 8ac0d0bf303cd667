import numpy as np
import pytest

from limbctl.envelope import boundary_kernels as bk
from limbctl.envelope.boundary import (
    DirectionMesh,
    alpha_triangles,
    boundary_edges,
    in_triangles_reference,
    project_reference,
)
from limbctl.envelope.synthetic import ConeRegion, PolygonRegion
from limbctl.errors import InvalidInputError
from limbctl.quat import direction_angle


@pytest.fixture(scope="module", params=["cone", "bean"])
def mesh_and_region(request):
    rng = np.random.default_rng(0)
    region = ConeRegion(np.radians(35.0)) if request.param == "cone" else PolygonRegion()
    d = region.sample(500, rng)
    return DirectionMesh.build(d, np.radians(12.0), np.radians(0.3)), region


def test_grid_kernels_match_brute_force_reference(mesh_and_region):
    mesh, region = mesh_and_region
    test = region.test_directions(3000, np.random.default_rng(1))
    inside_ref, out_ref = project_reference(mesh, test)
    np.testing.assert_array_equal(mesh.contains(test), inside_ref)
    np.testing.assert_allclose(mesh.project(test), out_ref, atol=1e-12)


def test_projection_lands_in_region_at_margin(mesh_and_region):
    mesh, region = mesh_and_region
    test = region.test_directions(3000, np.random.default_rng(2))
    out = mesh.project(test)
    assert mesh.contains(out).all()
    inside = mesh.contains(test)
    np.testing.assert_array_equal(out[inside], test[inside])
    # an outside direction moves, and never by more than to the nearest mesh vertex
    moved = direction_angle(out[~inside], test[~inside])
    to_vertex = np.min(np.arccos(np.clip(test[~inside] @ mesh.vertices.T, -1, 1)), axis=1)
    assert (moved > 0).all() and (moved <= to_vertex + 1e-9).all()


def test_boundary_edges_keep_the_region_on_their_left():
    rng = np.random.default_rng(3)
    d = ConeRegion(np.radians(20.0)).sample(200, rng)
    tri = alpha_triangles(d, np.radians(10.0))
    edges = boundary_edges(tri)
    a, b = d[edges[:, 0]], d[edges[:, 1]]
    # a point just left of each edge's midpoint is in the mesh
    mid = a + b
    mid /= np.linalg.norm(mid, axis=1, keepdims=True)
    left = np.cross(a, b)
    left /= np.linalg.norm(left, axis=1, keepdims=True)
    probe = mid + 1e-6 * left
    probe /= np.linalg.norm(probe, axis=1, keepdims=True)
    assert in_triangles_reference(probe, d, tri).all()
    probe_out = mid - 1e-6 * left
    probe_out /= np.linalg.norm(probe_out, axis=1, keepdims=True)
    assert not in_triangles_reference(probe_out, d, tri).any()


def test_degenerate_directions_are_refused():
    line = np.array([[1.0, 0, 0], [0.99, 0.141, 0], [0.98, 0.199, 0]])
    line /= np.linalg.norm(line, axis=1, keepdims=True)
    with pytest.raises(InvalidInputError):
        DirectionMesh.build(line, 0.1, 0.0)


def test_slerp_dir_moves_margin_toward_target():
    p = np.array([1.0, 0, 0])
    d = np.array([0.0, 1.0, 0])
    out = bk.slerp_dir(p, d, np.pi / 2, 0.1)
    assert direction_angle(out, p) == pytest.approx(0.1, abs=1e-12)
    np.testing.assert_array_equal(bk.slerp_dir(p, d, np.pi / 2, 0.0), p)
