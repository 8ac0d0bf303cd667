import numpy as np
import pytest

from limbctl.envelope.synthetic import EGG, PolygonRegion, rounded
from limbctl.envelope.synthetic_twist import SHOULDER, ShoulderRegion
from limbctl.errors import ConfigError
from limbctl.geometry.quat import limb_direction
from limbctl.region import TaughtRegion
from limbctl.region import edge_choice as ec
from limbctl.region.acceptance import Proposal, Refusal
from limbctl.region.evidence import edge_stations
from limbctl.region.loops import loop_area
from tests.region.support import noisy_egg

WINDOW = np.radians(3.0)


def test_choices_come_from_the_registry_and_unknown_names_are_refused(cone20):
    assert ec.EDGE_CHOICES == ("auto", "smooth", "traced", "supported")
    assert all(name == strategy.name for name, strategy in ec.EDGE_STRATEGIES.items())
    assert [s.safe for s in ec.EDGE_STRATEGIES.values()] == [False, False, True]
    assert set(ec.AUTO_ORDER) == set(ec.EDGE_STRATEGIES) and ec.AUTO_ORDER[-1] == ec.FALLBACK
    with pytest.raises(ConfigError, match="choose one of: auto, smooth, traced, supported"):
        ec.check_choice("round")
    with pytest.raises(ConfigError, match="unknown edge 'round'"):
        ec.choose_edge("round", *cone20, WINDOW)


def test_auto_takes_the_smooth_edge_of_a_cone_after_checking_it_against_the_traced(cone20):
    taken, verdicts = ec.choose_edge("auto", *cone20, WINDOW)
    assert [v.strategy for v in verdicts] == ["smooth", "traced", "supported"]
    assert taken is verdicts[0] and all(v.accepted for v in verdicts)
    assert "within 1 deg of the traced edge" in taken.reasons
    # the edge lies near the true circle, beyond the supported loop
    radius = np.degrees(np.arccos(np.clip(taken.region.vertices[:, 0], -1.0, 1.0)))
    assert abs(radius.mean() - 20.0) < 0.5


def test_one_strategy_by_name_is_judged_alone_and_falls_back_to_the_supported_loops(cone20):
    loops, data, supported = cone20
    taken, verdicts = ec.choose_edge("traced", loops, data, supported, WINDOW)
    assert taken.strategy == "traced" and [v.strategy for v in verdicts] == ["traced", "supported"]
    assert taken.reasons == (taken.reasons[0],), "no rival check outside auto"
    taken, verdicts = ec.choose_edge("supported", loops, data, supported, WINDOW)
    assert taken.strategy == "supported" and taken.region is supported and len(verdicts) == 1
    # too few samples for the traced edge: refused, saying how sparse, and the supported taken
    taken, verdicts = ec.choose_edge("traced", loops, data[:100], supported, WINDOW)
    assert taken.strategy == "supported" and not verdicts[0].accepted
    answer = ec.TracedEdge().propose(loops, data[:100], supported, WINDOW)
    assert isinstance(answer, Refusal)
    # 100 samples over a 20 deg cap: a window about twice the largest
    assert answer.figures["window_deg"] > 15.0
    assert answer.reason.startswith("loop 0 is taught too sparsely")
    assert isinstance(ec.TracedEdge().propose(loops, data, supported, 0.05), Proposal)


def test_the_smooth_strategy_refuses_a_bay_and_a_shape_its_window_cannot_follow():
    def counter_clockwise(loop):
        return loop[::-1] if loop_area(loop) < 0 else loop

    bean = PolygonRegion()
    data = bean.sample(1000, np.random.default_rng(2))
    loop = counter_clockwise(bean.boundary)
    answer = ec.SmoothEdge().propose([loop], data, None, WINDOW)
    assert isinstance(answer, Refusal) and answer.figures["bay_samples"] > 40.0
    assert "bay worth" in answer.reason
    answer = ec.SmoothEdge().propose([loop[::-1]], data, None, WINDOW)
    assert answer.reason == "loop 0 is a hole (concave throughout)"
    # the egg's tight end: 60 vertices with vertex noise, a window spanning its tip
    rng = np.random.default_rng(0)
    loop = counter_clockwise(noisy_egg(rng))
    answer = ec.SmoothEdge().propose([loop], PolygonRegion(EGG).sample(1000, rng), None, WINDOW)
    assert isinstance(answer, Refusal) and answer.figures["residual_ratio"] > 1.4


def test_a_traced_edge_refused_for_unexplained_samples_is_taken_clipped_to_the_supported_region():
    # limbctl eval's dense shoulder (quick scale, seed 0): the free traced edge adds a stretch
    truth = ShoulderRegion(rounded(SHOULDER))
    d = limb_direction(truth.teaching(2500, 1900, 3100, np.random.default_rng(0)))
    region = TaughtRegion().fit(d)
    traced = next(v for v in region.verdicts if v.strategy == "traced")
    assert region.edge == "traced" and traced.accepted, traced.reasons
    stations, _ = edge_stations(region.mesh, np.radians(0.25))
    depth = np.degrees(truth.swing.depth(stations))
    # clipped, the edge stays at the samples' reach
    assert np.percentile(depth, 5) > -0.1
