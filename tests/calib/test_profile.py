import copy
import itertools
import math
import os
from pathlib import Path

import pytest
import yaml

from calib import (
    Calibration,
    JointCalibration,
    JointProfile,
    ProfileError,
    RigProfile,
    calibration_from_dict,
    default_sim_profile,
    load_profile,
    profile_from_dict,
    save_profile,
)
from calib.profile import DEFAULT_END_STOP_DEG, END_STOP_MARGIN_DEG
from firmware_sim.world import DEFAULT_JOINTS, ROLL_JOINT
from limbctl.errors import ConfigError, FileFormatError
from limbctl.servo.profiles import joint_tick_limits, load_rig_profile

SIM_YAML = Path(__file__).resolve().parents[2] / "calib" / "rigs" / "sim.yaml"
SIM3_YAML = SIM_YAML.with_name("sim3.yaml")


@pytest.fixture
def sim_data():
    return yaml.safe_load(SIM_YAML.read_text())


def write(tmp_path, data, name="x.yaml"):
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data))
    return path


@pytest.mark.parametrize("rig", ["sim", "sim3"])
def test_a_packaged_profile_matches_its_file_and_the_world_round_trips_and_reads_as_a_list(
    rig, tmp_path
):
    data = yaml.safe_load(SIM_YAML.with_name(f"{rig}.yaml").read_text())
    profile = default_sim_profile(rig)
    assert isinstance(profile, RigProfile) and profile.is_sim
    assert (profile.name, profile.baud) == (data["name"], data["baud"])
    names = [name for name in ("pan", "tilt", "roll") if name in data]
    assert profile.joints == tuple((name, JointProfile(**data[name])) for name in names)
    assert profile.ids == tuple(data[name]["id"] for name in names)
    assert profile.source is not None and profile.source.endswith(f"{rig}.yaml")
    assert load_profile(save_profile(profile, tmp_path / "r.yaml")) == profile
    world = {joint.name: joint for joint in (*DEFAULT_JOINTS, ROLL_JOINT)}
    for name, joint in profile.joints:
        truth = world[name]
        assert joint.id == truth.servo_id
        for field in ("zero_tick", "direction", "stop_min_deg", "stop_max_deg"):
            assert getattr(joint, field) == getattr(truth, field), (name, field)
        # the hard limits lie inside the physical end stops, by the margin
        assert joint.stop_min_deg + END_STOP_MARGIN_DEG <= joint.min_deg
        assert joint.max_deg <= joint.stop_max_deg - END_STOP_MARGIN_DEG
    # the three-servo rig's pan and tilt are the two-servo rig's
    assert (profile.pan, profile.tilt) == (default_sim_profile().pan, default_sim_profile().tilt)
    with pytest.raises(ProfileError, match="the packaged rigs are sim, sim3"):
        default_sim_profile("sim4")
    # a joints list is the same profile, saved as a list; the named form is saved as it was read
    named = default_sim_profile(rig)
    data = named.to_dict()
    joints = [{"name": name} | data.pop(name) for name, _ in named.joints]
    listed = profile_from_dict(data | {"joints": joints}, "listed.yaml")
    assert listed == named and listed.listed and not named.listed
    assert [name for name, _ in listed.joints] == [name for name, _ in named.joints]
    saved = load_profile(save_profile(listed, tmp_path / "listed.yaml"))
    assert saved == named and saved.listed
    assert "joints" in yaml.safe_load((tmp_path / "listed.yaml").read_text())
    assert "joints" not in yaml.safe_load(save_profile(named, tmp_path / "n.yaml").read_text())
    for bad in (joints[::-1], joints[:1], "pan", [*joints[:2], {"name": "yaw", **joints[0]}]):
        with pytest.raises(ProfileError, match="joints must be a list of joints named pan, tilt"):
            profile_from_dict(data | {"joints": bad}, "listed.yaml")
    with pytest.raises(ProfileError, match="unknown keys pan"):
        profile_from_dict(data | {"joints": joints, "pan": joints[0]}, "listed.yaml")
    twin = [joints[0], joints[1] | {"id": joints[0]["id"]}, *joints[2:]]
    with pytest.raises(ProfileError, match="tilt.id must differ from pan.id"):
        profile_from_dict(data | {"joints": twin}, "listed.yaml")


def test_a_profile_is_frozen_saved_atomically_anywhere_and_refused_invalid(tmp_path, monkeypatch):
    profile = default_sim_profile()
    with pytest.raises(AttributeError):
        profile.baud = 1  # type: ignore[misc]
    with pytest.raises(AttributeError):
        profile.pan.direction = 1  # type: ignore[misc]
    path = tmp_path / "rig.yaml"
    out = save_profile(profile, path)
    again = load_profile(out)
    assert again == profile and again.source == str(out)
    # no temp files left behind by the atomic write; end stops saved
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rig.yaml"]
    assert "stop_max_deg: 75.0" in out.read_text()
    before = path.read_text()
    bad = profile.with_joints(pan=JointProfile(1, 2185, 3, -10.0, 10.0))
    with pytest.raises(ProfileError, match="pan.direction"):
        save_profile(bad, path)
    assert path.read_text() == before
    # profiles built in code meet the end-stop check too
    too_wide = profile.with_joints(tilt=JointProfile(2, 1890, -1, -55.0, 80.0, -60.0, 75.0))
    with pytest.raises(ProfileError, match="tilt.max_deg 80 is not 1 deg inside"):
        save_profile(too_wide, tmp_path / "wide.yaml")
    assert not (tmp_path / "wide.yaml").exists()
    monkeypatch.chdir(tmp_path)
    save_profile(profile, "here.yaml")
    assert load_profile(os.path.join(tmp_path, "here.yaml")) == profile


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
        (lambda d: d.update(model="ax12"), "model", "xl330-m077, xl330-m288, xc330-t181"),
        (lambda d: d.update(protocol=1.0), "protocol", "2.0"),
        (lambda d: d.update(port=""), "port", "non-empty"),
        (lambda d: d.pop("name"), "profile", "missing name"),
        (lambda d: d.update(prot=2.0), "profile", "unknown keys prot"),
        (lambda d: d.update(rest_direction=[0, 0, 0]), "rest_direction", "zero vector"),
        (lambda d: d.update(rest_direction=[1, 0]), "rest_direction", "3 numbers"),
        (lambda d: d["tilt"].update(max_deg=80.0), "tilt.max_deg", "end stop at 75"),
        (lambda d: d["tilt"].update(max_deg=74.5), "tilt.max_deg", "1 deg inside"),
        (lambda d: d["pan"].update(min_deg=-170.0), "pan.min_deg", "end stop at -120"),
        (lambda d: d["pan"].update(stop_max_deg=100.0), "pan.max_deg", "end stop at 100"),
        (lambda d: d["pan"].update(stop_min_deg="far"), "pan.stop_min_deg", "number"),
        (lambda d: d["pan"].update(stop_max_deg=200.0), "pan.stop_min_deg/stop_max_deg", "<= 180"),
        (lambda d: d["pan"].update(stop_min_deg=130.0), "pan.stop_min_deg/stop_max_deg", "<"),
        (lambda d: d.update(name="n" * 65), "name", "at most 64 characters, got 65"),
        (lambda d: d.update(name="sim\x1b[2J"), "name", "printable"),
        (lambda d: d.update(port="p" * 300), "port", "at most 256 characters"),
        (lambda d: d.update(baud=10**1000), "baud", "<an integer of about 1001 digits>"),
        (lambda d: d["pan"].update(max_deg=10**400), "pan.max_deg", "must be finite"),
        # the roll joint (sim3.yaml) is validated like the others
        (lambda d: d["roll"].update(direction=0), "roll.direction", "must be +1 or -1"),
        (lambda d: d["roll"].update(id=2), "roll.id", "must differ"),
        (lambda d: d["roll"].update(max_deg=104.5), "roll.max_deg", "104.5 is not 1 deg inside"),
        (lambda d: d["roll"].pop("zero_tick"), "roll", "is missing zero_tick"),
    ],
)
def test_invalid_fields_name_file_and_field(tmp_path, edit, field, fragment):
    data = yaml.safe_load((SIM3_YAML if field.startswith("roll") else SIM_YAML).read_text())
    edit(data)
    path = write(tmp_path, data)
    with pytest.raises(ConfigError) as info:
        load_rig_profile(path)
    message = str(info.value)
    assert message.startswith(f"{path}: {field} ")
    assert fragment in message


def test_the_brief_example_message_rest_direction_joint_limits_and_default_end_stops(
    tmp_path, sim_data
):
    data = copy.deepcopy(sim_data)
    data["pan"]["direction"] = 2
    path = write(tmp_path, data)
    with pytest.raises(ConfigError, match=r"x\.yaml: pan\.direction must be \+1 or -1, got 2$"):
        load_rig_profile(path)
    # rest_direction is optional and normalised
    data = copy.deepcopy(sim_data)
    del data["rest_direction"]
    assert profile_from_dict(data).rest_direction == (1.0, 0.0, 0.0)
    data["rest_direction"] = [0.0, 3.0, 4.0]
    assert profile_from_dict(data).rest_direction == pytest.approx((0.0, 0.6, 0.8))
    joint = JointProfile(id=1, zero_tick=2048, direction=-1, min_deg=-90.0, max_deg=45.0)
    assert (joint.min_rad, joint.max_rad) == pytest.approx((-math.pi / 2, math.pi / 4))
    # direction -1: +45 deg lies 512 ticks below zero, -90 deg 1024 above
    assert joint_tick_limits(joint) == (2048 - 512, 2048 + 1024)
    # unstated end stops default to a quarter turn
    for name in ("pan", "tilt"):
        del sim_data[name]["stop_min_deg"], sim_data[name]["stop_max_deg"]
    sim_data["pan"].update(min_deg=-80.0, max_deg=80.0)
    profile = load_rig_profile(write(tmp_path, sim_data))
    stops = (profile.pan.stop_min_deg, profile.pan.stop_max_deg)
    assert stops == (-DEFAULT_END_STOP_DEG, DEFAULT_END_STOP_DEG)
    sim_data["pan"].update(min_deg=-115.0, max_deg=115.0)
    path = write(tmp_path, sim_data, "wide.yaml")
    with pytest.raises(ConfigError) as err:
        load_rig_profile(path)
    assert str(err.value) == (
        f"{path}: pan.min_deg -115 is not 1 deg inside the end stop at -90: narrow pan.min_deg, "
        "or write down where the end stop really is (pan.stop_min_deg; unstated, it is taken "
        "to be -90)"
    )


@pytest.mark.parametrize(
    ("text", "error", "match"),
    [
        ("name: [unclosed\n", FileFormatError, "x.yaml: not valid YAML"),
        (None, ConfigError, "no such rig profile.*limbctl calibrate"),
        ("- 1\n- 2\n", ConfigError, "x.yaml: top level must be a mapping"),
    ],
)
def test_unreadable_missing_or_non_mapping_files_are_named(tmp_path, text, error, match):
    path = tmp_path / "x.yaml"
    if text is not None:
        path.write_text(text)
    with pytest.raises(error, match=match):
        load_rig_profile(path)


def test_duplicate_keys_many_unknown_keys_and_huge_values_are_refused_on_one_bounded_line(
    tmp_path, sim_data
):
    path = tmp_path / "dup.yaml"
    text = SIM_YAML.read_text().replace("  max_deg: 70.0\n", "  max_deg: 70.0\n  max_deg: 170.0\n")
    path.write_text(text)
    line = text.splitlines().index("  max_deg: 170.0") + 1
    with pytest.raises(FileFormatError) as err:
        load_rig_profile(path)
    assert str(err.value) == (
        f"{path}: line {line}: key 'max_deg' appears twice (also on line {line - 1}); keep "
        "one, a later value would silently win"
    )
    # an alias bomb: tests/safety/test_files.py (the CLI) and tests/calib/test_yaml_guard.py
    with pytest.raises(ConfigError, match="and 995 more") as err:
        load_rig_profile(write(tmp_path, sim_data | {f"extra{i}": i for i in range(1000)}))
    assert len(str(err.value)) < 300
    # values too long, wide or deep for the message are quoted boundedly
    deep = [[[[["deep"]]]] for _ in range(40)]
    for value, field in itertools.product(
        (["x" * 1000] * 10, {"k" * 1000: "v"}, "y" * 1000, deep), ("name", "baud", "protocol")
    ):
        with pytest.raises(ConfigError) as err:
            load_rig_profile(write(tmp_path, sim_data | {field: value}))
        assert len(str(err.value)) < 300 and "\n" not in str(err.value), str(err.value)


def pan_tilt(pan, tilt) -> Calibration:
    """The calibration of pan and tilt, each given as JointCalibration's arguments."""
    return Calibration((("pan", JointCalibration(*pan)), ("tilt", JointCalibration(*tilt))))


def test_calibrations_with_and_without_roll_round_trip_name_differences_and_bad_fields(
    sim_data,
):
    profile = default_sim_profile()
    calibration = profile.calibration
    assert calibration == pan_tilt((2185, 1, -115.0, 115.0), (1890, -1, -55.0, 70.0))
    assert calibration_from_dict(calibration.to_dict()) == calibration
    assert calibration.differences(calibration) == ()
    moved = pan_tilt((2385, 1, -115.0, 115.0), (1890, 1, -55.0, 60.0))
    assert calibration.differences(moved) == (
        "pan.zero_tick 2185 vs 2385",
        "tilt.direction -1 vs 1",
        "tilt.max_deg 70 vs 60",
    )
    # two servos carry no roll
    assert profile.roll is None and not calibration.twists
    assert "roll" not in profile.to_dict()
    assert set(calibration.to_dict()) == {"pan", "tilt"}
    assert profile.to_dict() == profile_from_dict(sim_data).to_dict()
    three = default_sim_profile("sim3").calibration
    assert three.twists
    assert calibration_from_dict(three.to_dict()) == three
    assert three.differences(calibration) == ("roll present vs absent",)
    assert calibration.differences(three) == ("roll absent vs present",)
    changed = three.to_dict()
    changed["roll"]["zero_tick"] = 2000
    assert three.differences(calibration_from_dict(changed)) == ("roll.zero_tick 1960 vs 2000",)
    data = calibration.to_dict()
    data["tilt"]["direction"] = 0
    with pytest.raises(ProfileError, match=r"^model.npz: calibration.tilt.direction must be \+1"):
        calibration_from_dict(data, "model.npz")
    with pytest.raises(ProfileError, match="calibration must be a mapping"):
        calibration_from_dict(["x"] * 10_000, "model.npz")
