"""The twist band never reaches past the taught evidence: an untaught dip is held inside the truth
and named as a place to teach, and a steep bump is followed along its local slope."""

import math

import numpy as np
import pytest

from firmware_sim.hand import Hand
from limbctl.envelope.synthetic_twist import BandRegion
from limbctl.geometry.gimbal import direction_to_pan_tilt, pan_tilt_to_direction, pose_quat_scalar
from limbctl.geometry.twist import compose, decompose, wrap
from limbctl.region.twist_evidence import REPORT_CUT_DEG, UnsupportedPlace, unsupported_places
from limbctl.region.twist_region import TwistRegion

SQUARE = np.array([[-40.0, -30.0], [40.0, -30.0], [40.0, 40.0], [-40.0, 40.0]])
#: Where (pan, tilt deg) the bands below dip or bump.
DIP_AT = (0.0, 5.0)
#: Around the dip the teaching turned only mid-band (no stop within this, deg).
SPARSE_DEG = 16.0


def _bump(centre_deg, half_deg, width_deg, slope=0.0):
    """A band, centre 5 deg (+ ``slope`` per deg of pan), half-width 40 deg, changed by
    ``centre_deg`` and ``half_deg`` in a Gaussian at DIP_AT of sigma ``width_deg``."""

    def band_deg(pan, tilt):
        g = np.exp(-((pan - DIP_AT[0]) ** 2 + (tilt - DIP_AT[1]) ** 2) / (2.0 * width_deg**2))
        return 5.0 + slope * pan + centre_deg * g, 40.0 + half_deg * g

    return band_deg


#: The upper limit dips 8 deg, 10 deg one sigma: at most 0.49 deg per deg, within CAP_SLOPE.
DIP = _bump(-4.0, -4.0, 10.0)


def dipped_teaching():
    """The true region with the dip and a teaching (N, 4) that turned only mid-band near it."""
    truth = BandRegion(SQUARE, DIP)
    q = truth.teaching(3000, 1500, 2500, np.random.default_rng(4))
    d, tau = decompose(q)
    pan, tilt = (np.degrees(a) for a in direction_to_pan_tilt(d))
    near = np.hypot(pan - DIP_AT[0], tilt - DIP_AT[1]) < SPARSE_DEG
    # near the dip the hand passed turning only through the band's middle third
    c, h = truth.band(d[near])
    u = np.random.default_rng(5).uniform(-0.3, 0.3, near.sum())
    q[near] = compose(d[near], c + u * h)
    return truth, q


def _learned_grid(region) -> np.ndarray:
    """Directions (K, 3) of a 1 deg pan and tilt grid over the square inside the learned outline."""
    pan, tilt = np.meshgrid(np.arange(-36.0, 37.0, 1.0), np.arange(-26.0, 37.0, 1.0))
    d = pan_tilt_to_direction(np.radians(pan.ravel()), np.radians(tilt.ravel()))
    return d[region.swing.mesh.contains(d)]


def _within_a_degree(truth, q):
    """The region fitted to ``q``, checked within 1 deg of the truth's band over the grid."""
    region = TwistRegion().fit(q)
    d = _learned_grid(region)
    lc, lh = region.band.at(d)
    tc, th = truth.band(d)
    off = wrap(lc - tc)
    excess = float(np.degrees(np.fmax(off + lh - th, -off + lh - th)).max())
    assert excess <= 1.0, f"band {excess:.2f} deg past the true stop"
    return region


def _from_dip(place) -> float:
    return math.hypot(place.pan_deg - DIP_AT[0], place.tilt_deg - DIP_AT[1])


def _holds_the_truth(region, d, truth):
    """The true band 2 deg inside each stop is held at 99 % of directions ``d``."""
    tc, th = truth.band(d)
    for sign in (-1.0, 1.0):
        assert np.mean(region.contains(compose(d, tc + sign * (th - math.radians(2.0))))) >= 0.99


def test_a_dip_taught_only_mid_band_is_not_bridged_and_its_stop_is_named():
    region = _within_a_degree(*dipped_teaching())
    assert region.unsupported, "the dip's stop was never taught, yet nothing is listed"
    # both stops near the dip were passed only mid-band: the upper one is asked for there
    first = next(p for p in region.unsupported if p.side == "upper")
    assert _from_dip(first) < SPARSE_DEG
    assert first.cut_deg > REPORT_CUT_DEG
    assert f"pan {first.pan_deg:+.0f}, tilt {first.tilt_deg:+.0f}" in first.words()
    assert "upper (positive) twist stop" in first.words()


def test_a_sparsely_taught_steep_dip_is_held_to_the_samples_near_it():
    """A dip of 12 deg (8 deg one sigma, up to 0.91 deg per deg) taught with 500 i.i.d. samples is
    held within 1 deg, its upper stop asked for within two sigma of it."""
    truth = BandRegion(SQUARE, _bump(-6.0, -6.0, 8.0))
    region = _within_a_degree(truth, truth.teaching(500, 400, 600, np.random.default_rng(3)))
    near = [p for p in region.unsupported if p.side == "upper" and _from_dip(p) < 16.0]
    assert near, "the dip's upper stop was held short, yet not listed"


@pytest.mark.parametrize(
    "band_deg",
    [
        # taught densely: nothing is listed, and the band is held over the square
        pytest.param(DIP, id="the dip"),
        # 0.76 deg per deg at the upper limit, steeper than the fixed cone's CAP_SLOPE (0.5)
        pytest.param(_bump(5.0, 5.0, 8.0), id="bump steeper than the cone"),
        # the lower limit rises 17 deg bending up to 0.27 deg^-1: read at the sample's end
        pytest.param(_bump(5.0, -12.0, 8.0, slope=0.3), id="sharply bending bump"),
        # bending ~0.2 deg^-1, past CURVATURE_PER_DEG: far samples must not vouch along its side
        pytest.param(_bump(6.0, -10.0, 9.0, slope=0.2), id="bending bump on a sloping band"),
    ],
)
def test_a_densely_taught_bump_is_not_exceeded_and_the_band_holds_the_truth(band_deg):
    truth = BandRegion(SQUARE, band_deg)
    region = _within_a_degree(truth, truth.teaching(3000, 1500, 4000, np.random.default_rng(6)))
    _holds_the_truth(region, _learned_grid(region), truth)
    if band_deg is DIP:
        assert region.unsupported == ()
        pan, tilt = np.meshgrid(np.arange(-36.0, 37.0, 2.0), np.arange(-26.0, 37.0, 2.0))
        square = pan_tilt_to_direction(*np.radians([pan.ravel(), tilt.ravel()]))
        _holds_the_truth(region, square, truth)


def test_unsupported_places_keep_the_largest_cut_of_each_cell_and_side():
    d = pan_tilt_to_direction(np.radians([1.0, 2.0, 40.0]), np.radians([1.0, 2.0, 1.0]))
    up = np.radians([2.0, 3.0, 0.5])
    lo = np.radians([0.0, 1.5, 0.0])
    places = unsupported_places(d, up, lo)
    got = [(round(p.pan_deg), p.side, round(p.cut_deg, 6)) for p in places]
    assert got == [(2, "upper", 3.0), (2, "lower", 1.5)]
    assert unsupported_places(np.zeros((0, 3)), np.zeros(0), np.zeros(0)) == ()
    assert isinstance(places[0], UnsupportedPlace)


def _hand_truth(twist: dict, seed: int) -> tuple[Hand, BandRegion]:
    """The simulator hand over SQUARE with the band ``twist``, and that band as the truth."""
    mapping = {"region": {"polygon": SQUARE.tolist()}, "speed_deg_s": 40, "twist": twist}
    hand = Hand.from_mapping(mapping, seed=seed, source="<test>")
    limits = np.vectorize(hand.band.limits_deg, otypes=[float, float])

    def band_deg(pan, tilt):
        low, high = limits(pan, tilt)
        return 0.5 * (low + high), 0.5 * (high - low)

    return hand, BandRegion(SQUARE, band_deg)


def test_a_sparse_teaching_of_a_band_steeper_than_most_stays_within_a_degree():
    # the region families' curved band of seed 27 (a limit sloping up to 1.8 deg per deg,
    # bending 0.22 deg^-1)
    twist = {
        "centre_deg": {
            "linear": [-8.64, 0.296, 0.333],
            "quadratic": [0.00171, 0.0001, 0.0000735],
            "bumps": [[5.12, 6.79, 10.9, 8.24]],
        },
        "half_width_deg": {"linear": [46.54, 0.139, -0.229], "bumps": [[6.5, 8.63, -9.43, 12.93]]},
    }
    _, truth = _hand_truth(twist, seed=0)
    region = _within_a_degree(truth, truth.teaching(500, 400, 600, np.random.default_rng(0)))
    assert region.unsupported


def test_a_hand_taught_steep_curved_band_stays_within_a_degree_of_the_truth():
    # a curved band whose limits fall faster than the hold's cone (1 deg per deg)
    twist = {
        "centre_deg": {
            "linear": [-14.0, 0.2, 0.2],
            "quadratic": [0.003, 0.001, 0.0],
            "bumps": [[-6.0, 10.6, -8.1, 9.3]],
        },
        "half_width_deg": {"linear": [37.0, 0.1, -0.33], "bumps": [[-18.5, 9.1, 10.9, 11.9]]},
    }
    hand, truth = _hand_truth(twist, seed=1)
    rows = [hand.pose_deg(t) for t in np.arange(0.0, 30.0, 1.0 / 125.0)]
    q = np.array([pose_quat_scalar(*np.radians(r)) for r in rows])
    assert truth.contains(q).all()
    # what the bound holds short is asked for
    assert _within_a_degree(truth, q).unsupported
