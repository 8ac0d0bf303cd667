"""The region cut back to the taught evidence: every edge point within the reach of a sample,
or the cut's own depth inside (issue 35, finding 1)."""

import numpy as np
import pytest
from scipy.spatial import cKDTree

from limbctl.region import evidence_clip as ec
from limbctl.region.evidence import Stretch, edge_stations, outer_arcs
from limbctl.region.loops import loop_area
from limbctl.region.mesh import DirectionMesh
from tests.region.support import off_x

#: The cone's radius (deg) about +x.
RADIUS_DEG = 20.0
X = np.array([1.0, 0.0, 0.0])


def _cone(radius_deg: float = RADIUS_DEG) -> DirectionMesh:
    loop = off_x(np.full(360, radius_deg), np.arange(0.0, 360.0, 1.0))
    assert loop_area(loop) > 0.0
    return DirectionMesh.from_loops([loop], 0.0)


def _taught(n: int, seed: int, radius_deg: float = RADIUS_DEG) -> np.ndarray:
    """``n`` directions uniform over the cone (area-uniform)."""
    rng = np.random.default_rng(seed)
    cos_angle = rng.uniform(np.cos(np.radians(radius_deg)), 1.0, n)
    return off_x(np.degrees(np.arccos(cos_angle)), rng.uniform(0.0, 360.0, n))


def _angle_deg(d: np.ndarray, x: np.ndarray) -> np.ndarray:
    return np.degrees(np.arccos(np.clip(d @ x, -1.0, 1.0)))


#: Where the cone's edge is left untaught.
GAP = off_x(RADIUS_DEG, 0.0)


def _with_gap(gap_deg: float, n: int = 4000, seed: int = 3) -> np.ndarray:
    """The cone taught uniformly and along its edge (every 0.5 deg, 0.05 deg in), none within
    ``gap_deg`` of ``GAP``."""
    edge = off_x(np.full(720, RADIUS_DEG - 0.05), np.arange(0.0, 360.0, 0.5))
    d = np.vstack([_taught(n, seed), edge])
    return d[_angle_deg(d, GAP) > gap_deg]


def test_a_region_whose_edge_stands_by_the_samples_comes_back_as_it_is():
    cone = _cone()
    stations, _ = edge_stations(cone, np.radians(ec.CLIP_STEP_DEG))
    clip = ec.clip_to_evidence(cone, np.vstack([_taught(2000, 1), stations]))
    assert clip.region is cone and not clip.cut and clip.cut_sr == 0.0


def test_a_region_wider_than_one_plane_is_left_uncut_and_says_so():
    wide = _cone(85.0)
    clip = ec.clip_to_evidence(wide, _taught(500, 2, 85.0))
    assert clip.region is wide and not clip.cut and not clip.fits


def test_an_untaught_stretch_of_edge_is_cut_back_to_the_samples_reach_and_named():
    taught = _with_gap(4.0)
    cone = _cone()
    clip = ec.clip_to_evidence(cone, taught)
    assert clip.cut and clip.fits
    # named once, at the gap, as far as its farthest station stood (the gap's 4 deg less)
    assert clip.places.shape[0] == 1
    assert _angle_deg(clip.places, GAP)[0] < 4.0
    assert 3.0 < clip.far_deg[0] <= 4.0 + ec.CLIP_STEP_DEG
    # every outer edge point (0.02 deg apart) within reach of a sample, or the cut's depth inside
    stations, arc = edge_stations(clip.region, np.radians(0.02))
    stations = stations[outer_arcs(clip.region)[arc]]
    far = np.degrees(2.0 * np.arcsin(0.5 * cKDTree(taught).query(stations)[0]))
    depth = RADIUS_DEG - _angle_deg(stations, X)
    assert np.all((far <= ec.CLIP_REACH_DEG + 0.01) | (depth >= ec.DEEP_DEG - 0.05)), far.max()
    # every taught sample kept; away from the gap nothing changed
    assert cone.contains(taught).all() and clip.region.contains(taught).all()
    probe = _taught(20000, 9, RADIUS_DEG + 2.0)
    away = _angle_deg(probe, GAP) > 4.0 + ec.CLIP_REACH_DEG + 0.1
    assert np.array_equal(clip.region.contains(probe[away]), cone.contains(probe[away]))
    # and the cut is a bite of the gap, no more: under a 4 deg disc's area
    assert 0.0 < clip.cut_sr < np.pi * np.radians(4.0) ** 2
    # the place cut is listed held, unless a stretch names it already
    listed = ec.clipped_stretches((), clip)
    assert len(listed) == 1 and listed[0].held
    assert listed[0].distance_deg == pytest.approx(clip.far_deg[0])
    assert "held at the evidence" in listed[0].line()
    there = Stretch(listed[0].pan_deg, listed[0].tilt_deg, 2.0, 1.0)
    assert ec.clipped_stretches((there,), clip) == (there,)


def test_a_cut_stops_at_its_depth_inside_the_region():
    """With no sample within 10 deg of the gap, the cut reaches ``DEEP_DEG`` in (plus its discs'
    slack) and stops: the region deeper is kept."""
    clip = ec.clip_to_evidence(_cone(), _with_gap(10.0))
    probe = _taught(40000, 5)
    depth = RADIUS_DEG - _angle_deg(probe, X)
    deep = depth >= (ec.DEEP_DEG + 0.5 * ec.DEEP_STEP_DEG) / ec.INSCRIBED
    assert clip.region.contains(probe[deep]).all()
    shallow_gap = (depth < ec.DEEP_DEG - 0.3) & (_angle_deg(probe, GAP) < 8.0)
    assert not clip.region.contains(probe[shallow_gap]).any()


def test_a_narrow_bridged_notch_is_cut_to_its_end():
    """An untaught channel 6.4 deg wide and 8 deg deep (its mouth about 4 deg): the first pass
    takes it to its end, not ``DEEP_DEG`` in, and names it."""
    d = _with_gap(0.0)
    channel = off_x(RADIUS_DEG - np.arange(0.0, 8.01, 0.05), np.zeros(1))
    taught = d[np.degrees(cKDTree(channel).query(d)[0]) > 3.2]
    clip = ec.cut_to_evidence(_cone(), taught)
    assert clip.cut and clip.region.contains(taught).all()
    floor = off_x(RADIUS_DEG - np.arange(ec.DEEP_DEG + 0.5, 8.0, 0.25), np.zeros(1))
    far = np.degrees(cKDTree(taught).query(floor)[0]) > ec.NOTCH_REACH_DEG + 0.1
    assert far.sum() >= 10
    assert not clip.region.contains(floor[far]).any()
    # the place is named, as far from the samples as the channel's half width
    assert _angle_deg(clip.places, GAP).min() < 3.2 and clip.far_deg.max() <= 3.2 + ec.CLIP_STEP_DEG
