import numpy as np
import pytest

from limbctl.envelope.synthetic import ConeRegion, trajectory_samples
from limbctl.geometry.quat import direction_angle, normalize
from limbctl.region import shape as rs
from limbctl.region.loops import loops_to_edges
from limbctl.region.mesh import DirectionMesh, boundary_edges, inside_reference
from limbctl.region.shape import alpha_complex, trace_loops
from tests.region.support import off_x


def enclosed(p: np.ndarray, loops: list[np.ndarray]) -> np.ndarray:
    """(N,) bool: directions ``p`` (N, 3) inside the closed loops (region on their left)."""
    if not loops:
        return np.zeros(p.shape[0], dtype=bool)
    vertices, edges = loops_to_edges(loops)
    return inside_reference(p, vertices, edges)


def loops_of(d: np.ndarray, tri: np.ndarray, keep: np.ndarray) -> list[np.ndarray]:
    """Boundary loops (each (M, 3), region on the left) of the triangles ``tri[keep]`` of ``d``."""
    return [d[idx] for idx in trace_loops(d, boundary_edges(tri[keep]))]


def alpha_loops(d: np.ndarray, alpha: float, max_hole: float) -> list[np.ndarray]:
    """Loops of the alpha shape of directions ``d`` (N, 3), holes below ``max_hole`` sr filled."""
    tri, _, inside = alpha_complex(d, alpha, max_hole)
    return loops_of(d, tri, inside) if inside.any() else []


def test_thin_keeps_spacing_covers_every_point_and_alpha_follows_the_data_scale():
    d = ConeRegion(np.radians(30.0)).sample(3000, np.random.default_rng(0))
    spacing = np.radians(2.0)
    keep = rs.thin(d, spacing)
    kept = d[keep]
    dots = kept @ kept.T
    np.fill_diagonal(dots, -1.0)
    assert np.arccos(np.clip(dots.max(axis=1), -1, 1)).min() >= spacing - 1e-12
    cover = np.arccos(np.clip((d @ kept.T).max(axis=1), -1, 1))
    assert cover.max() <= spacing + 1e-12
    assert keep.size < d.shape[0] / 2
    # the learned alpha follows the data's scale
    rng = np.random.default_rng(2)
    cone = ConeRegion(np.radians(30.0))
    dense = rs.learn_alpha(cone.sample(2000, rng), 2.0)
    sparse = rs.learn_alpha(cone.sample(200, rng), 2.0)
    assert sparse > 2.0 * dense
    # hand strokes leave gaps far wider than their sample spacing: alpha follows the gaps
    strokes = trajectory_samples(cone, 3000, rng)
    thin = strokes[rs.thin(strokes, np.radians(1.0))]
    assert rs.learn_alpha(thin, 2.0) > np.radians(3.0)


def test_edge_margins_reach_the_circle_and_cover_every_sample():
    rng = np.random.default_rng(3)
    cone = ConeRegion(np.radians(25.0))
    data = cone.sample(4000, rng)
    loops = alpha_loops(data, np.radians(4.0), max_hole=0.1)
    assert len(loops) == 1
    cap = np.radians(0.75)
    margins = rs.edge_margins(loops, data, np.radians(6.0), 12, cap)[0][0]
    assert margins.shape == (loops[0].shape[0],)
    assert (margins >= 0.0).all() and (margins <= cap).all()
    mesh = DirectionMesh.from_loops(loops, [margins])
    # every taught sample inside; the widened edge sits at the circle (within the cap)
    assert mesh.contains(data).all()
    probe = cone.test_directions(20000, rng)
    inside = mesh.contains(probe)
    depth = np.degrees(cone.depth(probe))
    assert inside[depth > 1.0].mean() > 0.99
    assert not inside[depth < -0.76].any()


def test_peel_takes_back_a_bridged_concavity_keeping_every_vertex_and_what_is_surrounded():
    # samples of a "C": a bay (the notch at +y) that a large alpha bridges
    rng = np.random.default_rng(5)
    d = ConeRegion(np.radians(25.0)).sample(3000, rng)
    bay = (d[:, 1] > 0.0) & (np.abs(d[:, 2]) < np.sin(np.radians(6.0)))
    d = d[~bay]
    tri, _, inside = rs.alpha_complex(d, np.radians(20.0), max_hole=0.0)
    probe = off_x(15.0, 0.0)[None]
    assert enclosed(probe, loops_of(d, tri, inside))[0]
    protected = rs.surrounded(rs.tri_centroids(d, tri), d, np.radians(4.0), np.radians(150.0))
    kept = rs.peel(d, tri, inside, np.radians(4.0), protected)
    peeled = loops_of(d, tri, kept)
    assert not enclosed(probe, peeled)[0]
    # no vertex of the shape is dropped; the middle of the disc stays
    assert np.isin(np.unique(tri[inside]), np.unique(tri[kept])).all()
    below = np.array([[np.cos(np.radians(12.0)), 0.0, -np.sin(np.radians(12.0))]])
    assert enclosed(below, peeled)[0]
    # surrounded tells the middle and near the edge from just beyond it (all samples on one
    # side) and outside
    d = ConeRegion(np.radians(20.0)).sample(3000, np.random.default_rng(6))
    probe = off_x(np.array([0.0, 18.0, 20.5, 30.0]), np.zeros(4))
    got = rs.surrounded(probe, d, np.radians(4.0), np.radians(150.0))
    np.testing.assert_array_equal(got, [True, True, False, False])


def _pond(gap_deg):
    """A jittered 1 deg gnomonic grid (N, 3) with an empty pond |x| < 4, 3 < y < 10 whose top is
    a row of samples ``gap_deg`` apart, and three far samples above it."""
    rng = np.random.default_rng(0)
    x, y = np.meshgrid(np.arange(-10.0, 10.5), np.arange(-10.0, 10.5))
    x, y = x.ravel(), y.ravel()
    keep = ~((np.abs(x) < 4.0) & (y > 2.5))
    grid = np.column_stack([x[keep], y[keep]]) + rng.normal(0.0, 0.05, (keep.sum(), 2))
    row = np.arange(-4.0 + gap_deg, 4.0 - 1e-9, gap_deg)
    top = np.column_stack([row, np.full(row.size, 10.0)])
    far = np.array([[-10.0, 20.0], [0.0, 20.0], [10.0, 20.0]])
    xy = np.radians(np.vstack([grid, top, far]))
    d = np.column_stack([np.ones(len(xy)), xy])
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def _holds_pond(d, mouth_deg):
    tri, _, inside = rs.alpha_complex(
        d, np.radians(1.0), max_hole=0.05, mouth=np.radians(mouth_deg)
    )
    probe = np.array([[1.0, 0.0, np.tan(np.radians(6.5))]])
    return bool(enclosed(probe / np.linalg.norm(probe), loops_of(d, tri, inside))[0])


def test_a_hole_open_only_through_a_gap_narrower_than_the_mouth_is_filled():
    # the pond's top row: samples 1.6 deg apart (a traced edge) closes it under a 2 deg mouth
    assert _holds_pond(_pond(1.6), mouth_deg=2.0)
    # 2.67 deg apart: wider than the mouth, the pond is open to the outside, not a hole
    assert not _holds_pond(_pond(8.0 / 3.0), mouth_deg=2.0)
    # without a mouth (the rule off) every gap lets the outside in
    assert not _holds_pond(_pond(1.6), mouth_deg=0.0)
    # holes below max_hole are filled, larger ones kept
    d = ConeRegion(np.radians(25.0)).sample(3000, np.random.default_rng(1))
    d = d[direction_angle(d, np.array([1.0, 0, 0])) >= np.radians(8.0)]  # a ring
    alpha = np.radians(3.0)
    probe = np.array([[1.0, 0.0, 0.0]])
    filled = alpha_loops(d, alpha, max_hole=0.1)
    kept = alpha_loops(d, alpha, max_hole=1e-4)
    assert enclosed(probe, filled)[0]
    assert not enclosed(probe, kept)[0]
    assert len(kept) == len(filled) + 1


def test_a_traced_concave_corner_arc_widens_no_further_than_its_neighbours_meet():
    # a +-15 deg square (gnomonic about +x) with a notch |u| < 7, v > 2 traced 1 deg apart, its
    # left corner cut by one bridge (-4, 2) -> (-7, 5), the arc from the floor's last point
    floor = [(u, 2.0) for u in np.arange(7.0, -4.5, -1.0)]
    wall = [(-7.0, v) for v in np.arange(5.0, 15.5, 1.0)]
    uv = [(-15.0, -15.0), (15.0, -15.0), (15.0, 15.0), (7.2, 15.0), *floor, *wall, (-15.0, 15.0)]
    loop = normalize(np.column_stack([np.ones(len(uv)), np.tan(np.radians(uv))]))
    bridge = len(floor) + 3
    m = loop.shape[0]
    seg = rs.edge_lengths(loop, np.column_stack([np.arange(m), (np.arange(m) + 1) % m]))
    traced, turn = np.radians(1.25), np.radians(60.0)
    # neighbours widened by 0.75 deg meet at (-6.25, 2.75), inside the bridge: no widening
    limit = rs.corner_limits(loop, np.full(m, np.radians(0.75)), seg, np.radians(6.0), traced, turn)
    assert limit[bridge] == 0.0
    assert np.isinf(np.delete(limit, bridge)).all()
    # widened by 2 deg they meet at (-5, 4): (-5 + 4 + 2) / sqrt(2) deg beyond the bridge
    limit = rs.corner_limits(loop, np.full(m, np.radians(2.0)), seg, np.radians(6.0), traced, turn)
    assert np.degrees(limit[bridge]) == pytest.approx(1.0 / np.sqrt(2.0), abs=0.03)
    # not a corner arc: no traced neighbour, a turn below corner_turn, or a bridge among them
    for args in ((0.5 * traced, turn), (traced, np.radians(100.0))):
        assert np.isinf(rs.corner_limits(loop, np.zeros(m), seg, np.radians(6.0), *args)).all()
    assert np.isinf(rs.corner_limits(loop, np.zeros(m), seg, np.radians(4.0), traced, turn)).all()
