"""The twist guide names the place of the swing plane where the twist was turned least."""

from __future__ import annotations

import math

import numpy as np
import pytest

from limbctl.geometry.gimbal import pan_tilt_to_direction
from limbctl.geometry.twist import compose
from limbctl.teach.twist_guide import MIN_CELL_SAMPLES, TwistGuide


def taught(guide, pan_deg, tilt_deg, twists_deg):
    d = pan_tilt_to_direction(math.radians(pan_deg), math.radians(tilt_deg))
    for tau in twists_deg:
        guide.add(compose(d, math.radians(tau)))


def six_places_turned(guide) -> None:
    """Six places, each turned 80 deg both ways."""
    for pan, tilt in [(p, t) for p in (-30, 0, 30) for t in (-20, 10)]:
        taught(guide, pan + 1, tilt + 1, np.linspace(-40, 40, MIN_CELL_SAMPLES))


def test_places_turned_both_ways_one_left_untaught_and_one_across_half_a_turn():
    guide = TwistGuide()
    assert "not yet taught" in guide.assess().line()
    six_places_turned(guide)
    full = guide.assess()
    assert (full.cells, full.turned) == (6, 6)
    assert full.wide_span_deg == pytest.approx(80.0)
    assert "every place visited was turned both ways" in full.line()
    assert full.short() == "twist 6/6 turned"
    # a new place visited with hardly any twist: named, with its span against the widest
    taught(guide, 46, 31, np.linspace(-3, 3, MIN_CELL_SAMPLES))
    found = guide.assess()
    assert (found.cells, found.turned) == (7, 6)
    pan, tilt, span = found.least
    # named where its samples lie, not at its cell's centre (+52, +38), which may lie outside
    assert (pan, tilt) == pytest.approx((46.0, 31.0)) and span == pytest.approx(6.0)
    assert "least at pan +46, tilt +31: 6 deg -> turn the limb both ways" in found.line()
    assert found.short() == "twist 6/7 turned, least 6 deg at (+46, +31)"
    (named,) = [p for p in found.places if not p.turned]
    assert (named.pan_deg, named.tilt_deg) == pytest.approx((46.0, 31.0))
    guide = TwistGuide()
    taught(guide, 0, 0, np.zeros(MIN_CELL_SAMPLES - 1))
    assert guide.assess().cells == 0, "a cell with too few samples was judged"
    # a range across half a turn stays one range
    guide = TwistGuide()
    taught(guide, 1, 1, np.linspace(170.0, 200.0, MIN_CELL_SAMPLES))  # 170..180, -180..-160
    (place,) = guide.assess().places
    assert place.high_deg - place.low_deg == pytest.approx(30.0)
    assert place.low_deg == pytest.approx(170.0) and place.high_deg == pytest.approx(200.0)


def test_every_place_turned_is_not_complete_until_the_missing_stop_is_taught():
    from tests.region.test_twist_evidence import DIP_AT, SPARSE_DEG, dipped_teaching

    truth, q = dipped_teaching()
    guide = TwistGuide()
    for row in q:
        guide.add(row)
    before = guide.assess()
    assert before.turned == before.cells and not before.complete  # not yet checked
    places = guide.check_support()
    found = guide.assess()
    assert found.support_checked and not found.complete
    first = found.unsupported[0]
    assert places == found.unsupported
    # both stops near the dip were passed only mid-band: both asked for, there
    assert {p.side for p in places} == {"upper", "lower"}
    for place in places[:2]:
        assert math.hypot(place.pan_deg - DIP_AT[0], place.tilt_deg - DIP_AT[1]) < SPARSE_DEG
    assert f"twist stop near pan {first.pan_deg:+.0f}, tilt {first.tilt_deg:+.0f}" in found.line()
    assert found.short().endswith(
        f"{first.side} stop at ({first.pan_deg:+.0f}, {first.tilt_deg:+.0f})"
    )
    # both stops taught all over (a lattice 2 deg apart): complete
    grid = np.meshgrid(np.arange(-38.0, 39.0, 2.0), np.arange(-28.0, 39.0, 2.0))
    d = pan_tilt_to_direction(*np.radians(grid).reshape(2, -1))
    c, h = truth.band(d)
    for sign in (1.0, -1.0):
        for row in compose(d, c + sign * (h - math.radians(0.2))):
            guide.add(row)
    guide.check_support()
    done = guide.assess()
    assert done.complete, done.line()
    assert "every place visited was turned both ways" in done.line()


@pytest.mark.parametrize("warmed", [False, True])
def test_the_support_check_while_recording_waits_for_the_warmed_kernels(monkeypatch, warmed):
    """No support check (it compiles in the recorder's process) until the kernels are cached."""
    from limbctl.geometry import jit

    asked = []

    def prepared(stage):
        asked.append(stage)
        return warmed

    monkeypatch.setattr(jit, "prepared", prepared)
    guide = TwistGuide()
    six_places_turned(guide)
    found = guide.assess()
    assert found.turned == found.cells == 6
    assert asked == ["train-twist"]
    if warmed:
        assert guide._checking is not None
        guide._checking.join()
        assert guide.assess().support_checked
    else:
        assert guide._checking is None and not found.support_checked
