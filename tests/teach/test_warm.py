"""limbctl.teach.warm: after a warm-up, the first train and teleop start compile no kernel."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from limbctl.geometry import jit
from limbctl.region.correct_kernels import SINGLE_ROWS
from limbctl.teach.warm import LARGE_BATCH, warming_in_background
from tests.test_first_run import ROOT, compiled_by, teaching


def test_the_larger_batch_takes_the_batch_kernel():
    # served row by row up to SINGLE_ROWS; one more takes the kernel a start outside asks
    assert LARGE_BATCH == SINGLE_ROWS + 1


def test_after_a_warm_up_train_and_teleop_compile_no_kernel_and_say_nothing(tmp_path):
    cache = tmp_path / "numba-cache"
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache), "PYTHONPATH": str(ROOT)}
    subprocess.run([sys.executable, "-m", "limbctl.teach.warm"], env=env, check=True, cwd=tmp_path)
    markers = sorted(p.name for p in cache.rglob("prepared-*"))
    assert markers == [f"prepared-{stage}" for stage in sorted(jit.STAGES)]
    data = teaching(tmp_path / "teach.limb")
    model = tmp_path / "model.npz"
    ours, _ = compiled_by(["train", str(data), "--out", str(model)], tmp_path, prepared=True)
    assert ours == []
    commands = '{"pan": 20, "tilt": 10}\n{"pan": 120, "tilt": 80}\n'
    ours, _ = compiled_by(
        ["teleop", "--model", str(model), "--source", "stdin"],
        tmp_path,
        stdin=commands,
        prepared=True,
    )
    assert ours == []


def test_no_warm_up_starts_when_everything_is_prepared_or_nothing_can_be_cached(monkeypatch):
    monkeypatch.setattr(jit, "prepared", lambda stage: True)
    with warming_in_background() as process:
        assert process is None
    monkeypatch.setattr(jit, "prepared", lambda stage: False)
    monkeypatch.setattr(jit, "cache_dir", lambda: None)
    with warming_in_background() as process:
        assert process is None


def test_a_second_warm_up_stands_aside_while_one_holds_the_lock(tmp_path, monkeypatch):
    monkeypatch.setattr(jit, "cache_dir", lambda: Path(tmp_path))
    holder = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import sys, fcntl\n"
            "lock = open(sys.argv[1], 'a+b'); fcntl.flock(lock, fcntl.LOCK_EX)\n"
            "print('locked', flush=True); sys.stdin.readline()\n",
            str(tmp_path / "warming.lock"),
        ],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert holder.stdout.readline().strip() == "locked"
        with jit.warming() as mine:
            assert not mine
    finally:
        holder.stdin.write("\n")  # the holder lets go and ends
        holder.stdin.close()
        holder.wait()
    with jit.warming() as mine:
        assert mine
