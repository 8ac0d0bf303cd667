import json
import os
import re
import selectors
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

from calib.profile import default_sim_profile
from limbctl.errors import ConfigError, FileFormatError, InvalidInputError
from limbctl.geometry import gimbal
from limbctl.teach.dataset import (
    COLUMNS,
    FORMAT_NAME,
    DatasetWriter,
    _seal,
    check_writable,
    is_dataset_file,
    load_dataset,
)

SMALL = 1024  # min_free_bytes for tests: the check runs, the tmp disk is never that full


def record(path, n=20, rig="sim", meta=None):
    rng = np.random.default_rng(1)
    pan = rng.uniform(-1.5, 1.5, n)
    tilt = rng.uniform(-0.9, 1.2, n)
    with DatasetWriter(path, rig=rig, meta=meta, min_free_bytes=SMALL) as out:
        for i in range(n):
            out.append(0.01 * i, pan[i], tilt[i])
    return pan, tilt


def test_round_trip_is_exact_visible_before_close_a_torn_tail_dropped_a_dataset_recognised(
    tmp_path,
):
    path = tmp_path / "a.limb"
    pan, tilt = record(path, meta={"rate_hz": 100})
    assert is_dataset_file(path)
    blob = bytearray(path.read_bytes())
    blob[-30] ^= 0x55  # damage far from the header: still a dataset, with a problem to name
    (tmp_path / "damaged.limb").write_bytes(bytes(blob))
    assert is_dataset_file(tmp_path / "damaged.limb")
    other = tmp_path / "model.npz"
    other.write_bytes(b"PK\x03\x04" + bytes(100))
    assert not is_dataset_file(other)
    assert not is_dataset_file(tmp_path / "missing.limb") and not is_dataset_file(tmp_path)
    torn = tmp_path / "torn.limb"
    torn.write_bytes(path.read_bytes() + b"0.1,3.0,4.0,0.99")
    data = load_dataset(torn)
    assert len(data) == 20, "a torn last line was not dropped"
    assert data.dropped_tail is not None and "line 22" in data.dropped_tail
    data = load_dataset(path)
    assert len(data) == 20 and data.dropped_tail is None
    assert data.header.rig == "sim" and data.header.columns == COLUMNS
    assert data.header.meta == {"rate_hz": 100}
    np.testing.assert_array_equal(data.t, 0.01 * np.arange(20))
    np.testing.assert_allclose(data.pan, pan, rtol=0, atol=1e-15)
    np.testing.assert_allclose(data.tilt, tilt, rtol=0, atol=1e-15)
    assert data.quaternions.shape == (20, 4)
    np.testing.assert_array_equal(data.quaternions, gimbal.pan_tilt_to_quat(pan, tilt))
    # records are visible to a second reader before close: they reached the OS
    live = DatasetWriter(tmp_path / "live.limb", rig="sim", min_free_bytes=SMALL).open()
    for i in range(5):
        live.append(0.01 * i, 0.0, 0.0)
    assert len(load_dataset(tmp_path / "live.limb")) == 5, "records not visible before close"
    live.close()
    live.close()  # a second close is harmless; an append after it is refused
    with pytest.raises(RuntimeError, match="not open"):
        live.append(0.0, 0.0, 0.0)


def test_a_quaternion_and_the_calibration_are_stored_exactly_and_old_files_have_none(tmp_path):
    path = tmp_path / "q.limb"
    q = np.array([0.0, 0.6, 0.0, -0.8])
    calibration = default_sim_profile().calibration
    with DatasetWriter(path, rig="sim", calibration=calibration, min_free_bytes=SMALL) as out:
        out.append(0.0, 0.1, 0.2, q)
        with pytest.raises(InvalidInputError, match="sample 1 quaternion"):
            out.append(0.01, 0.1, 0.2, [1.0, 1.0, 0.0, 0.0])
        with pytest.raises(InvalidInputError, match="non-finite"):
            out.append(float("nan"), 0.1, 0.2)
    data = load_dataset(path)
    assert len(data) == 1 and data.header.calibration == calibration
    # stored canonical (w >= 0; here w == 0 so the sign is kept) and exact
    np.testing.assert_array_equal(data.quaternions[0], q)
    first = path.read_bytes().split(b"\n")[0]
    assert b'"calibration": {"pan": {"zero_tick": 2185, "direction": 1' in first
    older = tmp_path / "older.limb"  # written before datasets recorded a calibration
    older.write_bytes(header_line())
    assert load_dataset(older).header.calibration is None


def edit_pan(lines):
    """A hand edit of line 5's pan_deg, its old checksum kept."""
    payload, crc = lines[4].split(b"|")
    fields = payload.split(b",")
    fields[1] = b"10.0"
    lines[4] = b",".join(fields) + b"|" + crc


def corrupt_byte(lines):
    """A non-UTF-8 byte in line 4."""
    lines[3] = lines[3][:3] + b"\xff" + lines[3][4:]


def header_line(**changes):
    header = {"format": FORMAT_NAME, "version": 1, "rig": "sim", "created": "now"}
    header |= {"columns": list(COLUMNS), "meta": {}, **changes}
    return _seal(json.dumps(header), 0)[0]


#: A header's calibration of one axis (zero tick 1 of 0..4095).
AXIS = {"zero_tick": 1, "direction": 1, "min_deg": -1, "max_deg": 1}


def non_unit_quaternion_file() -> bytes:
    """A header and one record of a non-unit quaternion, its checksum valid."""
    head = header_line()
    crc = int(head.rstrip(b"\n").split(b"|")[1], 16)
    return head + _seal("0.0,1.0,2.0,1.0,1.0,0.0,0.0", crc)[0]


@pytest.mark.parametrize(
    ("content", "problem"),
    [
        (edit_pan, "line 5: checksum mismatch"),
        (lambda lines: lines.pop(6), "line 7: checksum mismatch"),  # the chain is broken
        (corrupt_byte, "line 4: not UTF-8"),
        (lambda lines: lines.__setitem__(2, lines[2].split(b"|")[0]), "line 3: no checksum field"),
        (header_line(version=2), "line 1: dataset format version 2.*reads version 1"),
        (header_line(columns=["t", "q"]), "line 1: columns"),
        (b"t,pan,tilt\n0,1,2\n", "not a limbctl orientation dataset"),
        (b'{"format": "other"}|00000000\n', "not a limbctl orientation dataset"),
        (b"\x89PNG\r\n\x1a\n\x00\x00", "not a limbctl orientation dataset"),
        (b"", "no complete header"),
        (header_line()[:20], "no complete header"),
        (non_unit_quaternion_file(), "line 2: quaternion is not unit length"),
        (header_line(calibration={"pan": {}}), "line 1: calibration is missing tilt"),
        (
            header_line(calibration={"pan": {**AXIS, "zero_tick": 9999}, "tilt": AXIS}),
            re.escape("line 1: calibration.pan.zero_tick must be in 0..4095, got 9999"),
        ),
        (header_line(calibration="x" * 100_000), "line 1: calibration must be a mapping"),
    ],
    ids="edited deleted binary no-checksum version columns csv other png empty torn non-unit "
    "no-tilt zero-tick not-a-map".split(),
)
def test_a_damaged_record_another_version_a_foreign_or_torn_file_or_a_bad_header_is_refused(
    tmp_path, content, problem
):
    path = tmp_path / "refused.limb"
    if callable(content):  # a damage to the lines of a recording of 20 samples
        record(path)
        lines = path.read_bytes().split(b"\n")[:-1]
        content(lines)
        content = b"\n".join(lines) + b"\n"
    path.write_bytes(content)
    with pytest.raises(FileFormatError, match=problem) as err:
        load_dataset(path)
    assert err.value.path == str(path)
    assert len(str(err.value)) < 400, "a long value is echoed"  # a 100,000-character one


def test_preflight_checks(tmp_path):
    existing = tmp_path / "exists.limb"
    existing.write_text("x")
    with pytest.raises(ConfigError, match="already exists"):
        DatasetWriter(existing, rig="sim", min_free_bytes=SMALL)
    with pytest.raises(ConfigError, match="does not exist"):
        check_writable(tmp_path / "no" / "such" / "dir.limb", SMALL)
    with pytest.raises(ConfigError, match="MB free on that disk"):
        check_writable(tmp_path / "big.limb", min_free_bytes=1 << 62)
    assert not (tmp_path / "big.limb").exists()


CHILD = textwrap.dedent(
    """
    import sys, time
    from limbctl.teach.dataset import DatasetWriter
    period = 0.01
    with DatasetWriter(sys.argv[1], rig="sim", min_free_bytes=1024) as out:
        start = time.monotonic()
        for i in range(100000):
            # pace at 100 Hz against a deadline (the sample clock, not a test sync)
            delay = start + i * period - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            t = time.monotonic() - start
            out.append(t, 0.001 * i, -0.0005 * i)
            print(repr(t), flush=True)
    """
)


def test_kill_9_loses_at_most_half_a_second(tmp_path):
    path = tmp_path / "killed.limb"
    proc = subprocess.Popen(
        [sys.executable, "-c", CHILD, str(path)], stdout=subprocess.PIPE, text=True
    )
    reported: list[float] = []
    selector = selectors.DefaultSelector()
    selector.register(proc.stdout, selectors.EVENT_READ)
    deadline = time.monotonic() + 30.0
    try:
        # wait (on the child's own reports) until it has recorded for a second
        while not reported or reported[-1] < 1.0:
            remaining = deadline - time.monotonic()
            assert remaining > 0, "child did not record for 1 s within 30 s"
            if selector.select(timeout=remaining):
                line = proc.stdout.readline()
                assert line, f"child exited early with {proc.poll()}"
                reported.append(float(line))
        os.kill(proc.pid, signal.SIGKILL)
        assert proc.wait(timeout=10) == -signal.SIGKILL
        reported.extend(float(line) for line in proc.stdout.read().split())
    finally:
        selector.close()
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        proc.stdout.close()
    data = load_dataset(path)
    lost_s = reported[-1] - data.t[-1]
    assert lost_s <= 0.5, f"lost {lost_s:.3f} s of samples"
    # every sample the child reported as appended is in the file, in order
    np.testing.assert_array_equal(data.t[: len(reported)], reported)
    assert len(data) >= len(reported) >= 100
