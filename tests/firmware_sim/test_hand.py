"""The scripted hand: regions, scripts, tremor and seed, visits, the twist band and the roll."""

from __future__ import annotations

import importlib.util
import math
import re
import sys
from pathlib import Path

import numpy as np
import pytest

from firmware_sim.hand import DEFAULT_TREMOR_DEG, TWIST_INSET_DEG, Hand
from firmware_sim.hand_path import STYLES
from firmware_sim.orientation import chain_quat, chain_twist, wrap_deg
from firmware_sim.regions import region_from_mapping
from firmware_sim.twist_band import MAX_HALF_WIDTH_DEG, MIN_HALF_WIDTH_DEG, TwistBand
from firmware_sim.world import ROLL_JOINT, World
from limbctl.demo import true_twist_probes
from limbctl.geometry.gimbal import direction_to_pan_tilt
from limbctl.geometry.twist import decompose, wrap
from limbctl.region.twist_region import TwistRegion
from limbctl.session import demo_region_path

REGIONS = Path(__file__).resolve().parents[2] / "examples" / "regions"
GUIDED = Path(__file__).resolve().parents[2] / "benchmarks" / "bench_guided_teaching.py"
REGION3 = demo_region_path().with_name("demo_region3.yaml")
CONE = {"region": {"cone": {"half_angle_deg": 30}}}
OFF = {1: None, 2: None}
#: The hand's tremor (0.2 deg peak) rides on top of the band position; half of it on the twist.
TREMOR_SLACK_DEG = 0.15


def sample(hand: Hand, t_end: float, dt: float = 0.02):
    """Times (N,) s, poses (N, 3) deg, twists (N,) deg and the band's limits (N, 2) deg there."""
    times = np.arange(0.0, t_end, dt)
    poses = np.array([hand.pose_deg(float(t)) for t in times])
    tau = [math.degrees(chain_twist(math.radians(p), math.radians(t))) for p, t, _ in poses]
    twist = np.array([wrap_deg(r + d) for r, d in zip(poses[:, 2], tau, strict=True)])
    limits = np.array([hand.band.limits_deg(p, t) for p, t, _ in poses])
    return times, poses, twist, limits


@pytest.mark.parametrize(
    "data, turns",
    [
        (CONE, False),
        ({**CONE, "twist": {"half_width_deg": 20}}, True),
        ({"script": [[0, 0, 0], [2, 10, 0]], "tremor_deg": 0}, False),
        ({"script": [[0, 0, 0, 0], [2, 10, 0, 40]], "tremor_deg": 0}, True),
    ],
    ids=["region", "region+twist", "script", "script+roll"],
)
def test_a_twist_band_or_a_roll_column_turns_the_roll_and_a_script_is_followed_then_held(
    data, turns
):
    hand = Hand.from_mapping(data)
    assert hand.turns_roll == turns
    assert len(hand.pose_deg(1.0)) == 2 + turns
    if "script" in data:  # linear between waypoints, the last one held
        assert hand.pose_deg(1.0) == pytest.approx((5, 0, 20)[: 2 + turns])
        assert hand.pose_deg(5.0) == pytest.approx((10, 0, 40)[: 2 + turns])


def test_tremor_is_a_few_tenths_of_a_degree_and_unknown_styles_and_visits_are_refused():
    still = {"script": [[0.0, 10.0, 5.0]]}
    hand = Hand.from_mapping(still, seed=13)
    poses = np.array([hand.pose_deg(t) for t in np.arange(0.0, 10.0, 0.001)])
    amplitude = np.abs(poses - [10.0, 5.0]).max(axis=0)
    assert np.all(amplitude > 0.1) and np.all(amplitude <= DEFAULT_TREMOR_DEG + 1e-12)
    calm = Hand.from_mapping({**still, "tremor_deg": 0}, seed=13)
    assert calm.pose_deg(3.3) == (10.0, 5.0)
    with pytest.raises(ValueError, match="unknown style 'spiral'") as caught:
        Hand.from_mapping({**CONE, "style": "spiral"})
    assert all(name in str(caught.value) for name in STYLES)
    with pytest.raises(ValueError, match="not to a script"):
        Hand.from_mapping({"script": [[0, 0, 0]], "style": "trace"})
    with pytest.raises(ValueError, match="'visits' applies to a region hand"):
        Hand.from_mapping({"script": [[0, 0, 0]], "visits": []})


@pytest.mark.parametrize("path", [REGIONS / "irregular.yaml", REGION3], ids=["sim", "sim3"])
def test_same_seed_same_path_whatever_order_it_is_asked_in(path):
    a, b = Hand.from_yaml(path, seed=14), Hand.from_yaml(path, seed=14)
    times = np.arange(0.0, 40.0, 0.37)
    late_first = {t: b.pose_deg(t) for t in times[::-1]}
    assert [a.pose_deg(t) for t in times] == [late_first[t] for t in times]
    c = Hand.from_yaml(path, seed=15)
    assert [c.pose_deg(t) for t in times] != [a.pose_deg(t) for t in times]


def test_the_calibration_script_moves_the_backdriven_limb_and_a_hand_turns_the_roll_joint():
    world = World(hand=Hand.from_yaml(REGIONS / "calibration.yaml"), seed=16)
    seen = {}
    for k in range(1, 16001):
        world.step(0.001, OFF)
        if k % 1000 == 0:
            seen[k // 1000] = world.joint_angles_deg()
    assert seen[1] == pytest.approx({"pan": 0.0, "tilt": 0.0}, abs=0.3)
    assert seen[5] == pytest.approx({"pan": 45.0, "tilt": 0.0}, abs=0.3)
    assert seen[12] == pytest.approx({"pan": 0.0, "tilt": 30.0}, abs=0.3)
    assert seen[16] == pytest.approx({"pan": 0.0, "tilt": 0.0}, abs=0.3)
    hand = Hand.from_yaml(REGION3, seed=1)
    world = World(joints=(*World().joints, ROLL_JOINT), hand=hand, seed=1)
    for _ in range(3000):
        world.step(0.001, {1: None, 2: None, 3: None})
    angles = world.joint_angles_deg()
    pan, tilt, roll = hand.pose_deg(world.hand_time_s)
    # the grip lags the hand by ~15 ms: the roll lies among the hand's rolls of the last 30 ms
    recent = [hand.pose_deg(world.hand_time_s - 0.001 * k)[2] for k in range(31)]
    assert min(recent) - 1.0 <= angles["roll"] <= max(recent) + 1.0
    assert abs(roll) > 1.0
    assert angles["pan"] == pytest.approx(pan, abs=3.0)
    plain = World(joints=(*World().joints, ROLL_JOINT), hand=Hand.from_mapping(CONE), seed=1)
    rest = plain.joint_angles_deg()["roll"]
    for _ in range(500):
        plain.step(0.001, {1: None, 2: None, 3: None})
    assert plain.joint_angles_deg()["roll"] == rest, "a plain hand turned the roll joint"


def test_the_twist_keeps_to_a_plane_or_curved_band_and_reaches_both_its_stops():
    hand = Hand.from_yaml(REGION3, seed=2)
    start, end = hand.path.trace_span_s
    times, poses, twist, limits = sample(hand, end + 30.0)
    low, high = limits[:, 0], limits[:, 1]
    assert np.all(twist >= low + TWIST_INSET_DEG - TREMOR_SLACK_DEG)
    assert np.all(twist <= high - TWIST_INSET_DEG + TREMOR_SLACK_DEG)
    near_high = twist >= high - TWIST_INSET_DEG - 0.5
    near_low = twist <= low + TWIST_INSET_DEG + 0.5
    tracing = (times >= start) & (times < end)
    depth = hand.region.edge_distance_deg(poses[:, 0], poses[:, 1])
    # along the edge trace: both stops, at several places round the edge (>= 3 each)
    for near in (near_high, near_low):
        at_edge = near & tracing & (depth < 3.0)
        places = hand.region.boundary_fraction(poses[at_edge, 0], poses[at_edge, 1])
        assert len(np.unique(np.round(places * 8))) >= 3
    assert np.any(near_high & (times > end)) and np.any(near_low & (times > end)), "wander"
    data = {
        "region": {"polygon": [[-40, -30], [40, -30], [40, 40], [-40, 40]]},
        "twist": {
            "centre_deg": {"linear": [10, 0.2, 0], "quadratic": [0.003, 0, -0.002]},
            "half_width_deg": {"linear": [35, 0, -0.2], "bumps": [[0, 5, -10, 8]]},
        },
    }
    hand = Hand.from_mapping(data, seed=2)
    _, poses, twist, limits = sample(hand, 40.0)
    low, high = limits[:, 0], limits[:, 1]
    # the band is curved: its width at the bump differs from a plane's by its height
    assert hand.band.limits_deg(0, 5)[1] - hand.band.limits_deg(0, 5)[0] < 2 * (35 - 1 - 9)
    slack = TWIST_INSET_DEG - TREMOR_SLACK_DEG
    assert np.all(twist <= high - slack + 1e-9) and np.all(twist >= low + slack - 1e-9)
    assert np.sum(twist >= high - TWIST_INSET_DEG - TREMOR_SLACK_DEG) > 10
    assert np.sum(twist <= low + TWIST_INSET_DEG + TREMOR_SLACK_DEG) > 10


def test_a_minute_of_the_hand_teaches_a_band_within_the_truth_or_names_what_is_missing():
    """Issue 35: a learned 60 s teaching stays within 1 deg of the true band; holds 99 % or asks."""
    hand = Hand.from_yaml(REGION3, seed=1)
    hand.start_from(0.0, 0.0, 0.0)
    poses = np.radians([hand.pose_deg(float(t)) for t in np.arange(0.0, 60.0, 1.0 / 125.0)])
    q = np.array([chain_quat(*p) for p in poses])
    region = TwistRegion().fit(q)
    probes = true_twist_probes(REGION3)
    d = np.unique(np.round(decompose(probes)[0], 12), axis=0)
    pan, tilt = (np.degrees(a) for a in direction_to_pan_tilt(d))
    low, high = np.radians([hand.band.limits_deg(p, t) for p, t in zip(pan, tilt)]).T
    c, h = region.band.at(d)
    off = wrap(c - 0.5 * (low + high))
    past = np.degrees(np.fmax(off + h, h - off) - 0.5 * (high - low))
    assert past.max() <= 1.0, f"the band reaches {past.max():.2f} deg past the true stop"
    held = np.mean(region.contains(probes))
    assert held >= 0.99 or region.unsupported, f"{100 * held:.2f} % held, nothing asked for"


#: A region the bad files below add to or break.
CONE20 = "region: {cone: {half_angle_deg: 20}}\n"
VISIT = CONE20 + "visits: [{%s}]\n"
SQUARE20 = "region: {polygon: [[-40, -30], [40, -30], [40, 50], [-40, 50]]}\n"  # tilt -30..50
BAND = SQUARE20 + "twist: {%s}\n"
CURVED = SQUARE20 + "twist: {half_width_deg: {linear: [40, 0, 0], %s}}\n"
WIDTHS = f"within {MIN_HALF_WIDTH_DEG:g}..{MAX_HALF_WIDTH_DEG:g}"
BAD_FILES = {
    "missing": (None, "cannot read the region file"),
    "missing-region": ("speed_deg_s: 30\n", "exactly one of 'region' or 'script'"),
    "both": (CONE20 + "script: [[0, 0, 0]]\n", "exactly one"),
    "unknown-key": (CONE20 + "speed: 3\n", "unknown key"),
    "no-shape": ("region: {}\n", "exactly one of polygon or cone"),
    "two-points": ("region: {polygon: [[0, 0], [10, 0]]}\n", "at least 3 vertices"),
    "nan": ("region: {polygon: [[0, 0], [10, .nan], [0, 10]]}\n", "finite"),
    "text": ("region: {polygon: [[0, 0], [10, ten], [0, 10]]}\n", "must be a number"),
    "bow-tie": ("region: {polygon: [[0, 0], [10, 10], [10, 0], [0, 10]]}\n", "crosses itself"),
    "flat": ("region: {polygon: [[0, 0], [5, 0], [10, 0]]}\n", "crosses itself|zero area"),
    "cone-zero": ("region: {cone: {half_angle_deg: 0}}\n", r"\(0, 180\)"),
    "cone-180": ("region: {cone: {half_angle_deg: 180}}\n", r"\(0, 180\)"),
    "cone-key": ("region: {cone: {half_angle: 20}}\n", "half_angle_deg"),
    "speed": (CONE20 + "speed_deg_s: -1\n", "speed_deg_s"),
    "script-order": ("script: [[0, 0, 0], [2, 1, 1], [1, 2, 2]]\n", "later than"),
    "script-row": ("script: [[0, 0]]\n", r"script\[0\]"),
    "too-thin": ("region: {polygon: [[0, 0], [40, 0], [40, 1]]}\n", "too small"),
    "tiny-cone": ("region: {cone: {half_angle_deg: 1.5}}\n", "too small"),
    "not-yaml": ("region: [unclosed\n", "not valid YAML"),
    "not-mapping": ("- 1\n- 2\n", "expected a mapping"),
    "script-roll-row": (
        "script: [[0, 0, 0, 0], [2, 10, 0]]\n",
        r"script\[1\] must be \[t_s, pan_deg, tilt_deg, roll_deg\]",
    ),
    "script-roll-nan": ("script: [[0, 0, 0, 0], [2, 10, 0, .nan]]\n", "non-finite"),
    "script-twist": ("script: [[0, 0, 0]]\ntwist: {half_width_deg: 20}\n", "not to a script"),
    "twist-narrow": (CONE20 + "twist: {half_width_deg: 1}\n", "within 3"),
    "visit-do": (VISIT % "after_s: 1, at: [0, 0], do: dance", r"visits\[0\]: unknown do"),
    "visit-at": (VISIT % "after_s: 1, at: [0], do: edge", r"visits\[0\]: at must be"),
    "visit-keys": (VISIT % "at: [0, 0], do: edge", r"visits\[0\] .*after_s, at and do"),
    "visit-after": (VISIT % "after_s: -1, at: [0, 0], do: edge", r"\[0\]: after_s .*>= 0"),
    "visit-key": (VISIT % "after_s: 1, at: [0, 0], do: edge, x: 2", r"\[0\]: unknown key"),
    "band-runs": (BAND % "half_width_deg: [40, 0, -1.0]", "runs"),  # 40 - 50 < 0 at the top
    "band-wide": (BAND % "half_width_deg: 175", WIDTHS),
    "band-no-width": (BAND % "centre_deg: 0", r"half_width_deg \(required\)"),
    "band-key": (BAND % "half_width_deg: 20, spin: 1", "twist takes"),
    "band-pair": (BAND % "half_width_deg: [1, 2]", r"a number or \[a, b, c\]"),
    "band-text": (BAND % "half_width_deg: wide", "finite numbers"),
    "band-list": (SQUARE20 + "twist: [1, 2]\n", "must be a mapping"),
    "band-cubic": (CURVED % "cubic: [1, 2, 3]", "takes linear, quadratic, bumps"),
    "band-bumps": (CURVED % "bumps: [[0, 0, 5]]", "bumps must be a list"),
    "band-quadratic": (CURVED % "quadratic: 0.1", re.escape("quadratic must be [p, m, t]")),
}


@pytest.mark.parametrize("name", sorted(BAD_FILES))
def test_malformed_region_files_name_the_file_and_the_problem(tmp_path, name):
    text, problem = BAD_FILES[name]
    path = tmp_path / f"{name}.yaml"
    if text is not None:
        path.write_text(text)
    with pytest.raises(ValueError, match=problem) as caught:
        Hand.from_yaml(path)
    assert str(path) in str(caught.value)


#: A region hand with a twist band and two requests to answer from VISIT_AT_S.
VISIT_AT_S = 4.0
VISITING = {
    "region": {"polygon": [[-30, -20], [30, -20], [30, 25], [-30, 25]]},
    "twist": {"centre_deg": 10, "half_width_deg": 35},
    "visits": [
        {"after_s": VISIT_AT_S, "at": [29, 10], "do": "edge", "length_deg": 12},
        {"after_s": VISIT_AT_S, "at": [-15, 0], "do": "twist"},
    ],
}


def test_visits_answer_the_requests_in_order_and_leave_the_path_before_them_alone():
    plain = Hand.from_mapping({k: v for k, v in VISITING.items() if k != "visits"}, seed=5)
    hand = Hand.from_mapping(VISITING, seed=5)
    times, poses, twist, limits = sample(hand, 60.0, dt=0.01)
    _, before, _, _ = sample(plain, VISIT_AT_S, dt=0.01)
    assert np.array_equal(poses[: len(before)], before)
    (e0, e1, edge), (w0, w1, turn) = hand.path.visit_spans
    assert VISIT_AT_S <= e0 < e1 <= w0 < w1 and (edge.do, turn.do) == ("edge", "twist")
    # the edge visit: along the edge, about a degree inside, over the stretch asked for
    at = (times >= e0) & (times < e1)
    depth = hand.region.edge_distance_deg(poses[at, 0], poses[at, 1])
    assert np.all((depth > 0.3) & (depth < 1.8))
    assert np.ptp(poses[at, 1]) >= 12.0 - 1.0 and np.all(np.abs(poses[at, 0] - 29.0) < 1.8)
    # the twist visit: round the place, the twist at both stops
    at = (times >= w0) & (times < w1)
    assert np.all(np.hypot(poses[at, 0] + 15.0, poses[at, 1]) < 3.0 + 0.5)
    for k, side in ((1, 1.0), (0, -1.0)):
        stop = limits[at, k] - side * TWIST_INSET_DEG
        assert np.any(np.abs(twist[at] - stop) < TREMOR_SLACK_DEG + 0.1)
    assert np.all(twist[at] >= limits[at, 0] + TWIST_INSET_DEG - TREMOR_SLACK_DEG)
    assert np.all(twist[at] <= limits[at, 1] - TWIST_INSET_DEG + TREMOR_SLACK_DEG)


def test_a_guided_teaching_of_a_small_region_ends_ready_and_within_a_degree_of_the_truth():
    spec = importlib.util.spec_from_file_location("bench_guided_teaching", GUIDED)
    bench = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = bench
    spec.loader.exec_module(bench)
    # an oval 36 x 28 deg, its band sloping with pan and narrowing with tilt
    phi = np.radians(np.arange(0.0, 360.0, 30.0))
    polygon = [[5.0 + 18.0 * math.cos(a), 5.0 + 14.0 * math.sin(a)] for a in phi]
    region = {
        "region": {"polygon": polygon},
        "twist": {"centre_deg": [10, 0.2, 0.0], "half_width_deg": [30, 0.0, -0.1]},
    }
    taught = bench.guided(region, seed=1, teach_s=12.0)
    assert taught["asked"][0] > 0 and taught["rounds"] >= 1
    assert taught["complete"] and taught["asked"][-1] == 0
    figures = bench.measure(bench.truth_of(region), taught["q"], 1, True)
    assert figures["complete"]
    assert figures["swing_excess"] <= 1.0 and figures["twist_excess"] <= 1.0
    assert figures["coverage"] >= 0.95


SQUARE = region_from_mapping({"polygon": [[-40, -30], [40, -30], [40, 50], [-40, 50]]})


def test_a_band_constant_linear_or_curved_with_bumps_compares_on_the_circle():
    band = TwistBand.from_mapping({"half_width_deg": 30}, SQUARE)
    assert band.limits_deg(0, 0) == (-30.0, 30.0)
    assert band.limits_deg(35, 45) == (-30.0, 30.0)
    band = TwistBand.from_mapping(
        {"centre_deg": [10, 0.5, 0], "half_width_deg": [40, 0, -0.3]}, SQUARE
    )
    assert band.limits_deg(0, 0) == pytest.approx((-30.0, 50.0))
    # narrower as the limb rises, centre moving with pan
    low, high = band.limits_deg(20, 50)
    assert (high - low) / 2 == pytest.approx(25.0)
    assert (high + low) / 2 == pytest.approx(20.0)
    band = TwistBand.from_mapping({"centre_deg": 170, "half_width_deg": 20}, SQUARE)
    assert band.contains(0, 0, -175.0)  # 15 deg past +180 is still inside
    assert band.contains(0, 0, 160.0)
    assert not band.contains(0, 0, -165.0)
    assert not band.contains(0, 0, 140.0)
    # both limits themselves lie in the band (one across +-180), a tenth of a degree past them not
    assert band.contains(0, 0, 150.0) and band.contains(0, 0, -170.0)
    assert not band.contains(0, 0, 149.9) and not band.contains(0, 0, -169.9)
    band = TwistBand.from_mapping(
        {
            "centre_deg": {"linear": [5, 0.1, 0], "quadratic": [0, 0, 0.01]},
            "half_width_deg": {"linear": [40, 0, 0], "bumps": [[10, 20, -12, 5]]},
        },
        SQUARE,
    )
    low, high = band.limits_deg(0, 0)
    # centre 5 + 0.01 * 0; half 40 - 12 exp(-(100 + 400) / 50) ~= 40
    assert (high + low) / 2 == pytest.approx(5.0)
    assert (high - low) / 2 == pytest.approx(40.0 - 12.0 * math.exp(-10.0))
    low, high = band.limits_deg(10, 20)
    assert (high + low) / 2 == pytest.approx(5.0 + 1.0 + 4.0)  # 0.1 pan + 0.01 tilt^2
    assert (high - low) / 2 == pytest.approx(28.0)  # the bump's floor
    assert TwistBand.from_mapping({"half_width_deg": [40, 0, -0.3]}, SQUARE).limits_deg(
        0, 10
    ) == pytest.approx((-37.0, 37.0))
