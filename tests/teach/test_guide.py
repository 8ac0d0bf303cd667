"""The teaching guide on synthetic teachings with known answers, and on the simulator's hand."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from firmware_sim.hand import Hand
from firmware_sim.world import World
from limbctl.geometry.gimbal import direction_to_pan_tilt, pan_tilt_to_direction
from limbctl.geometry.quat import tangent_frame
from limbctl.teach.guide import (
    EDGE_BINS,
    PHASES,
    READY_INSIDE_COVERED,
    EdgeGap,
    Guide,
    InsideGap,
    assess,
    assess_directions,
)

REGIONS = Path(__file__).resolve().parents[2] / "examples" / "regions"
CENTRE_DEG = (20.0, 10.0)
RADIUS_DEG = 30.0
RATE_HZ = 100.0


def frame():
    c = pan_tilt_to_direction(*np.radians(CENTRE_DEG))
    u, v = tangent_frame(c)
    return c, u, v


def on_disc(radius_deg: np.ndarray, azimuth_deg: np.ndarray) -> np.ndarray:
    """Directions (M, 3) at angle ``radius_deg`` from the centre, azimuth ``azimuth_deg``."""
    c, u, v = frame()
    r, a = np.radians(radius_deg)[:, None], np.radians(azimuth_deg)[:, None]
    return np.cos(r) * c + np.sin(r) * (np.cos(a) * u + np.sin(a) * v)


def trace(from_deg: float, to_deg: float, speed_deg_s: float = 15.0) -> np.ndarray:
    """The circle's edge traced from azimuth ``from_deg`` to ``to_deg`` at a steady pace, sampled
    at RATE_HZ: (M, 3) directions."""
    arc_deg = np.radians(abs(to_deg - from_deg)) * np.sin(np.radians(RADIUS_DEG)) * 180 / np.pi
    n = int(arc_deg / speed_deg_s * RATE_HZ) + 1
    return on_disc(np.full(n, RADIUS_DEG), np.linspace(from_deg, to_deg, n))


def fill(from_deg: float, to_deg: float, n: int, seed: int = 0) -> np.ndarray:
    """``n`` directions spread evenly (by area) over the sector from_deg..to_deg of the disc."""
    rng = np.random.default_rng(seed)
    radius = RADIUS_DEG * np.sqrt(rng.uniform(size=n))
    return on_disc(radius, rng.uniform(from_deg, to_deg, size=n))


def times(n: int, start_s: float = 0.0) -> np.ndarray:
    return start_s + np.arange(n) / RATE_HZ


def test_a_full_trace_closes_the_edge_and_one_with_a_90_degree_gap_locates_the_gap():
    d = trace(0.0, 360.0)
    g = assess_directions(times(len(d)), d)
    assert g.edge_closed == 1.0 and g.edge_gaps == ()
    assert g.centre_deg == pytest.approx(CENTRE_DEG, abs=0.1)
    assert g.phase == "middle" and not g.ready  # the middle is still to be wandered
    assert g.spread_deg == pytest.approx(RADIUS_DEG, abs=0.5)
    # a trace with a 90 degree gap is three quarters closed, and the gap is located
    d = trace(45.0, 315.0)  # the stretch from -45 to +45 deg azimuth is never traced
    g = assess_directions(times(len(d)), d)
    # 270 of 360 deg; the two bins the gap's ends fall in hold samples
    assert g.edge_closed == pytest.approx(0.75, abs=2.0 / EDGE_BINS)
    assert g.phase == "edge" and not g.ready
    (gap,) = g.edge_gaps
    assert gap.fraction == pytest.approx(0.25, abs=2.0 / EDGE_BINS)
    # where: the gap's middle is the edge at azimuth 0, its ends at -45 and +45
    expected = on_disc(np.full(3, RADIUS_DEG), np.array([-45.0, 0.0, 45.0]))
    pan, tilt = np.degrees(direction_to_pan_tilt(expected))
    for got, p, t in zip((gap.start_deg, gap.middle_deg, gap.end_deg), pan, tilt, strict=True):
        assert got == pytest.approx((p, t), abs=1.5)
    assert g.largest_gap is gap
    assert "edge gap 24 %" in g.line() and PHASES["edge"] in g.line()  # 44 of 180 bins


def test_inside_coverage_of_a_half_filled_disc_is_a_half_and_the_empty_half_is_the_gap():
    edge = trace(0.0, 360.0)
    d = np.vstack([edge, fill(-90.0, 90.0, 20000)])
    g = assess_directions(times(len(d)), d)
    assert g.edge_closed == 1.0
    assert g.inside_covered == pytest.approx(0.5, abs=0.06)
    gap = g.inside_gaps[0]
    assert gap.fraction == pytest.approx(0.5, abs=0.06)
    # the empty half lies at azimuth 180: its middle 4 R / (3 pi) = 12.7 deg from the centre
    expected = on_disc(np.array([4.0 * RADIUS_DEG / (3.0 * np.pi)]), np.array([180.0]))
    pan, tilt = np.degrees(direction_to_pan_tilt(expected))
    assert gap.middle_deg == pytest.approx((pan[0], tilt[0]), abs=1.5)
    assert g.largest_gap is gap and "inside gap" in g.line()
    assert g.phase == "ready"  # half the inside is more than READY_INSIDE_COVERED
    assert READY_INSIDE_COVERED < 0.5


def test_a_traced_edge_and_a_filled_middle_are_ready_collected_too_a_few_samples_say_nothing():
    d = np.vstack([trace(0.0, 360.0), fill(-180.0, 180.0, 20000)])
    g = assess_directions(times(len(d)), d)
    assert g.edge_closed == 1.0 and g.inside_covered == 1.0 and g.inside_gaps == ()
    assert g.ready and g.phase == "ready" and "READY TO TRAIN" in g.line()
    # the guide collects the samples as the recorder reads them, to the same verdict
    t = times(len(d))
    pan, tilt = direction_to_pan_tilt(d)
    guide = Guide(capacity=16)  # grows as samples come
    for k in range(len(d)):
        guide.add(t[k], pan[k], tilt[k])
    assert guide.samples == len(d)
    collected = guide.assess()
    assert collected.samples == g.samples == len(d)
    for name in ("edge_closed", "inside_covered", "phase"):
        assert getattr(collected, name) == getattr(g, name), name
    assert collected.centre_deg == pytest.approx(g.centre_deg, abs=1e-9)
    # a few samples say nothing yet, and bad input is refused
    few = assess_directions(times(5), trace(0.0, 10.0)[:5])
    assert few.phase == "start" and few.samples == 5 and not few.ready
    assert assess_directions(np.empty(0), np.empty((0, 3))).phase == "start"
    with pytest.raises(ValueError, match="one time each"):
        assess_directions(times(3), trace(0.0, 90.0))


def test_only_a_slow_trace_counts_as_the_edge_and_strokes_out_to_it_do_not_close_it():
    fast = trace(0.0, 360.0, speed_deg_s=60.0)  # a sweep, not a trace
    assert assess_directions(times(len(fast)), fast).edge_closed == 0.0
    slow = trace(0.0, 360.0, speed_deg_s=20.0)
    assert assess_directions(times(len(slow)), slow).edge_closed == 1.0
    # eight slow strokes from the centre to the edge and back: a star, not a traced edge
    strokes = []
    for azimuth in np.arange(0.0, 360.0, 45.0):
        out = np.linspace(0.0, RADIUS_DEG, int(RADIUS_DEG / 15.0 * RATE_HZ))
        strokes.append(on_disc(np.r_[out, out[::-1]], np.full(2 * len(out), azimuth)))
    d = np.vstack(strokes)
    g = assess_directions(times(len(d)), d)
    assert g.edge_closed < 0.1
    assert g.phase == "edge" and len(g.edge_gaps) > 1


def simulated(style: str, seconds: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(t, pan_tilt_deg) sampled at 100 Hz while the simulator's hand teaches irregular.yaml."""
    spec = {**yaml.safe_load((REGIONS / "irregular.yaml").read_text()), "style": style}
    world = World(hand=Hand.from_mapping(spec, seed=seed), seed=seed)
    samples = []
    for _ in range(int(seconds * RATE_HZ)):
        world.step(1.0 / RATE_HZ, {1: None, 2: None})
        angles = world.joint_angles_deg()
        samples.append((angles["pan"], angles["tilt"]))
    return times(len(samples)), np.radians(samples)


@pytest.mark.parametrize("seed", [0, 1])
def test_the_simulators_hand_is_guided_through_the_phases(seed):
    t, pose = simulated("trace", 32.0, seed)
    phases = {}
    # the hand reaches the edge at 1.4 s and closes it at 25.1-25.3 s (seeds 0, 1)
    for seconds in (10.0, 25.5, 32.0):
        k = int(seconds * RATE_HZ)
        phases[seconds] = assess(t[:k], pose[:k, 0], pose[:k, 1])
    assert phases[10.0].phase == "edge" and isinstance(phases[10.0].largest_gap, EdgeGap)
    assert phases[25.5].phase == "middle" and isinstance(phases[25.5].largest_gap, InsideGap)
    assert phases[32.0].phase == "ready" and phases[32.0].edge_closed >= 0.97


def test_thirty_seconds_of_wandering_leave_most_of_the_edge_open():
    t, pose = simulated("wander", 30.0, 0)
    g = assess(t, pose[:, 0], pose[:, 1])
    assert g.edge_closed < 0.5 and g.phase == "edge" and not g.ready


def dented_trace(dents_deg, speed_deg_s=15.0, fast_in=None):
    """The circle's edge traced once round at ``speed_deg_s``, down into, across and out of an
    8 deg wide, 6 deg deep dent at each azimuth of ``dents_deg``; the dent at ``fast_in`` and
    6 deg of edge each side are swept at 60 deg/s. Directions (M, 3) at RATE_HZ."""
    corners = [(RADIUS_DEG, 0.0)]
    for at in sorted(dents_deg):
        corners += [(RADIUS_DEG, at - 10), (RADIUS_DEG, at - 4), (RADIUS_DEG - 6, at - 4)]
        corners += [(RADIUS_DEG - 6, at + 4), (RADIUS_DEG, at + 4), (RADIUS_DEG, at + 10)]
    corners.append((RADIUS_DEG, 360.0))
    pieces = []
    for (r0, a0), (r1, a1) in zip(corners[:-1], corners[1:], strict=True):
        fast = fast_in is not None and abs((a0 + a1) / 2 - fast_in) < 10
        # the leg's length on the sphere, about: radial deg, or an arc of r sin(R) per azimuth deg
        length = abs(r1 - r0) + abs(a1 - a0) * np.sin(np.radians(RADIUS_DEG))
        n = max(int(length / (60.0 if fast else speed_deg_s) * RATE_HZ), 1)
        pieces.append(on_disc(np.linspace(r0, r1, n, endpoint=False), np.linspace(a0, a1, n)))
    return np.vstack(pieces)


def test_a_slow_trace_along_narrow_dents_closes_them_a_fast_one_or_a_hole_does_not():
    dents = (40.0, 160.0, 280.0)
    d = dented_trace(dents)
    g = assess_directions(times(len(d)), d)
    # the outline runs across each dent's mouth and the trace along its floor lies 6 deg below
    # it, out of the band; traced slowly from one side to the other, the dents are edge
    assert g.edge_closed == 1.0 and g.edge_gaps == ()
    # swept at 60 deg/s, a dent and the edge beside it are not traced: at least the dent's 4 bins
    # stay open, and every gap lies in the swept stretch (azimuth 150-170)
    d = dented_trace(dents, fast_in=160.0)
    g = assess_directions(times(len(d)), d)
    assert 1.0 - 10.0 / EDGE_BINS <= g.edge_closed <= 1.0 - 4.0 / EDGE_BINS
    swept = on_disc(np.full(2, RADIUS_DEG), np.array([150.0, 170.0]))
    pan, tilt = np.degrees(direction_to_pan_tilt(swept))
    for gap in g.edge_gaps:
        assert min(pan) - 1 <= gap.middle_deg[0] <= max(pan) + 1
        assert min(tilt) - 1 <= gap.middle_deg[1] <= max(tilt) + 1
    # a hole in the recording while in a dent: the limb may have left the dent unseen
    d = dented_trace(dents)
    t = times(len(d))
    in_dent = np.flatnonzero(
        np.isclose(np.degrees(np.arccos(d @ frame()[0])), RADIUS_DEG - 6, atol=0.01)
    )
    t[in_dent[len(in_dent) // 2] :] += 0.5
    assert assess_directions(t, d).edge_closed < 1.0
