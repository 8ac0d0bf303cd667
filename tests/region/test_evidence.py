"""Hand-taught notches and bays are not bridged by more than 1 deg (issue 35, finding 1)."""

from dataclasses import replace

import numpy as np
import pytest

from firmware_sim.hand import Hand
from limbctl.envelope.synthetic import PolygonRegion, reach_into
from limbctl.geometry.gimbal import pan_tilt_to_direction
from limbctl.geometry.twist import decompose
from limbctl.region import RegionParams, TaughtRegion
from limbctl.region import taught as taught_module
from limbctl.region.evidence import SETTLED_DEG, Stretch, unsupported_stretches
from limbctl.region.evidence_clip import Clip
from tests.region.support import benchmark

#: The region's bound outside the truth (deg), docs/region.md.
BOUND_DEG = 1.0
RATE_HZ = 125.0


def notched_ellipse(a, b, centre, at_deg, width, depth):
    """An ellipse with a ``width`` x ``depth`` deg notch at ``at_deg``: vertices (V, 2) deg."""
    r_here = np.hypot(a * np.cos(np.radians(at_deg)), b * np.sin(np.radians(at_deg)))
    half = np.degrees(0.5 * width / r_here)
    floor = 1.0 - depth / r_here
    points = [(t, floor if abs((t - at_deg + 180) % 360 - 180) <= half else 1.0)
              for t in np.arange(0.0, 360.0, 2.0)]  # fmt: skip
    points += [(at_deg - half, 1.0), (at_deg - half + 1e-6, floor)]
    points += [(at_deg + half - 1e-6, floor), (at_deg + half, 1.0)]
    theta, radius = np.array(sorted(points)).T
    theta = np.radians(theta)
    return np.stack(
        [centre[0] + a * radius * np.cos(theta), centre[1] + b * radius * np.sin(theta)], axis=1
    ), (at_deg, half, floor)


def hand_teaching(outline, seed, seconds=60.0):
    """Directions (N, 3) the simulator's hand teaches over ``outline`` at RATE_HZ."""
    hand = Hand.from_mapping({"region": {"polygon": outline.tolist()}}, seed=seed)
    hand.start_from(*hand.region.center_deg)
    pose = np.radians([hand.pose_deg(t) for t in np.arange(int(seconds * RATE_HZ)) / RATE_HZ])
    return pan_tilt_to_direction(pose[:, 0], pose[:, 1])


def _notch_and_box(a, b, centre, at_deg):
    """A notched ellipse (9 x 8 deg notch) and the box over the notch and 3 deg round it."""
    x, y = centre[0] + a * np.cos(np.radians(at_deg)), centre[1] + b * np.sin(np.radians(at_deg))
    outline, _ = notched_ellipse(a, b, centre, at_deg, width=9.0, depth=8.0)
    return outline, ((x - 10.0, x + 10.0), (y - 10.0, y + 10.0))


def test_a_bridged_notch_is_listed_as_unsupported(monkeypatch):
    """An uncarved edge across a notch the samples surround is found over it; carved, gone."""
    monkeypatch.setattr(taught_module, "CARVE_ROUNDS", 0)
    outline, (at, half, floor) = notched_ellipse(27.2, 23.4, (-5.7, 7.2), 273.0, 9.0, 8.0)
    taught = PolygonRegion(outline).sample(8000, np.random.default_rng(0))
    params = RegionParams(edge="supported", alpha_factor=4.0)
    held = TaughtRegion(params).fit(taught)
    # the edge as kept, before the hold and the cut take it in to the evidence
    monkeypatch.setattr(
        taught_module, "hold_to_evidence", lambda mesh, data, *_, **__: (mesh, False)
    )
    monkeypatch.setattr(
        taught_module, "cut_to_evidence", lambda mesh, data, *_, **__: Clip.nothing(mesh)
    )
    bridged = TaughtRegion(params).fit(taught)
    assert held.held_edge and not unsupported_stretches(held.mesh, taught)
    # every stretch the hold took in is named held (the cut back to the evidence may add more)
    assert {replace(s, held=True) for s in bridged.unsupported_edge} <= set(held.unsupported_edge)
    found = unsupported_stretches(bridged.mesh, taught)
    assert found, "an edge across the notch must be found unsupported"
    # the region's report (every stretch past REACH_DEG, surrounded or not) names it first
    reported = bridged.unsupported_edge[0]
    assert (reported.pan_deg, reported.tilt_deg) == (found[0].pan_deg, found[0].tilt_deg)
    x = -5.7 + 27.2 * np.cos(np.radians(at))
    y = 7.2 + 23.4 * np.sin(np.radians(at))
    assert abs(found[0].pan_deg - x) < 8.0 and abs(found[0].tilt_deg - y) < 10.0
    monkeypatch.setattr(taught_module, "CARVE_ROUNDS", 12)
    carved = TaughtRegion(params).fit(taught)
    assert not unsupported_stretches(carved.mesh, taught)


def bayed_ellipse(a, b, centre, bays):
    """An ellipse with raised-cosine bays ``(at_deg, width, depth)`` deg: vertices (V, 2) deg."""
    theta = np.arange(0.0, 360.0, 2.0)
    radius = np.ones_like(theta)
    for at, width, depth in bays:
        r_here = np.hypot(a * np.cos(np.radians(at)), b * np.sin(np.radians(at)))
        half, frac = np.degrees(0.5 * width / r_here), min(depth, 0.5 * r_here) / r_here
        off = np.abs((theta - at + 180.0) % 360.0 - 180.0)
        dent = 1.0 - frac * 0.5 * (1.0 + np.cos(np.pi * np.minimum(off / half, 1.0)))
        radius = np.minimum(radius, np.where(off <= half, dent, 1.0))
    t = np.radians(theta)
    return np.stack([centre[0] + a * radius * np.cos(t), centre[1] + b * radius * np.sin(t)], 1)


@pytest.mark.parametrize(
    ("shape", "seed", "seconds"), [("notch 1", 1, 60.0), ("notch 2", 0, 60.0), ("bays", 2, 30.0)]
)
def test_a_hand_taught_notch_or_bay_is_not_bridged(shape, seed, seconds):
    if shape == "bays":  # the families' outline 2
        outline = bayed_ellipse(22.7, 15.6, (5.0, -6.5), [(242.2, 17.9, 6.8), (11.0, 11.8, 6.2)])
        box = ((-22.0, 32.0), (-27.0, 14.0))
    elif shape == "notch 1":
        outline, box = _notch_and_box(27.2, 23.4, (-5.7, 7.2), 273.0)
    else:
        outline, box = _notch_and_box(29.5, 15.2, (-7.3, -7.7), 30.0)
    region = TaughtRegion().fit(hand_teaching(outline, seed, seconds))
    reach = reach_into(region.contains, PolygonRegion(outline), box, step_deg=0.1)
    assert reach <= BOUND_DEG, f"the region reaches {reach:.2f} deg outside ({region.edge} edge)"


def v_notched_ellipse(a, b, centre, at_deg, mouth_deg, depth):
    """An ellipse with a V notch ``mouth_deg`` wide at its mouth and ``depth`` deg deep at
    ``at_deg``: vertices (V, 2) deg."""
    c = np.asarray(centre, dtype=float)
    rim = c + np.stack([a * np.cos(np.radians(at_deg)), b * np.sin(np.radians(at_deg))])
    r_here = float(np.linalg.norm(rim - c))
    half = np.degrees(0.5 * mouth_deg / r_here)
    theta = [t for t in np.arange(0.0, 360.0, 2.0) if abs((t - at_deg + 180) % 360 - 180) > half]
    points = [(t, c + [a * np.cos(np.radians(t)), b * np.sin(np.radians(t))])
              for t in theta + [at_deg - half, at_deg + half]]  # fmt: skip
    points.append((at_deg, rim + depth * (c - rim) / r_here))
    return np.array([xy for _, xy in sorted(points, key=lambda p: p[0])])


def test_a_traced_v_notch_the_edge_bridges_is_settled_and_held_within_the_bound():
    """A hand-traced V notch (6 deg mouth, 3 deg deep) the edge bridges is held, settled by the
    samples' outline, within the bound of the truth."""
    outline = v_notched_ellipse(27.2, 23.4, (-5.7, 7.2), 90.0, 6.0, 3.0)
    region = TaughtRegion().fit(hand_teaching(outline, seed=0))
    over = [s for s in region.unsupported_edge if np.hypot(s.pan_deg + 5.7, s.tilt_deg - 30.6) < 6]
    assert over and all(s.held for s in over), region.unsupported_edge
    assert max(s.distance_deg for s in over) > SETTLED_DEG, "the edge did not bridge the notch"
    assert all(s.settled for s in over), f"a traced notch is still asked for: {over}"
    assert all(s.outline_deg <= SETTLED_DEG for s in over), over
    box = ((-12.0, 1.0), (26.0, 34.0))
    reach = reach_into(region.contains, PolygonRegion(outline), box, step_deg=0.1)
    assert reach <= BOUND_DEG, f"the held region reaches {reach:.2f} deg outside at the notch"


def test_the_open_end_of_an_unfinished_trace_stays_asked():
    """The curved band (seed 0) taught 30 s by hand: the unclosed trace's edge across the untaught
    inside is held, and still asked for."""
    bench = benchmark("bench_region_families")
    truth, mapping = bench.make_truth("curved band with bumps", 0)
    d, _ = decompose(bench.teach(truth, mapping, ("hand", 30.0), 0))
    region = TaughtRegion().fit(d)
    # the held stretches farther than SETTLED_DEG from the samples, 5 deg or more inside the truth
    deep = []
    for s in region.unsupported_edge:
        x = pan_tilt_to_direction(*np.radians([s.pan_deg, s.tilt_deg]))[None]
        if s.held and s.distance_deg > SETTLED_DEG and np.degrees(truth.swing.depth(x)[0]) > 5.0:
            deep.append(s)
    assert deep, region.unsupported_edge
    assert not any(s.settled for s in deep), f"an untaught inside was settled: {deep}"


def test_a_stretch_past_the_samples_outline_or_unheld_is_not_settled():
    """The outline settles only a held stretch near it; without one the distance decides."""
    deep = SETTLED_DEG + 0.5
    assert Stretch(0.0, 0.0, deep, 3.0, held=True, outline_deg=0.2).settled
    assert not Stretch(0.0, 0.0, deep, 3.0, held=True, outline_deg=SETTLED_DEG + 0.1).settled
    assert not Stretch(0.0, 0.0, deep, 3.0, held=False, outline_deg=0.2).settled
    assert not Stretch(0.0, 0.0, deep, 3.0, held=True).settled
    assert Stretch(0.0, 0.0, SETTLED_DEG - 0.1, 3.0, held=True).settled
