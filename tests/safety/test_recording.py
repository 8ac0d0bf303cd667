"""Promise 3: recordings through the real ``limbctl record`` survive signals, an unwritable
path, a full disk and a lost servo (power cut, preflight: tests/teach/test_dataset.py)."""

from __future__ import annotations

import resource
import signal
import subprocess
import sys

import numpy as np
import pytest

from limbctl.errors import FileFormatError
from limbctl.teach.dataset import load_dataset
from tests.safety.support import wait_for

RECORD_TIMEOUT_S = 120.0


def start_record(out, *extra, preexec_fn=None) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "limbctl.cli", "record", "--out", str(out), *map(str, extra)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=preexec_fn,
    )


def wait_for_samples(proc, path, count: int):
    """Wait (on the file itself) until ``count`` samples are on disk; return what loads."""

    def enough():
        assert proc.poll() is None, f"recorder exited early: {proc.stderr.read()}"
        try:
            return len(load_dataset(path)) >= count
        except FileFormatError:  # not even a header yet
            return False

    wait_for(enough, RECORD_TIMEOUT_S, f"{count} samples in {path}")
    return load_dataset(path)


def finish(proc) -> tuple[int, str]:
    try:
        _, err = proc.communicate(timeout=RECORD_TIMEOUT_S)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    return proc.returncode, err


def assert_prefix(before, after) -> None:
    """Everything seen on disk before is still there, unchanged, at the start."""
    n = len(before)
    assert len(after) >= n
    np.testing.assert_array_equal(after.t[:n], before.t)
    np.testing.assert_array_equal(after.quaternions[:n], before.quaternions)


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM, signal.SIGKILL])
def test_a_signal_loses_no_sample_written_and_kill_9_leaves_a_file_that_loads(tmp_path, signum):
    out = tmp_path / "teach.limb"
    proc = start_record(out, "--duration", 600)
    try:
        before = wait_for_samples(proc, out, 100)
        proc.send_signal(signum)
    finally:
        code, err = finish(proc)
    data = load_dataset(out)  # after SIGKILL, a torn last line, if any, is dropped and reported
    assert_prefix(before, data)
    if signum == signal.SIGKILL:
        assert code == -signal.SIGKILL
        return
    assert code == 0, err
    assert data.dropped_tail is None, data.dropped_tail
    assert f"wrote {len(data)} samples to {out}" in err, err
    assert "ended by           stopped" in err


@pytest.mark.parametrize(
    "where, problem",
    [
        ("missing/teach.limb", "does not exist"),
        ("a-file/teach.limb", "is not a directory"),
        ("exists.limb", "already exists"),
    ],
)
def test_unwritable_path_is_refused_before_recording(tmp_path, where, problem):
    (tmp_path / "a-file").write_text("not a folder")
    (tmp_path / "exists.limb").write_text("an earlier recording")
    out = tmp_path / where
    code, err = finish(start_record(out, "--duration", 5))
    assert code == 2, err
    assert str(out) in err and problem in err, err
    assert "simulator" not in err and "Traceback" not in err
    assert (tmp_path / "exists.limb").read_text() == "an earlier recording"


def _limit_file_size(limit: int):
    def apply() -> None:
        # a full disk, in miniature: writes past `limit` bytes fail with EFBIG
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    return apply


def test_disk_full_mid_recording_is_reported_and_keeps_what_was_written(tmp_path):
    out = tmp_path / "teach.limb"
    limit = 40_000
    code, err = finish(start_record(out, "--duration", 600, preexec_fn=_limit_file_size(limit)))
    assert code == 2, err
    assert str(out) in err and "Traceback" not in err, err
    assert "File too large" in err or "No space" in err, err
    data = load_dataset(out)
    assert len(data) > 100
    assert out.stat().st_size <= limit


def test_a_servo_lost_mid_recording_exits_3_and_keeps_the_samples(tmp_path, sim):
    out = tmp_path / "teach.limb"
    proc = start_record(out, "--port", sim.port, "--duration", 600)
    try:
        before = wait_for_samples(proc, out, 50)
        sim.vanish(2, 600.0)  # the tilt servo drops off the bus for good
    finally:
        code, err = finish(proc)
    assert code == 3, err
    assert "ended by           bus failure: 50 reads in a row failed" in err
    assert "FAULT: the recording ended early" in err and "servo 2" in err
    data = load_dataset(out)
    assert f"wrote {len(data)} samples to {out}" in err
    assert_prefix(before, data)
