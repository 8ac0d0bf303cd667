import numpy as np
import pytest

from limbctl.envelope.synthetic import ConeRegion
from limbctl.region import acceptance
from limbctl.region.acceptance import Proposal, Refusal, Verdict, judge
from limbctl.region.mesh import DirectionMesh
from tests.region.support import circle


@pytest.fixture(scope="module")
def cone_data():
    return ConeRegion(np.radians(20.0)).sample(1000, np.random.default_rng(0))


@pytest.fixture(scope="module")
def supported():
    return DirectionMesh.from_loops([circle(19.5, 120)], np.radians(0.5))


def test_crossing_arcs_are_found_and_refused(cone_data, supported):
    assert not acceptance.arcs_cross([circle(20.0, 30)])
    # two vertices swapped: the loop crosses itself
    bad = circle(20.0, 30)
    bad[[3, 4]] = bad[[4, 3]]
    assert acceptance.arcs_cross([bad])
    verdict = judge(Proposal("smooth", [bad]), cone_data, supported)
    assert not verdict.accepted and verdict.reasons == ("two of its arcs cross",)
    # two loops that overlap: the same circle turned 0.3 rad away about z
    turn = np.array([[np.cos(0.3), -np.sin(0.3), 0], [np.sin(0.3), np.cos(0.3), 0], [0, 0, 1]])
    near = circle(20.0, 30) @ turn
    assert acceptance.arcs_cross([circle(20.0, 30), near])


def test_gap_worth_is_zero_inside_and_large_over_a_dense_bay():
    supported = DirectionMesh.from_loops([circle(20.0, 60)], 0.0)
    data = ConeRegion(np.radians(20.0)).sample(3000, np.random.default_rng(1))
    assert acceptance.unexplained_gap(circle(19.0, 200), data, supported) == 0.0
    # an edge 3 deg beyond all around, over dense data: hundreds of samples' worth
    assert acceptance.unexplained_gap(circle(23.0, 200), data, supported) > 100.0


def test_reach_beyond_measures_how_far_stations_leave_a_region():
    region = DirectionMesh.from_loops([circle(20.0, 120)], 0.0)
    assert acceptance.reach_beyond([circle(19.0, 60)], region) == 0.0
    reach = np.degrees(acceptance.reach_beyond([circle(21.0, 60)], region))
    # 1 deg out everywhere; the 120-gon's chords lie up to 0.01 deg inside the circle
    assert 1.0 <= reach < 1.02


def test_an_edge_on_the_true_circle_is_accepted_with_its_region(cone_data, supported):
    verdict = judge(Proposal("smooth", [circle(20.0, 240)]), cone_data, supported)
    assert verdict.accepted and verdict.region is not None
    assert verdict.region.contains(cone_data).mean() > 0.999
    assert verdict.line().startswith("accepted: holds the taught samples")


def test_an_edge_that_cuts_the_taught_samples_is_refused_with_the_count(cone_data, supported):
    # 2 deg inside the edge leaves about a fifth of the samples out
    verdict = judge(Proposal("traced", [circle(18.0, 240)]), cone_data, supported)
    assert not verdict.accepted and verdict.region is None
    assert verdict.figures["samples_left_out"] > 100
    assert "taught samples more than 0.1 deg outside" in verdict.reasons[0]


def test_a_stretch_no_sample_ever_reached_is_refused(cone_data, supported):
    # 3 deg wider and 3 deg off centre: a crescent up to 6 deg wide where the dense data put
    # nothing
    wide = circle(23.0, 240, shift_deg=3.0)
    assert acceptance.unexplained_gap(wide, cone_data, supported) > acceptance.GAP_EXPECTED
    verdict = judge(Proposal("smooth", [wide]), cone_data, supported)
    assert not verdict.accepted
    assert verdict.figures["unexplained_samples"] > acceptance.GAP_EXPECTED
    assert verdict.reasons[0].startswith("loop 0 adds a stretch")


def test_a_rival_edge_bounds_how_far_an_edge_may_reach(cone_data, supported):
    def rival(radius_deg):
        region = DirectionMesh.from_loops([circle(radius_deg, 240)], 0.0)
        return Verdict("traced", True, ("accepted",), {}, region)

    edge = Proposal("smooth", [circle(20.0, 240)])
    near = judge(edge, cone_data, supported, (rival(19.5),))
    assert near.accepted and "within 1 deg of the traced edge" in near.reasons
    far = judge(edge, cone_data, supported, (rival(18.5),))
    assert not far.accepted
    assert 1.4 < far.figures["reach_beyond_deg"] < 1.6
    assert "beyond the traced edge" in far.reasons[0]


def test_refusals_and_safe_proposals_pass_through(cone_data, supported):
    verdict = judge(Refusal("traced", "too sparse", {"window_deg": 12.0}), cone_data, supported)
    assert not verdict.accepted and verdict.figures == {"window_deg": 12.0}
    assert verdict.line() == "refused: too sparse"
    # a proposal that comes with its region is taken as it is, whatever its loops
    safe = Proposal("supported", [circle(5.0, 10)], region=supported, note="by construction")
    verdict = judge(safe, cone_data, supported)
    assert verdict.accepted and verdict.region is supported
