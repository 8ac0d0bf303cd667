"""limbctl.teach.warm: after a warm-up, the first train and teleop start compile no kernel."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from limbctl.geometry import jit
from limbctl.region.correct_kernels import SINGLE_ROWS
from limbctl.teach.warm import LARGE_BATCH, warming_in_background
from tests.test_first_run import ROOT, compiled_by, teaching


def test_the_larger_batch_takes_the_batch_kernel():
    # served row by row up to SINGLE_ROWS; one more takes the kernel a start outside asks
    assert LARGE_BATCH == SINGLE_ROWS + 1


def teaching3(path: Path) -> Path:
    """A synthetic teaching of the three-servo demo region (another seed than the warm-up's),
    written under the simulated three-servo rig's calibration (so train fits the twist band)."""
    from limbctl.envelope.synthetic_twist import ShoulderRegion
    from limbctl.geometry.gimbal import direction_to_pan_tilt
    from limbctl.geometry.quat import limb_direction
    from limbctl.servo.profiles import load_rig_profile
    from limbctl.teach.dataset import DatasetWriter
    from limbctl.teach.warm import TWIST_HALF_DEG, _demo_polygon

    region = ShoulderRegion(_demo_polygon("demo_region3.yaml"), *TWIST_HALF_DEG, 0.0, 0.0, 0.0)
    q = region.teaching(1500, 700, 700, np.random.default_rng(1))
    pan, tilt = direction_to_pan_tilt(limb_direction(q))
    profile = load_rig_profile("sim3")
    with DatasetWriter(path, rig=profile.name, calibration=profile.calibration) as writer:
        for i in range(len(q)):
            writer.append(i / 125.0, float(pan[i]), float(tilt[i]), q[i])
    return path


@pytest.mark.parametrize("rig", ["sim", "sim3"])
def test_after_a_warm_up_train_and_teleop_compile_no_kernel_and_say_nothing(rig, tmp_path):
    twist = rig == "sim3"
    cache = tmp_path / "numba-cache"
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache), "PYTHONPATH": str(ROOT)}
    warm = [sys.executable, "-m", "limbctl.teach.warm", *(["--twist"] if twist else [])]
    subprocess.run(warm, env=env, check=True, cwd=tmp_path)
    markers = sorted(p.name for p in cache.rglob("prepared-*"))
    assert markers == sorted(f"prepared-{jit.stage(s, twist)}" for s in ("train", "gate"))
    data = (teaching3 if twist else teaching)(tmp_path / "teach.limb")
    model = tmp_path / "model.npz"
    ours, _ = compiled_by(["train", str(data), "--out", str(model)], tmp_path, prepared=True)
    assert ours == []
    commands = '{"pan": 20, "tilt": 10}\n{"pan": 120, "tilt": 80}\n'
    ours, _ = compiled_by(
        ["teleop", "--model", str(model), "--source", "stdin", "--rig", rig],
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
