"""What a first run compiles from an empty kernel cache: ``train``, a teleop start, a twist fit
(counts: docs/bench_first_run.md, "Compiles per command"; raise one only if worth it)."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from limbctl.envelope.synthetic_twist import ShoulderRegion
from limbctl.geometry.gimbal import direction_to_pan_tilt
from limbctl.geometry.quat import limb_direction
from limbctl.servo.profiles import load_rig_profile
from limbctl.teach.dataset import DatasetWriter, load_dataset
from limbctl.teach.warm import TWIST_HALF_DEG, _demo_polygon
from tests.compile_probe import COUNTER

ROOT = Path(__file__).resolve().parents[1]
TEACHING = ROOT / "tests" / "data" / "hand_irregular_seed0_20s.limb"

#: Dispatchers ``limbctl train`` compiles from an empty cache: limbctl's kernels, numba's helpers
#: (the arc foot's arithmetic, ``mesh_kernels._foot``, is one kernel shared by two callers; the
#: hold's two crossing searches, ``hold_kernels``, save seconds on every fit that holds an edge).
TRAIN_COMPILES = (39, 23)
#: The same for ``limbctl teleop`` of two commands with no train before (a start outside the
#: region also compiles ``correct_serial`` and a helper or two for the approach's candidates;
#: ``nearest_on_arc`` calls the shared ``_foot``, which calls ``_angle3``: two small kernels).
TELEOP_COMPILES = (13, 9)

PROBE = (
    COUNTER
    + r"""
ev.register("numba:compile", Count())
from limbctl.cli import main
status = main(sys.argv[2:])
with open(sys.argv[1], "w") as out:
    json.dump(compiled, out)
sys.exit(status)
"""
)


def probed(script: str, tmp: Path, args=(), stdin: str = "") -> tuple[str, list]:
    """Run a probe ``script`` with ``args`` from an empty cache: its stderr, and what it logged."""
    log = tmp / "compiled.json"
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp / "numba-cache"), "PYTHONPATH": str(ROOT)}
    done = subprocess.run(
        [sys.executable, "-c", script, str(log), *args],
        cwd=tmp,
        env=env,
        input=stdin,
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stderr
    return done.stderr, json.loads(log.read_text())


def compiled_by(
    args: list[str], tmp: Path, stdin: str = "", prepared: bool = False
) -> tuple[list[str], list[str]]:
    """Run ``limbctl ARGS`` from an empty cache: (limbctl kernels, numba helpers) compiled."""
    said, names = probed(PROBE, tmp, args, stdin)
    # a first run says why it waits; a run that finds everything compiled does not
    assert ("preparing (first run only)" in said) != prepared, said
    ours = [n for n in names if n.startswith("limbctl.")]
    return ours, [n for n in names if not n.startswith("limbctl.")]


def _within(what: str, found: tuple[list[str], list[str]], limits: tuple[int, int]) -> None:
    ours, helpers = found
    assert len(ours) <= limits[0], f"{what} compiles {len(ours)} kernels: {sorted(ours)}"
    assert len(helpers) <= limits[1], f"{what} compiles {len(helpers)} helpers: {sorted(helpers)}"


def teaching(path: Path, rig: str = "sim") -> Path:
    """A teaching written under the simulated ``rig``'s calibration: on two servos the recorded
    one; on three a synthetic one of the demo region (another seed than the warm-up's)."""
    profile = load_rig_profile(None if rig == "sim" else rig)
    with DatasetWriter(path, rig=profile.name, calibration=profile.calibration) as writer:
        if rig == "sim":
            data = load_dataset(TEACHING)
            for t, pan, tilt in zip(data.t, data.pan_deg, data.tilt_deg, strict=True):
                writer.append(float(t), math.radians(pan), math.radians(tilt))
            return path
        region = ShoulderRegion(_demo_polygon("demo_region3.yaml"), *TWIST_HALF_DEG, 0.0, 0.0, 0.0)
        q = region.teaching(1500, 700, 700, np.random.default_rng(1))
        pan, tilt = direction_to_pan_tilt(limb_direction(q))
        for i in range(len(q)):
            writer.append(i / 125.0, float(pan[i]), float(tilt[i]), q[i])
    return path


@pytest.fixture(scope="module")
def model(tmp_path_factory) -> tuple[Path, tuple[list[str], list[str]]]:
    """A model trained from an empty cache, and what that train compiled."""
    tmp = tmp_path_factory.mktemp("train")
    data = teaching(tmp / "teach.limb")
    found = compiled_by(["train", str(data), "--out", str(tmp / "model.npz")], tmp)
    return tmp / "model.npz", found


def test_train_and_a_teleop_start_compile_at_most_the_documented_count(model, tmp_path):
    _within("train", model[1], TRAIN_COMPILES)
    # train serves its small batches on one thread and never gates
    ours = model[1][0]
    gate = {f"limbctl.region.correct_kernels.correct_{k}" for k in ("batch", "serial", "single")}
    assert not gate & set(ours)
    commands = '{"pan": 20, "tilt": 10}\n{"pan": 120, "tilt": 80}\n'
    found = compiled_by(
        ["teleop", "--model", str(model[0]), "--source", "stdin"], tmp_path, stdin=commands
    )
    _within("teleop", found, TELEOP_COMPILES)
    # the park check's small batch goes through the gate's own single-command kernel
    assert "limbctl.region.correct_kernels.correct_single" in found[0]
    assert not {"limbctl.region.correct_kernels.correct_batch"} & set(found[0])


#: Dispatchers a first ``RigidMap(twist=True).fit`` from Python compiles from an empty cache.
TWIST_FIT_COMPILES = (49, 54)
#: Compiles of such a fit repeating a (dispatcher, signature): 5 of numba's own overloads, 14 of
#: gradient_caps' helpers (``error_model="numpy"``, unlike the other kernels).
TWIST_FIT_REPEATS = 19

TWIST_FIT = (
    COUNTER
    + r"""
import numpy as np
from limbctl.envelope import RigidMap
from limbctl.envelope.synthetic_twist import ShoulderRegion

q = ShoulderRegion().teaching(1000, 500, 500, np.random.default_rng(0))
ev.register("numba:compile", Count())
RigidMap(seed=0, twist=True).fit(q)
with open(sys.argv[1], "w") as out:
    json.dump(signatures, out)
"""
)


def test_a_first_twist_fit_compiles_no_helper_per_prange_body_and_no_gate_kernel(tmp_path):
    """No prange body recompiles numba's helpers, no np.linalg checks, no gate containment."""
    compiled = [tuple(c) for c in probed(TWIST_FIT, tmp_path)[1]]
    ours = [n for n, _ in compiled if n.startswith("limbctl.")]
    helpers = [n for n, _ in compiled if not n.startswith("limbctl.")]
    _within("a twist fit", (ours, helpers), TWIST_FIT_COMPILES)
    assert len(compiled) - len(set(compiled)) <= TWIST_FIT_REPEATS, sorted(compiled)
    assert len(set(ours)) == len(ours), sorted(ours)
    assert not [n for n in helpers if n.startswith("numba.np.linalg")]
    assert "limbctl.region.mesh_kernels.contains_batch" not in ours
