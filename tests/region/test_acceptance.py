import numpy as np

from limbctl.envelope.synthetic import ConeRegion
from limbctl.region import acceptance
from limbctl.region.acceptance import Proposal, Refusal, Verdict, judge
from limbctl.region.mesh import DirectionMesh
from tests.region.support import circle


def test_crossing_arcs_are_found_and_refused(cone20):
    cone = cone20[1:]
    assert not acceptance.arcs_cross([circle(20.0, 30)])
    bad = circle(20.0, 30)
    bad[[3, 4]] = bad[[4, 3]]  # two vertices swapped: the loop crosses itself
    assert acceptance.arcs_cross([bad])
    verdict = judge(Proposal("smooth", [bad]), *cone)
    assert not verdict.accepted and verdict.reasons == ("two of its arcs cross",)
    # two loops that overlap: the same circle turned 0.3 rad about z
    assert acceptance.arcs_cross([circle(20.0, 30), circle(20.0, 30, shift_deg=-np.degrees(0.3))])


def test_gap_worth_and_reach_beyond_measure_an_edge_against_data_and_a_region():
    supported = DirectionMesh.from_loops([circle(20.0, 60)], 0.0)
    data = ConeRegion(np.radians(20.0)).sample(3000, np.random.default_rng(1))
    assert acceptance.unexplained_gap(circle(19.0, 200), data, supported) == 0.0
    # an edge 3 deg beyond all around, over dense data: hundreds of samples' worth
    assert acceptance.unexplained_gap(circle(23.0, 200), data, supported) > 100.0
    region = DirectionMesh.from_loops([circle(20.0, 120)], 0.0)
    assert acceptance.reach_beyond([circle(19.0, 60)], region) == 0.0
    # 1 deg out everywhere; the 120-gon's chords lie up to 0.01 deg inside the circle
    assert 1.0 <= np.degrees(acceptance.reach_beyond([circle(21.0, 60)], region)) < 1.02


def test_judge_accepts_the_true_edge_and_refuses_one_that_cuts_or_overreaches(cone20):
    _, data, supported = cone20
    verdict = judge(Proposal("smooth", [circle(20.0, 240)]), data, supported)
    assert verdict.accepted and verdict.region is not None, "the true circle is accepted"
    assert verdict.region.contains(data).mean() > 0.999
    assert verdict.line().startswith("accepted: holds the taught samples")
    # 2 deg inside the edge leaves about a fifth of the samples out
    verdict = judge(Proposal("traced", [circle(18.0, 240)]), data, supported)
    assert not verdict.accepted and verdict.region is None, "an edge cutting samples is refused"
    assert verdict.figures["samples_left_out"] > 100
    assert "taught samples more than 0.1 deg outside" in verdict.reasons[0]
    # 3 deg wider and 3 deg off centre: a crescent up to 6 deg wide where the data put nothing
    wide = circle(23.0, 240, shift_deg=3.0)
    assert acceptance.unexplained_gap(wide, data, supported) > acceptance.GAP_EXPECTED
    verdict = judge(Proposal("smooth", [wide]), data, supported)
    assert not verdict.accepted, "a stretch no sample reached is refused"
    assert verdict.figures["unexplained_samples"] > acceptance.GAP_EXPECTED
    assert verdict.reasons[0].startswith("loop 0 adds a stretch")


def test_a_rival_edge_bounds_an_edge_and_refusals_and_safe_proposals_pass_through(cone20):
    cone = cone20[1:]

    def rival(radius_deg):
        region = DirectionMesh.from_loops([circle(radius_deg, 240)], 0.0)
        return Verdict("traced", True, ("accepted",), {}, region)

    edge = Proposal("smooth", [circle(20.0, 240)])
    near = judge(edge, *cone, (rival(19.5),))
    assert near.accepted and "within 1 deg of the traced edge" in near.reasons
    far = judge(edge, *cone, (rival(18.5),))
    assert not far.accepted
    assert 1.4 < far.figures["reach_beyond_deg"] < 1.6
    assert "beyond the traced edge" in far.reasons[0]
    # refusals and safe proposals pass through
    verdict = judge(Refusal("traced", "too sparse", {"window_deg": 12.0}), *cone)
    assert not verdict.accepted and verdict.figures == {"window_deg": 12.0}
    assert verdict.line() == "refused: too sparse"
    # a proposal that comes with its region is taken as it is, whatever its loops
    safe = Proposal("supported", [circle(5.0, 10)], region=cone[1], note="by construction")
    verdict = judge(safe, *cone)
    assert verdict.accepted and verdict.region is cone[1]
