"""Promise 4: damaged, wrong-version or hand-edited model, dataset and rig files, and models for
another rig, are refused naming the file and the problem (the CLI before it touches a servo)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
import zipfile

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from calib.profile import RigProfile
from limbctl.envelope import Cone, load_model
from limbctl.envelope.base import _digest
from limbctl.errors import ConfigError, FileFormatError
from limbctl.jobs import gate_for
from limbctl.servo.profiles import load_rig_profile
from limbctl.teach.dataset import DatasetWriter, load_dataset
from tests.safety.support import PROFILE, bean_model

PROBES = np.array(
    [[1.0, 0.0, 0.0, 0.0], [0.9, 0.1, 0.3, -0.3], [0.5, 0.0, 0.7, 0.5], [0.2, 0.0, 0.0, 0.98]]
)
PROBES /= np.linalg.norm(PROBES, axis=1, keepdims=True)


# ---- damage -----------------------------------------------------------------------------------
@st.composite
def damaged(draw, b: bytes) -> bytes:
    """``b`` truncated, a byte flipped, bytes inserted or bytes deleted."""
    kind = draw(st.sampled_from(["truncate", "flip", "insert", "delete"]))
    at = draw(st.integers(0, max(0, len(b) - 1)))
    if kind == "truncate":
        return b[:at]
    if kind == "flip":
        mask = draw(st.integers(1, 255))
        return b[:at] + bytes([b[at] ^ mask]) + b[at + 1 :]
    if kind == "insert":
        extra = draw(st.binary(min_size=1, max_size=8))
        return b[:at] + extra + b[at:]
    count = draw(st.integers(1, 16))
    return b[:at] + b[at + count :]


SETTINGS = settings(
    max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)


# ---- model files ------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def model_files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("models")
    cone = Cone(np.radians(35.0))
    rigid = bean_model()
    trained = {"rig": "sim", "calibration": PROFILE.calibration.to_dict()}
    return {
        "cone": (cone, cone.save(folder / "cone.npz", metadata=trained)),
        "rigidmap": (rigid, rigid.save(folder / "rigid.npz", metadata=trained)),
    }


@pytest.mark.parametrize("kind", ["cone", "rigidmap"])
@SETTINGS
@given(data=st.data())
def test_damaged_model_is_refused_or_unchanged(tmp_path, model_files, kind, data):
    model, path = model_files[kind]
    bad = tmp_path / f"damaged-{kind}.npz"
    bad.write_bytes(data.draw(damaged(path.read_bytes())))
    try:
        loaded = load_model(bad)
    except FileFormatError as exc:
        assert str(bad) in str(exc) and exc.problem, str(exc)
        return
    # the damage missed everything the model is made of (zip padding, timestamps): the
    # checksum held, so it must answer exactly as the original
    np.testing.assert_array_equal(loaded.correct(PROBES), model.correct(PROBES))
    np.testing.assert_array_equal(loaded.contains(PROBES), model.contains(PROBES))


def _rewrite_header(src, dst, edit, reseal: bool) -> None:
    with np.load(src) as z:
        arrays = {n: z[n] for n in z.files}
    header = json.loads(arrays.pop("__header__").tobytes())
    edit(header)
    if reseal:
        header["sha256"] = _digest(header, arrays)
    raw = np.frombuffer(json.dumps(header).encode(), dtype=np.uint8)
    with open(dst, "wb") as fh:
        np.savez(fh, __header__=raw, **arrays)


def test_wrong_version_hand_edits_and_foreign_files_are_named(tmp_path, model_files):
    _, path = model_files["cone"]
    newer = tmp_path / "newer.npz"
    _rewrite_header(path, newer, lambda h: h.update(format_version=2), reseal=True)
    with pytest.raises(FileFormatError, match="version 2 is not supported") as err:
        load_model(newer)
    assert str(newer) in str(err.value)

    edited = tmp_path / "edited.npz"  # somebody widened the cone by hand
    _rewrite_header(path, edited, lambda h: h["params"].update(half_angle=1.5), reseal=False)
    with pytest.raises(FileFormatError, match="checksum mismatch") as err:
        load_model(edited)
    assert str(edited) in str(err.value)

    arrays_only = tmp_path / "not-ours.npz"
    np.savez(arrays_only, weights=np.zeros((3, 4)))
    with pytest.raises(FileFormatError, match="no header"):
        load_model(arrays_only)
    with pytest.raises(FileFormatError, match="no such model file"):
        load_model(tmp_path / "missing.npz")
    empty = tmp_path / "empty.npz"
    empty.write_bytes(b"")
    with pytest.raises(FileFormatError, match="truncated or corrupt"):
        load_model(empty)
    other = tmp_path / "photos.npz"  # a zip of something else
    with zipfile.ZipFile(other, "w") as z:
        z.writestr("cat.jpg", b"\xff\xd8\xff" + b"0" * 100)
    with pytest.raises(FileFormatError) as err:
        load_model(other)
    assert str(other) in str(err.value)


# ---- dataset files ------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def dataset_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("data") / "teach.limb"
    rng = np.random.default_rng(0)
    with DatasetWriter(path, rig="sim", min_free_bytes=1024) as out:
        for i, (pan, tilt) in enumerate(rng.uniform(-0.8, 0.8, (60, 2))):
            out.append(0.01 * i, pan, tilt)
    return path, load_dataset(path)


@SETTINGS
@given(data=st.data())
def test_damaged_dataset_is_refused_or_a_clean_prefix(tmp_path, dataset_file, data):
    path, original = dataset_file
    blob = path.read_bytes()
    bad = tmp_path / "damaged.limb"
    bad.write_bytes(hurt := data.draw(damaged(blob)))
    try:
        loaded = load_dataset(bad)
    except FileFormatError as exc:
        assert str(bad) in str(exc) and "line" in exc.problem, str(exc)
        return
    # what loads is exactly a prefix of what was written (a torn tail is dropped and said)
    n = len(loaded)
    np.testing.assert_array_equal(loaded.quaternions, original.quaternions[:n])
    np.testing.assert_array_equal(loaded.t, original.t[:n])
    if n < len(original) and not loaded.dropped_tail:
        # the one silent case: cut exactly after a record, which is what a crash between two
        # records leaves too (an append-only file has no footer to tell the two apart)
        assert hurt == blob[: len(hurt)] and hurt.endswith(b"\n"), "samples went missing"


# ---- rig profiles -------------------------------------------------------------------------------
SIM_YAML = yaml.safe_dump(PROFILE.to_dict(), sort_keys=False).encode()


@SETTINGS
@given(data=st.data())
def test_damaged_rig_profile_is_refused_naming_the_file_or_still_valid(tmp_path, data):
    bad = tmp_path / "rig.yaml"
    bad.write_bytes(data.draw(damaged(SIM_YAML)))
    try:
        profile = load_rig_profile(bad)
    except (ConfigError, FileFormatError) as exc:
        assert str(bad) in str(exc), str(exc)
        return
    # a change that still reads as a valid profile (a digit of a limit, say) passed every
    # check: it is a complete, validated profile, never a half-read one
    assert isinstance(profile, RigProfile)
    assert profile.pan.min_deg < profile.pan.max_deg and profile.tilt.min_deg < profile.tilt.max_deg


# ---- the CLI refuses bad files before touching a servo -------------------------------------------
def limbctl(*args, cwd, stdout=subprocess.PIPE):
    """``limbctl ARGS`` in a new process: its stderr, and its stdout unless sent to ``stdout``."""
    return subprocess.run(
        [sys.executable, "-m", "limbctl.cli", *map(str, args)],
        stdout=stdout,
        stderr=subprocess.PIPE,
        text=True,
        timeout=120,
        cwd=cwd,
    )


def test_cli_refuses_bad_files_and_another_calibrations_model_naming_them(
    tmp_path, model_files, dataset_file
):
    _, model = model_files["cone"]
    data, _ = dataset_file
    torn = tmp_path / "torn.npz"
    torn.write_bytes(model.read_bytes()[:200])
    foreign = Cone(np.radians(35.0)).save(tmp_path / "foreign.npz", metadata={"rig": "bench-2"})
    bad_rig = tmp_path / "rig.yaml"
    bad_rig.write_text(SIM_YAML.decode().replace("direction: -1", "direction: 2"))
    edited = tmp_path / "edited.limb"
    lines = data.read_text().splitlines(keepends=True)
    lines[5] = lines[5].replace("0.0", "0.5", 1) if "0.0" in lines[5] else "9" + lines[5]
    edited.write_text("".join(lines))
    # a model trained under the sim rig's calibration, and the same rig name with the pan zero
    # tick off by 200 (17.6 deg); an older model that recorded no calibration
    recording = tmp_path / "teach.limb"
    rng = np.random.default_rng(1)
    with DatasetWriter(
        recording, rig="sim", calibration=PROFILE.calibration, min_free_bytes=1024
    ) as out:
        for i, (pan, tilt) in enumerate(rng.uniform(-0.4, 0.4, (60, 2))):
            out.append(0.01 * i, pan, tilt)
    calibrated = tmp_path / "model.npz"
    trained = limbctl("train", recording, "--out", calibrated, "--kind", "cone", cwd=tmp_path)
    assert trained.returncode == 0, trained.stderr
    assert "NOT RECORDED" not in trained.stderr
    assert gate_for(calibrated, PROFILE, 200.0, 120.0) is not None  # its own rig: accepted
    shifted = tmp_path / "shifted.yaml"
    shifted.write_text(SIM_YAML.decode().replace("zero_tick: 2185", "zero_tick: 2385"))
    older = Cone(np.radians(35.0)).save(tmp_path / "older.npz", metadata={"rig": "sim"})
    moved = "(trained vs now: pan.zero_tick 2185 vs 2385)"
    uncalibrated = "does not record the calibration it was trained under"
    cases = [
        (["teleop", "--rig", shifted, "--model", calibrated], calibrated, moved),
        (["teleop", "--model", older], older, uncalibrated),
        (["teleop", "--model", torn], torn, "truncated or corrupt"),
        (["teleop", "--model", foreign], foreign, "trained for rig 'bench-2'"),
        (["teleop", "--model", model, "--rig", bad_rig], bad_rig, "direction must be +1 or -1"),
        (["train", edited, "--out", tmp_path / "m.npz"], edited, "line 6: checksum mismatch"),
        (["info", torn], torn, "truncated or corrupt"),
    ]
    for args, named, problem in cases:
        done = limbctl(*args, cwd=tmp_path)
        assert done.returncode == 2, (args, done.stderr)
        assert str(named) in done.stderr and problem in done.stderr, done.stderr
        assert "Traceback" not in done.stderr
        assert "simulator" not in done.stderr  # refused before any servo was touched
    assert not (tmp_path / "m.npz").exists()


# ---- rig profiles that cannot hurt, through the CLI ---------------------------------------------
#: Longest a refused profile may take through the whole CLI (python start and imports included,
#: on a loaded 2-core box); the refusal itself is under a second (tests/calib/test_yaml_guard.py).
CLI_REFUSAL_S = 10.0


def _alias_bomb_in_name() -> str:
    """The sim profile whose name is 9 levels of nested aliases (9**9 strings expanded)."""
    levels = ["  - &a0 [x, x, x, x, x, x, x, x, x]"]
    levels += [f"  - &a{i} [" + ", ".join([f"*a{i - 1}"] * 9) + "]" for i in range(1, 9)]
    return SIM_YAML.decode().replace("name: sim\n", "name:\n" + "\n".join(levels) + "\n")


@pytest.mark.parametrize(
    ("case", "text", "problem"),
    [
        ("alias bomb", _alias_bomb_in_name(), "anchors and aliases (&name, *name) are not allowed"),
        (
            "duplicate key",
            SIM_YAML.decode().replace("  max_deg: 70.0\n", "  max_deg: 70.0\n  max_deg: 170.0\n"),
            "key 'max_deg' appears twice",
        ),
        (
            "oversized value",
            SIM_YAML.decode().replace("baud: 4000000", "baud: " + "9" * 50_000),
            "a value of 50000 characters",
        ),
        ("oversized file", SIM_YAML.decode() + "#" * 70_000 + "\n", "larger than 64 KiB"),
        (
            "limit past the end stop",
            SIM_YAML.decode().replace("  max_deg: 70.0\n", "  max_deg: 80.0\n"),
            "tilt.max_deg 80 is not 1 deg inside the end stop at 75",
        ),
    ],
)
def test_cli_refuses_a_harmful_profile_fast_on_one_line(tmp_path, model_files, case, text, problem):
    _, model = model_files["cone"]
    rig = tmp_path / "rig.yaml"
    rig.write_text(text)
    started = time.perf_counter()
    done = limbctl("teleop", "--rig", rig, "--model", model, cwd=tmp_path)
    elapsed = time.perf_counter() - started
    assert done.returncode == 2, (case, done.stderr[:500])
    assert elapsed < CLI_REFUSAL_S, (case, elapsed)
    lines = done.stderr.splitlines()
    assert len(lines) == 1 and len(lines[0]) < 400, (case, done.stderr[:500])
    assert str(rig) in lines[0] and problem in lines[0], (case, lines[0])
    assert "simulator" not in done.stderr  # refused before a servo (or its EEPROM) was touched


# ---- info names a damaged file's real problem ---------------------------------------------------
def test_info_names_a_damaged_datasets_problem_and_survives_a_closed_pipe(
    tmp_path, dataset_file, model_files
):
    path, _ = dataset_file
    lines = path.read_bytes().split(b"\n")
    lines[10] = lines[10].replace(b"0.", b"1.", 1)  # an edited record, line 11
    damaged = tmp_path / "damaged.limb"
    damaged.write_bytes(b"\n".join(lines))
    done = limbctl("info", damaged, cwd=tmp_path)
    assert done.returncode == 2, done.stderr
    assert f"{damaged}: line 11: checksum mismatch" in done.stderr, done.stderr
    assert "pickle" not in done.stderr and "Traceback" not in done.stderr

    intact = limbctl("info", path, cwd=tmp_path)
    assert intact.returncode == 0, intact.stderr
    assert "dataset of 60 samples from rig 'sim'" in intact.stdout
    assert "calibration: not recorded" in intact.stdout

    headless = tmp_path / "headless.limb"  # the header itself is gone
    headless.write_bytes(b"\n".join(lines[1:]))
    done = limbctl("info", headless, cwd=tmp_path)
    assert done.returncode == 2
    assert "neither a limbctl model nor a dataset (as a model: " in done.stderr, done.stderr
    assert "as a dataset: line 1: not a limbctl orientation dataset" in done.stderr
    assert "pickle" not in done.stderr
    # info into a closed pipe prints no traceback
    _, model = model_files["rigidmap"]
    read_end, write_end = os.pipe()
    os.close(read_end)  # the reader is gone before limbctl writes a byte, as after `| head`
    try:
        done = limbctl("info", model, cwd=tmp_path, stdout=write_end)
    finally:
        os.close(write_end)
    assert done.returncode == 1, done.stderr
    assert done.stderr == "", done.stderr  # no traceback, no "Exception ignored"
