"""The kept edge is held to the taught evidence where it stands past it (issue 35, finding 1)."""

import numpy as np
import pytest
from scipy.spatial import cKDTree

from limbctl.envelope.synthetic import PolygonRegion, reach_into
from limbctl.geometry.gimbal import pan_tilt_to_direction
from limbctl.geometry.twist import decompose
from limbctl.region import TaughtRegion
from limbctl.region import evidence as ev
from limbctl.region import taught as taught_module
from limbctl.region.edge_hold import _cut_slivers, hold_to_evidence
from limbctl.region.evidence_clip import CLIP_REACH_DEG, DEEP_DEG, Clip
from limbctl.region.mesh import DirectionMesh
from tests.region.support import benchmark
from tests.region.test_evidence import notched_ellipse

#: The scan's own step (deg): a direction of the region lies within half a diagonal of it.
SCAN_DEG = 0.1
#: Step (deg) at which the held edge is checked: a point between two checked ones lies at most
#: half of it farther from the samples.
CHECK_DEG = 0.02


@pytest.fixture(scope="module")
def sparse_notch():
    """A notched ellipse taught with 1500 i.i.d. samples: truth, teaching, the scan's box, the
    region held, unheld, and held but not cut back to the evidence."""
    outline, _ = notched_ellipse(27.2, 23.4, (-5.7, 7.2), 273.0, 9.0, 8.0)
    truth = PolygonRegion(outline)
    taught = truth.sample(1500, np.random.default_rng(1))
    lo, hi = outline.min(axis=0) - 4.0, outline.max(axis=0) + 4.0
    region = TaughtRegion().fit(taught)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(
            taught_module, "cut_to_evidence", lambda mesh, data, *_, **__: Clip.nothing(mesh)
        )
        held_uncut = TaughtRegion().fit(taught)
        mp.setattr(taught_module, "hold_to_evidence", lambda mesh, data, *_, **__: (mesh, False))
        unheld = TaughtRegion().fit(taught)
    return truth, taught, ((lo[0], hi[0]), (lo[1], hi[1])), region, unheld, held_uncut


def test_a_sparse_teaching_is_held_to_the_evidence(sparse_notch):
    truth, taught, box, region, unheld, held_uncut = sparse_notch
    reach = reach_into(region.contains, truth, box, step_deg=SCAN_DEG)
    bound = ev.REACH_DEG + 0.5 * ev.STATION_DEG + np.hypot(SCAN_DEG, SCAN_DEG)
    assert region.held_edge and region.unsupported_edge
    assert reach <= bound, f"the held region reaches {reach:.2f} deg past the truth"
    # the report names the stretches held; the cut names its places held
    assert any(s.held for s in region.unsupported_edge)
    assert any("held at the evidence" in s.line() for s in region.unsupported_edge)
    d = taught_module.taught_directions(taught)
    # named unheld: the places the holds left past the reach that still stand past it after the cut
    far = np.radians(ev.REACH_DEG + ev.HELD_SLACK_DEG)
    cut_left = ev.unsupported_stretches(region.mesh, d, far, surrounded=False)
    hold_left = ev.unsupported_stretches(held_uncut.mesh, d, far, surrounded=False)
    still = [s for s in hold_left if ev.at_same_place(s, cut_left)]
    left = [s for s in region.unsupported_edge if not s.held]
    assert bool(still) == bool(left), (still, left)
    assert all(s.distance_deg > ev.REACH_DEG + ev.HELD_SLACK_DEG for s in left)
    # unheld, the region reaches past the bound; held, it keeps every sample the unheld one held
    assert reach_into(unheld.contains, truth, box, step_deg=SCAN_DEG) > bound
    assert not np.any(unheld.mesh.contains(d) & ~region.mesh.contains(d)), "a taught sample lost"
    assert reach <= 1.0, f"the patient tight hold reaches {reach:.2f} deg past the truth"


def test_a_region_with_no_far_station_is_returned_as_it_is(sparse_notch):
    """Every station within reach of a sample: the very same mesh comes back."""
    _, taught, _, region, unheld, _ = sparse_notch
    d = taught_module.taught_directions(taught)
    stations, _ = ev.edge_stations(region.mesh, np.radians(ev.STATION_DEG))
    same, held = hold_to_evidence(region.mesh, np.vstack([d, stations]))
    assert same is region.mesh and not held
    assert hold_to_evidence(unheld.mesh, d)[1], "the teaching alone leaves stations to hold"


def test_every_point_of_the_held_edge_lies_within_reach_of_a_sample(sparse_notch):
    """Every outer edge point (``CHECK_DEG`` apart) lies within ``CLIP_REACH_DEG`` of a sample, or
    where the cut stopped, ``DEEP_DEG`` inside the held region."""
    _, taught, _, region, _, held_uncut = sparse_notch
    d = taught_module.taught_directions(taught)
    stations, arc = ev.edge_stations(region.mesh, np.radians(CHECK_DEG))
    stations = stations[ev.outer_arcs(region.mesh)[arc]]
    far = np.degrees(2.0 * np.arcsin(0.5 * cKDTree(d).query(stations)[0]))
    assert region.held_edge and region.clip.cut
    before, _ = ev.edge_stations(held_uncut.mesh, np.radians(CHECK_DEG))
    deep = stations[far > CLIP_REACH_DEG + 0.5 * CHECK_DEG]
    depth = np.degrees(2.0 * np.arcsin(0.5 * cKDTree(before).query(deep)[0]))
    assert held_uncut.mesh.contains(deep).all()
    assert np.all(depth >= DEEP_DEG - CHECK_DEG), depth.min()


@pytest.mark.parametrize(
    ("seed", "kind"),
    [
        pytest.param(1, "iid sparse", id="the tight hold walks into trouble"),
        pytest.param(2, "iid dense", id="dense, the edge a degree from its samples"),
        pytest.param(17, "iid sparse", id="a sliver the straight hold leaves"),
        pytest.param(84, "iid sparse", id="a bridged notch cut to its end"),
        pytest.param(78, "iid sparse", id="a report read on the cut region"),
    ],
)
def test_a_swing_family_teaching_is_held_within_1_deg_keeping_its_samples(seed, kind):
    """The swing families' outline ``seed`` taught ``kind`` is held within 1 deg (read on its
    edge), keeps the samples, and names unheld exactly where the edge still stands past reach."""
    families = benchmark("bench_swing_families")
    outline, _ = families.random_outline(np.random.default_rng(seed))
    taught = families.teach(outline, kind, seed)
    region = TaughtRegion().fit(taught)
    excess = benchmark("bench_region_families").edge_excess
    reach = excess(region.mesh, PolygonRegion(outline).depth)
    assert region.held_edge
    assert reach <= 1.0, f"the held region reaches {reach:.2f} deg past the truth"
    assert np.mean(region.mesh.contains(taught)) >= 0.995
    bound = ev.REACH_DEG + ev.HELD_SLACK_DEG
    far = ev.unsupported_stations(region.mesh, taught, np.radians(bound), surrounded=False)[3]
    left = [s for s in region.unsupported_edge if not s.held]
    assert (far.size > 0) == bool(left) and all(s.distance_deg > bound for s in left)
    if seed in (1, 78, 84):
        assert any(not s.settled for s in region.unsupported_edge), "nothing is asked for"
    if kind == "iid dense":
        assert all(s.held for s in region.unsupported_edge)


def _tongue(sample_in_it: bool):
    """A 10 deg square loop with a 0.02 deg wide tongue out to an island about a sample at
    (9.5, 0), as (points, margins, chain flags); the cKDTree of the samples and them."""
    corners = [(-5, -5), (5, -5), (5, -0.01), (9, -0.01), (9, -0.5), (10, -0.5), (10, 0.5)]
    corners += [(9, 0.5), (9, 0.01), (5, 0.01), (5, 5), (-5, 5)]
    p = pan_tilt_to_direction(*np.radians(np.array(corners, dtype=float).T))
    grid = np.stack(np.meshgrid(np.arange(-4.5, 5.0), np.arange(-4.5, 5.0)), -1).reshape(-1, 2)
    samples = np.vstack([grid, [(9.5, 0.0)]] + ([[(7.0, 0.0)]] if sample_in_it else []))
    d = pan_tilt_to_direction(*np.radians(samples.T))
    k = p.shape[0]
    return (p, np.zeros(k), np.ones(k, dtype=bool)), cKDTree(d), d


def test_a_sliver_holding_no_sample_is_cut_from_the_loop():
    """The tongue is cut off, keeping every sample; with a sample in it the loop stays whole."""
    loop, tree, d = _tongue(sample_in_it=False)
    reach = np.radians(ev.HOLD_REACH_DEG)
    cut = _cut_slivers(*loop, tree, reach)
    assert sorted(p.shape[0] for p, _, _ in cut) == [6, 6]
    whole = DirectionMesh.from_loops([loop[0]], 0.0, lookup=False)
    parts = DirectionMesh.from_loops([p for p, _, _ in cut], 0.0, lookup=False)
    assert parts.contains(d).all()
    tongue = pan_tilt_to_direction(*np.radians(np.array([[6.0, 7.0, 8.0], [0.0, 0.0, 0.0]])))
    assert whole.contains(tongue).all() and not parts.contains(tongue).any()
    loop, tree, _ = _tongue(sample_in_it=True)
    kept = _cut_slivers(*loop, tree, reach)
    assert len(kept) == 1 and kept[0][0] is loop[0]


def test_arcs_the_patient_hold_gave_back_are_held_straight_to_the_tight_reach():
    """The region families' curved band seed 25 taught sparsely is held within 1 deg."""
    families = benchmark("bench_region_families")
    truth, mapping = families.make_truth("curved band with bumps", 25)
    taught = families.teach(truth, mapping, families.TEACHINGS["i.i.d. sparse (1500)"], 25)
    directions, _ = decompose(taught)
    region = TaughtRegion().fit(directions)
    past = families.edge_excess(region.mesh, truth.swing.depth)
    assert region.held_edge
    assert past <= 1.0, f"the held region reaches {past:.2f} deg past the truth"
    assert np.mean(region.mesh.contains(directions)) >= 0.995
