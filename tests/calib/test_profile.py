import copy
import math
import os
from pathlib import Path

import pytest
import yaml

from calib import (
    JointProfile,
    ProfileError,
    RigProfile,
    default_sim_profile,
    load_profile,
    profile_from_dict,
    save_profile,
)
from limbctl.errors import ConfigError, FileFormatError
from limbctl.servo.profiles import joint_tick_limits, load_rig_profile

SIM_YAML = Path(__file__).resolve().parents[2] / "calib" / "rigs" / "sim.yaml"


@pytest.fixture
def sim_data():
    return yaml.safe_load(SIM_YAML.read_text())


def write(tmp_path, data, name="x.yaml"):
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data))
    return path


def test_default_sim_profile_matches_the_packaged_file(sim_data):
    profile = default_sim_profile()
    assert isinstance(profile, RigProfile)
    assert profile.name == sim_data["name"]
    assert profile.is_sim
    assert profile.baud == sim_data["baud"]
    assert profile.pan == JointProfile(**sim_data["pan"])
    assert profile.tilt == JointProfile(**sim_data["tilt"])
    assert profile.ids == (sim_data["pan"]["id"], sim_data["tilt"]["id"])
    assert profile.source is not None and profile.source.endswith("sim.yaml")


def test_profile_is_frozen():
    profile = default_sim_profile()
    with pytest.raises(AttributeError):
        profile.baud = 1  # type: ignore[misc]
    with pytest.raises(AttributeError):
        profile.pan.direction = 1  # type: ignore[misc]


def test_save_then_load_round_trips(tmp_path):
    profile = default_sim_profile()
    out = save_profile(profile, tmp_path / "rig.yaml")
    again = load_profile(out)
    assert again == profile
    assert again.source == str(out)
    # no temp files left behind by the atomic write
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rig.yaml"]


def test_save_replaces_atomically_and_refuses_invalid(tmp_path):
    path = tmp_path / "rig.yaml"
    profile = default_sim_profile()
    save_profile(profile, path)
    before = path.read_text()
    bad = RigProfile(**{**profile.__dict__, "pan": JointProfile(1, 2185, 3, -10.0, 10.0)})
    with pytest.raises(ProfileError, match="pan.direction"):
        save_profile(bad, path)
    assert path.read_text() == before


@pytest.mark.parametrize(
    ("edit", "field", "fragment"),
    [
        (lambda d: d["pan"].update(direction=2), "pan.direction", "must be +1 or -1, got 2"),
        (lambda d: d["tilt"].update(direction=True), "tilt.direction", "+1 or -1"),
        (lambda d: d["pan"].update(id=300), "pan.id", "0..252"),
        (lambda d: d["tilt"].update(id=d["pan"]["id"]), "tilt.id", "must differ"),
        (lambda d: d["pan"].update(zero_tick=5000), "pan.zero_tick", "0..4095"),
        (lambda d: d["pan"].update(zero_tick=1.5), "pan.zero_tick", "integer"),
        (lambda d: d["tilt"].update(min_deg=80.0), "tilt.min_deg/max_deg", "min_deg < max_deg"),
        (lambda d: d["tilt"].update(max_deg=float("nan")), "tilt.max_deg", "finite"),
        (lambda d: d["pan"].update(max_deg="lots"), "pan.max_deg", "number"),
        (lambda d: d["pan"].update(zero_tick=100), "pan.min_deg/max_deg", "outside one servo"),
        (lambda d: d["pan"].pop("zero_tick"), "pan", "missing zero_tick"),
        (lambda d: d["pan"].update(zero=1), "pan", "unknown keys zero"),
        (lambda d: d.update(baud=12345), "baud", "must be one of"),
        (lambda d: d.update(model="ax12"), "model", "xl430-w250, xm430-w350"),
        (lambda d: d.update(protocol=1.0), "protocol", "2.0"),
        (lambda d: d.update(port=""), "port", "non-empty"),
        (lambda d: d.pop("name"), "profile", "missing name"),
        (lambda d: d.update(prot=2.0), "profile", "unknown keys prot"),
        (lambda d: d.update(rest_direction=[0, 0, 0]), "rest_direction", "zero vector"),
        (lambda d: d.update(rest_direction=[1, 0]), "rest_direction", "3 numbers"),
    ],
)
def test_invalid_fields_name_file_and_field(tmp_path, sim_data, edit, field, fragment):
    data = copy.deepcopy(sim_data)
    edit(data)
    path = write(tmp_path, data)
    with pytest.raises(ConfigError) as info:
        load_rig_profile(path)
    message = str(info.value)
    assert message.startswith(f"{path}: {field} ")
    assert fragment in message


def test_the_brief_example_message(tmp_path, sim_data):
    sim_data["pan"]["direction"] = 2
    path = write(tmp_path, sim_data)
    with pytest.raises(ConfigError, match=r"x\.yaml: pan\.direction must be \+1 or -1, got 2$"):
        load_rig_profile(path)


def test_unreadable_yaml_is_a_file_format_error(tmp_path):
    path = tmp_path / "broken.yaml"
    path.write_text("name: [unclosed\n")
    with pytest.raises(FileFormatError, match="broken.yaml: not valid YAML"):
        load_rig_profile(path)


def test_missing_file_says_what_to_do(tmp_path):
    with pytest.raises(ConfigError, match="no such rig profile.*limbctl calibrate"):
        load_rig_profile(tmp_path / "nope.yaml")


def test_top_level_must_be_a_mapping(tmp_path):
    path = tmp_path / "list.yaml"
    path.write_text("- 1\n- 2\n")
    with pytest.raises(ConfigError, match="list.yaml: top level must be a mapping"):
        load_rig_profile(path)


def test_rest_direction_is_optional_and_normalised(sim_data):
    data = copy.deepcopy(sim_data)
    del data["rest_direction"]
    assert profile_from_dict(data).rest_direction == (1.0, 0.0, 0.0)
    data["rest_direction"] = [0.0, 3.0, 4.0]
    assert profile_from_dict(data).rest_direction == pytest.approx((0.0, 0.6, 0.8))


def test_joint_limits_in_radians_and_ticks():
    joint = JointProfile(id=1, zero_tick=2048, direction=-1, min_deg=-90.0, max_deg=45.0)
    assert joint.min_rad == pytest.approx(-math.pi / 2)
    assert joint.max_rad == pytest.approx(math.pi / 4)
    # direction -1: +45 deg lies 512 ticks below zero, -90 deg 1024 above
    assert joint_tick_limits(joint) == (2048 - 512, 2048 + 1024)


def test_save_into_current_directory(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    save_profile(default_sim_profile(), "here.yaml")
    assert load_profile(os.path.join(tmp_path, "here.yaml")) == default_sim_profile()
