"""The twist band of a REGION.yaml: its format, how it varies with the pose, its refusals."""

from __future__ import annotations

import math
import re

import pytest

from firmware_sim.regions import region_from_mapping
from firmware_sim.twist_band import MAX_HALF_WIDTH_DEG, MIN_HALF_WIDTH_DEG, TwistBand

#: The linear part of a curved band the malformed ones below add to.
LINEAR = {"linear": [40, 0, 0]}
SQUARE = region_from_mapping({"polygon": [[-40, -30], [40, -30], [40, 50], [-40, 50]]})


def test_a_number_is_the_same_everywhere_and_a_list_is_linear_in_pan_and_tilt():
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


def test_contains_compares_on_the_circle():
    band = TwistBand.from_mapping({"centre_deg": 170, "half_width_deg": 20}, SQUARE)
    assert band.contains(0, 0, -175.0)  # 15 deg past +180 is still inside
    assert band.contains(0, 0, 160.0)
    assert not band.contains(0, 0, -165.0)
    assert not band.contains(0, 0, 140.0)


@pytest.mark.parametrize(
    ("spec", "message"),
    [
        ({"half_width_deg": [40, 0, -1.0]}, "runs"),  # 40 - 50 < 0 at the top
        ({"half_width_deg": 175}, f"within {MIN_HALF_WIDTH_DEG:g}..{MAX_HALF_WIDTH_DEG:g}"),
        ({"centre_deg": 0}, "half_width_deg \\(required\\)"),
        ({"half_width_deg": 20, "spin": 1}, "twist takes"),
        ({"half_width_deg": [1, 2]}, "a number or \\[a, b, c\\]"),
        ({"half_width_deg": "wide"}, "finite numbers"),
        ([1, 2], "must be a mapping"),
        ({"half_width_deg": {**LINEAR, "cubic": [1, 2, 3]}}, "takes linear, quadratic, bumps"),
        ({"half_width_deg": {**LINEAR, "bumps": [[0, 0, 5]]}}, "bumps must be a list"),
        (
            {"half_width_deg": {**LINEAR, "quadratic": 0.1}},
            re.escape("quadratic must be [p, m, t]"),
        ),
    ],
)
def test_bad_bands_are_refused_with_the_reason(spec, message):
    with pytest.raises(ValueError, match=message):
        TwistBand.from_mapping(spec, SQUARE, "r.yaml")


def test_a_mapping_gives_a_curved_band_with_bumps_and_the_list_forms_still_load():
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
