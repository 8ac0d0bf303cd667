"""Holes in a teaching (written to disk and read back): one over the edge trace keeps it open."""

from __future__ import annotations

import numpy as np
import pytest

from limbctl.geometry.gimbal import direction_to_pan_tilt
from limbctl.teach.dataset import DatasetWriter, load_dataset
from limbctl.teach.guide import READY_EDGE_CLOSED, assess
from limbctl.teach.holes import HOLE_MIN_S, hole_bins, sample_gaps
from tests.teach.test_guide import RADIUS_DEG, RATE_HZ, fill, on_disc, times, trace

#: The hole: from azimuth 100 deg of the trace on, 0.25 s of samples missing (at the trace's
#: 15 deg/s, 3.75 deg of edge, 7.5 deg of azimuth on a 30 deg circle: 3 of the guide's 2 deg bins,
#: so the edge still reads closed above READY_EDGE_CLOSED, as in docs/decisions/twist.md).
HOLE_AT_DEG, HOLE_S = 100.0, 0.25


def teaching(hole: bool, retrace: bool = False, inside_hole: bool = False) -> np.ndarray:
    """Times (N,) and directions (N, 3): the circle's edge traced once from azimuth 0, then the
    middle filled; optionally ``HOLE_S`` of the trace missing from HOLE_AT_DEG on, a second
    slow pass over that stretch at the end, or a hole in the middle's strokes instead."""
    d = np.vstack([trace(0.0, 360.0), fill(-180.0, 180.0, 6000)])
    t = times(len(d))
    n_trace = len(trace(0.0, 360.0))
    keep = np.ones(len(d), dtype=bool)
    if hole:
        start = int(n_trace * HOLE_AT_DEG / 360.0)
        keep[start : start + int(HOLE_S * RATE_HZ)] = False
    if inside_hole:
        keep[n_trace + 1000 : n_trace + 1000 + int(0.5 * RATE_HZ)] = False
    t, d = t[keep], d[keep]
    if retrace:
        again = trace(HOLE_AT_DEG - 10.0, HOLE_AT_DEG + 25.0)
        t, d = np.r_[t, times(len(again), t[-1] + 1.0 / RATE_HZ)], np.vstack([d, again])
    return t, d


def written_and_loaded(tmp_path, t: np.ndarray, d: np.ndarray):
    """The teaching through a dataset file on disk: what the guide reads back from it."""
    pan, tilt = direction_to_pan_tilt(d)
    path = tmp_path / "teach.limb"
    with DatasetWriter(path, rig="sim") as writer:
        for k in range(len(t)):
            writer.append(t[k], pan[k], tilt[k])
    data = load_dataset(path)
    return assess(data.t, np.radians(data.pan_deg), np.radians(data.tilt_deg))


def test_a_hole_over_the_edge_trace_is_flagged_and_the_guide_asks_to_retrace_there(tmp_path):
    g = written_and_loaded(tmp_path, *teaching(hole=True))
    (hole,) = g.holes
    assert hole.duration_s == pytest.approx(HOLE_S + 1.0 / RATE_HZ, abs=1e-6)
    # (a stroke through the middle may by chance count as on the edge in one of its bins)
    assert hole.at_edge and hole.open and 0.5 * hole.fraction <= hole.open_fraction <= hole.fraction
    # the stretch lies between the samples around the hole: 7.5 deg of azimuth, 3-4 bins
    assert 3.0 / 180.0 <= hole.fraction <= 4.0 / 180.0
    middle = on_disc(np.array([RADIUS_DEG]), np.array([HOLE_AT_DEG + 3.75]))
    pan, tilt = np.degrees(direction_to_pan_tilt(middle))
    assert hole.edge_deg == pytest.approx((pan[0], tilt[0]), abs=1.5)
    # without the hole's bins the edge still reads closed: the hole alone keeps it from ready
    assert g.edge_closed >= READY_EDGE_CLOSED
    assert not g.ready and g.phase == "edge" and g.open_hole is hole
    p, t = hole.edge_deg
    assert f"re-trace the edge near pan {p:+.0f}, tilt {t:+.0f}" in g.line()
    assert "READY TO TRAIN" not in g.line()
    assert "untaught -> re-trace the edge near" in hole.line()
    # its stretch shows as an edge gap where it is
    assert any(gap.middle_deg == pytest.approx(hole.edge_deg, abs=2.5) for gap in g.edge_gaps)


@pytest.mark.parametrize(
    ("teaching_of", "at_edge", "ending"),
    [
        ({"hole": False}, None, None),
        ({"hole": True, "retrace": True}, True, "re-traced since"),
        ({"hole": False, "inside_hole": True}, False, "; inside"),
    ],
    ids=["none", "re-traced", "inside"],
)
def test_no_hole_a_re_traced_one_or_one_in_the_middle_leaves_ready_standing(
    tmp_path, teaching_of, at_edge, ending
):
    g = written_and_loaded(tmp_path, *teaching(**teaching_of))
    assert g.ready and "READY TO TRAIN" in g.line() and g.open_hole is None
    if ending is None:
        assert g.holes == (), g.holes
        return
    (hole,) = g.holes
    assert hole.at_edge == at_edge and not hole.open
    assert hole.fraction > 0.0 if at_edge else hole.edge_deg is None
    assert hole.line().endswith(ending)


def test_gaps_and_stretches_are_counted_as_documented():
    t = np.cumsum([0.0, 0.01, 0.999 * HOLE_MIN_S, 1.001 * HOLE_MIN_S, 0.01])
    # a gap just under HOLE_MIN_S is no hole; one just over it is
    assert sample_gaps(t).tolist() == [2]
    # the bins strictly between, the shorter way round, across the turn's seam too
    assert hole_bins(np.radians(-179.0), np.radians(179.0), 180).size == 0  # neighbours
    assert hole_bins(np.radians(-175.0), np.radians(175.0), 180).tolist() == [178, 179, 0, 1]
    assert hole_bins(np.radians(0.5), np.radians(9.0), 180).tolist() == [91, 92, 93]
    assert hole_bins(np.radians(9.0), np.radians(0.5), 180).tolist() == [91, 92, 93]
