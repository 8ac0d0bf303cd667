import numpy as np
import pytest

from limbctl.envelope.synthetic import NOTCH, ConeRegion, PolygonRegion
from limbctl.region.mesh import DirectionMesh, inside_reference
from tests.region.support import nearest_on_edges_reference

REGIONS = {
    "cone": ConeRegion(np.radians(35.0)),
    "bean": PolygonRegion(),
    "notch": PolygonRegion(NOTCH),
}


def _meshes(name: str, margins: str) -> tuple[DirectionMesh, DirectionMesh, object]:
    """One region with its lookup grid built and without, and the true region; the arcs widened
    ``margins``: "even" (0.3 deg), "random" (up to 3 deg) or "none"."""
    rng = np.random.default_rng(11)
    region = REGIONS[name]
    mesh = DirectionMesh.alpha_shape(region.sample(800, rng), np.radians(8.0), np.radians(0.3))
    widen = {
        "even": mesh.margins,
        "random": rng.uniform(0.0, np.radians(3.0), mesh.edges.shape[0]),
        "none": np.zeros(mesh.edges.shape[0]),
    }[margins]
    arrays = (mesh.vertices, mesh.edges, widen, mesh.axis, mesh.grid_shape)
    return DirectionMesh(*arrays).build_lookup(), DirectionMesh(*arrays), region


def _probes(mesh: DirectionMesh, region, rng) -> np.ndarray:
    """Test directions near and far, the loops' vertices, points on their arcs, -axis."""
    a = mesh.vertices[mesh.edges[:, 0]]
    b = mesh.vertices[mesh.edges[:, 1]]
    on_arcs = a + rng.uniform(0.0, 1.0, (len(a), 1)) * (b - a)
    near = region.test_directions(3000, rng)
    far = rng.normal(size=(500, 3))
    d = np.vstack([near, mesh.vertices, on_arcs, far, -mesh.axis[None, :]])
    return d / np.linalg.norm(d, axis=1, keepdims=True)


@pytest.mark.parametrize("margins", ["even", "random"])
@pytest.mark.parametrize("name", ["cone", "bean", "notch"])
def test_queries_from_the_arcs_answer_as_the_grid_does(name, margins):
    with_grid, without, region = _meshes(name, margins)
    d = _probes(with_grid, region, np.random.default_rng(12))
    inside = with_grid.contains(d)
    assert 0 < inside.sum() < len(d)
    np.testing.assert_array_equal(without.contains(d), inside)
    np.testing.assert_allclose(without.project(d), with_grid.project(d), rtol=0.0, atol=1e-12)
    assert without.cell_inside is None, "answered from the arcs alone: the grid was never built"


@pytest.mark.parametrize("name", ["bean", "notch"])
def test_the_parity_count_agrees_with_the_fan_area_and_the_grid_is_built_when_saved(name):
    _, without, region = _meshes(name, "none")
    d = _probes(without, region, np.random.default_rng(13))
    _, _, to_loops = nearest_on_edges_reference(d, without.vertices, without.edges)
    clear = to_loops > 1e-6
    assert clear.sum() > 3000
    want = inside_reference(d[clear], without.vertices, without.edges)
    np.testing.assert_array_equal(without.contains(d[clear]), want)
    # a mesh without its grid builds it when saved
    _, without, _ = _meshes("cone", "even")
    assert without.cell_inside is None
    assert without.arrays()["mesh_cell_start"].size == without.grid_shape.prod() + 1
    assert without.cell_inside is not None
