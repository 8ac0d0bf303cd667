import pytest

from limbctl.errors import ConfigError
from limbctl.region.params import RegionParams


def test_defaults_a_round_trip_through_plain_values_and_unknown_names_refused():
    params = RegionParams()
    assert params.edge == "auto" and params.thin_deg == 1.0 and params.support_nodes == 3000
    changed = RegionParams(thin_deg=2, edge="traced")
    assert isinstance(changed.thin_deg, float)
    assert RegionParams.from_dict(changed.as_dict()) == changed
    with pytest.raises(AttributeError):
        changed.edge = "smooth"  # frozen
    with pytest.raises(ConfigError, match="unknown region settings smooth_edge; choose from: "):
        RegionParams.from_dict({"smooth_edge": False})


@pytest.mark.parametrize(
    "settings, message",
    [
        ({"thin_deg": 0.0}, "thin_deg must be > 0"),
        ({"peel_factor": -1.0}, "peel_factor must be > 0"),
        ({"max_margin_deg": -0.1}, "max_margin_deg must be >= 0"),
        ({"support_nodes": 2}, "support_nodes must be >= 3"),
        ({"edge": "round"}, "choose one of: auto, smooth, traced, supported"),
    ],
)
def test_bad_settings_are_refused_saying_what_is_allowed(settings, message):
    with pytest.raises(ConfigError, match=message):
        RegionParams(**settings)
