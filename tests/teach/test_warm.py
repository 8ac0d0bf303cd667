"""After ``limbctl prepare`` the first train, teleop start and library fit compile no kernel."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
from pathlib import Path

from limbctl.cli import main
from limbctl.geometry import jit
from limbctl.region.correct_kernels import SINGLE_ROWS
from limbctl.teach.warm import LARGE_BATCH, warming_in_background
from tests.compile_probe import COUNTER
from tests.test_first_run import ROOT, compiled_by, teaching

#: A library user's first use in a fresh process: a fit of bare orientations (another seed and
#: size than the warm-up's teaching), then ``contains`` and ``correct`` of one orientation and of
#: batches up to a thousand; writes the dispatchers numba compiled meanwhile as JSON.
LIBRARY = (
    COUNTER
    + r"""
import numpy as np
from limbctl.envelope import RigidMap
from limbctl.envelope.synthetic_twist import ShoulderRegion
from limbctl.geometry.quat import limb_direction, swing_from_direction

twist = sys.argv[2] == "sim3"
q = ShoulderRegion().teaching(1000, 500, 500, np.random.default_rng(1))
if not twist:
    q = swing_from_direction(limb_direction(q))
ev.register("numba:compile", Count())
model = RigidMap(twist=twist).fit(q)
for rows in (q[0], q[:13], q[:65], q[:1000]):
    model.contains(rows)
    model.correct(rows)
with open(sys.argv[1], "w") as out:
    json.dump(compiled, out)
"""
)


def test_after_prepare_train_teleop_and_a_library_fit_compile_no_kernel(tmp_path):
    # both rigs prepared into one cache, as on a machine that teaches both: the three-servo
    # prepare after the two-servo one compiles only what twist adds
    cache = tmp_path / "numba-cache"
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache), "PYTHONPATH": str(ROOT)}
    done_stages: list[str] = []
    for rig in ("sim", "sim3"):
        twist = rig == "sim3"
        prepare = [sys.executable, "-m", "limbctl.cli", "prepare", "--rig", rig]
        done = subprocess.run(prepare, env=env, cwd=tmp_path, capture_output=True, text=True)
        assert done.returncode == 0, done.stderr
        stages = [jit.stage(s, twist) for s in ("train", "gate")]
        done_stages += stages
        markers = sorted(p.name for p in cache.rglob("prepared-*"))
        assert markers == sorted(f"prepared-{stage}" for stage in done_stages)
        folder = next(cache.rglob("prepared-*")).parent
        lines = done.stdout.splitlines()
        # away from a terminal, a line as each stage begins and one as it ends, with its compiles
        ended = [line.split(" ...")[0] for line in lines[1:-1] if line.endswith(" s")]
        expected = [f"[{i}/2] {rig}: {stage}" for i, stage in enumerate(stages, 1)]
        assert ended == expected, done.stdout
        assert len(lines) == 2 + 2 * len(stages), done.stdout
        assert str(folder) in lines[0] and str(folder) in lines[-1], done.stdout
        # the library's first use in a fresh process
        log = tmp_path / f"library-{rig}.json"
        library = [sys.executable, "-c", LIBRARY, str(log), rig]
        done = subprocess.run(library, env=env, cwd=tmp_path, capture_output=True, text=True)
        assert done.returncode == 0, done.stderr
        assert json.loads(log.read_text()) == [], rig
        # a teaching recorded with no warm-up since (prepare only): train, then a teleop start
        data = teaching(tmp_path / f"teach-{rig}.limb", rig)
        model = tmp_path / f"model-{rig}.npz"
        train = ["train", str(data), "--out", str(model)]
        ours, _ = compiled_by(train, tmp_path, prepared=True)
        assert ours == [], rig
        commands = '{"pan": 20, "tilt": 10}\n{"pan": 120, "tilt": 80}\n'
        teleop = ["teleop", "--model", str(model), "--source", "stdin", "--rig", rig]
        ours, _ = compiled_by(teleop, tmp_path, stdin=commands, prepared=True)
        assert ours == [], rig
        # run again, it finds every stage in the cache
        again = subprocess.run(prepare, env=env, cwd=tmp_path, capture_output=True, text=True)
        assert again.returncode == 0, again.stderr
        assert again.stdout.count("already in the cache") == 2, again.stdout


def test_no_warm_up_when_all_is_prepared_or_nothing_can_be_cached_and_prepare_says_so(
    monkeypatch, capsys
):
    # served row by row up to SINGLE_ROWS; more take the kernel a start outside asks
    assert LARGE_BATCH > SINGLE_ROWS, "the larger batch does not take the batch kernel"
    monkeypatch.setattr(jit, "prepared", lambda stage: True)
    with warming_in_background() as process:
        assert process is None, "a warm-up started with every stage prepared"
    monkeypatch.setattr(jit, "prepared", lambda stage: False)
    monkeypatch.setattr(jit, "cache_dir", lambda: None)
    with warming_in_background() as process:
        assert process is None, "a warm-up started with no cache"
    assert main(["prepare", "--rig", "sim"]) == 2
    err = capsys.readouterr().err
    assert "limbctl prepare: error: no writable folder" in err
    assert "NUMBA_CACHE_DIR" in err


#: Takes the lock file argv[1], says "locked", and holds it until a line comes on stdin.
HOLD_LOCK = """import sys, fcntl
lock = open(sys.argv[1], 'a+b'); fcntl.flock(lock, fcntl.LOCK_EX)
print('locked', flush=True); sys.stdin.readline()
"""


def test_a_warm_up_stands_aside_while_another_holds_the_lock_and_prepare_waits_for_it(
    tmp_path, monkeypatch
):
    monkeypatch.setattr(jit, "cache_dir", lambda: Path(tmp_path))
    hold = [sys.executable, "-c", HOLD_LOCK, str(tmp_path / "warming.lock")]
    holder = subprocess.Popen(hold, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    told, got = threading.Event(), []

    def take() -> None:
        with jit.warming(wait=told.set) as mine:
            got.append(mine)

    taker = threading.Thread(target=take)
    try:
        assert holder.stdout.readline().strip() == "locked"
        with jit.warming() as mine:
            assert not mine, "a second warm-up did not stand aside"
        taker.start()  # prepare: says it waits, then takes the lock
        assert told.wait(timeout=60)
        assert got == []  # still waiting: the holder has not let go
    finally:
        holder.stdin.write("\n")  # the holder lets go and ends
        holder.stdin.close()
        holder.wait()
    taker.join(timeout=60)
    assert got == [True], "prepare did not take the lock once it was free"
    with jit.warming() as mine:
        assert mine
