"""Compile the training's and the gate's kernels ahead, in a low-priority background process.

``limbctl record`` starts :func:`warming_in_background` as it begins: a teaching lasts tens of
seconds, enough to compile every kernel the first ``limbctl train`` and ``limbctl teleop`` would
otherwise compile while the person waits. At the lowest priority (:data:`NICENESS`) on one numba
thread, it trains a Rigid Map on a synthetic teaching of the demo region (the three-servo one,
with its twist band, for a three-servo rig) through :func:`limbctl.teach.train.train`, then asks
the model what the gate asks: one command, a small batch (the park check) and a larger one (a
start outside the region). The kernels land in the cache of :mod:`limbctl.geometry.jit` one by
one; the first real train and teleop load them and compile whatever is not there yet. With no
cache folder, or the rig's stages already prepared, no warm-up starts.
"""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from importlib import resources
from pathlib import Path

import numpy as np
import yaml

from limbctl.geometry import jit

#: The warm-up's priority: the lowest, so the recorder's sampling (and anything else) goes first.
NICENESS = 19
#: Length (s) of the synthetic teaching: like a short real one (30 s at 125 Hz), long enough
#: for the fit to try each edge strategy and build the gate's grid.
TEACHING_S = 30.0
#: Commands of the small batch asked of the model: the park check's 13 probes.
SMALL_BATCH = 13
#: Commands of the larger batch asked of the model: one more than a batch served command by
#: command (``correct_kernels.SINGLE_ROWS``), as a start outside the region asks the approach's
#: candidate poses; train itself no longer compiles that kernel (its summary asks the arcs).
LARGE_BATCH = 65


#: The three-servo demo region's twist band as its YAML (data/demo_region3.yaml) describes it:
#: half-widths (deg) with the limb low and high, centred on no twist. The warm-up needs the fit's
#: code paths (a band bounded everywhere, narrowing), not the region itself.
TWIST_HALF_DEG = (49.0, 23.0)


def _demo_polygon(name: str = "demo_region.yaml") -> np.ndarray:
    """A packaged demo region's polygon (V, 2), (pan, tilt) degrees."""
    text = resources.files("limbctl").joinpath("data", name).read_text()
    return np.asarray(yaml.safe_load(text)["region"]["polygon"], dtype=np.float64)


def _write_teaching(path: Path, twist: bool = False) -> None:
    """A synthetic teaching of the demo region (its edge traced, then the middle), as a dataset;
    with ``twist``, full orientations of the three-servo demo region (uniform, along the edge and
    at the twist stops), TEACHING_S at the same rate."""
    from limbctl.envelope.synthetic import PolygonRegion, traced_teaching
    from limbctl.envelope.synthetic_twist import ShoulderRegion
    from limbctl.geometry.gimbal import direction_to_pan_tilt
    from limbctl.geometry.quat import limb_direction
    from limbctl.teach.dataset import DatasetWriter

    rate_hz = 125.0
    rng = np.random.default_rng(0)
    q = None
    if twist:
        n = int(TEACHING_S * rate_hz)
        region = ShoulderRegion(_demo_polygon("demo_region3.yaml"), *TWIST_HALF_DEG, 0.0, 0.0, 0.0)
        q = region.teaching(n - n // 2, n // 4, n // 4, rng)
        directions = limb_direction(q)
    else:
        directions, _ = traced_teaching(PolygonRegion(_demo_polygon()), TEACHING_S, rng, rate_hz)
    pan, tilt = direction_to_pan_tilt(directions)
    with DatasetWriter(path, rig="warm-up") as writer:
        for i in range(len(pan)):
            writer.append(i / rate_hz, float(pan[i]), float(tilt[i]), None if q is None else q[i])


def warm_up(twist: bool = False) -> bool:
    """Compile (or load) the kernels of the rig's stages not yet prepared, in this process.

    Parameters
    ----------
    twist : bool
        Warm a three-servo rig's stages (``train-twist``, ``gate-twist``) instead of a
        two-servo rig's (``train``, ``gate``).

    Returns whether it ran (False: no cache folder, or another warm-up holds the lock).
    """
    train_stage, gate_stage = jit.stage("train", twist), jit.stage("gate", twist)
    with jit.warming() as mine:
        if not mine:
            return False
        if jit.prepared(train_stage) and jit.prepared(gate_stage):
            return True
        from limbctl.envelope import load_model
        from limbctl.teach.dataset import load_dataset
        from limbctl.teach.train import train

        with tempfile.TemporaryDirectory(prefix="limbctl-warm-") as tmp:
            data, model_path = Path(tmp) / "warm.limb", Path(tmp) / "warm.npz"
            _write_teaching(data, twist)
            # the options `limbctl train` passes by default (and sets for a three-servo dataset)
            train(data, model_path, "rigidmap", {"seed": 0, **({"twist": True} if twist else {})})
            jit.mark_prepared(train_stage)
            model = load_model(model_path)
            taught = load_dataset(data).quaternions
            q = np.ascontiguousarray(taught[:SMALL_BATCH])
            model.contains(q[0])
            model.correct(q[0])
            model.contains(q)
            model.correct(q)
            model.correct(np.ascontiguousarray(taught[:LARGE_BATCH]))
            jit.mark_prepared(gate_stage)
    return True


@contextlib.contextmanager
def warming_in_background(twist: bool = False) -> Iterator[subprocess.Popen | None]:
    """Start the warm-up of a rig's stages (``twist``: a three-servo rig's) in its own
    low-priority process, unless nothing needs it; yields it.

    The process is left running on exit (it may still be compiling what the next train loads),
    in its own session so that a Ctrl-C ending the recording does not end it too; its output is
    discarded.
    """
    stages = (jit.stage("train", twist), jit.stage("gate", twist))
    if jit.cache_dir() is None or all(jit.prepared(stage) for stage in stages):
        yield None
        return
    process = subprocess.Popen(
        [sys.executable, "-m", "limbctl.teach.warm", *(["--twist"] if twist else [])],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
        env={**os.environ, "NUMBA_NUM_THREADS": "1"},
    )
    yield process


def main(argv: list[str] | None = None) -> int:
    """The background process: lowest priority, then :func:`warm_up` (``--twist``: of a
    three-servo rig's stages)."""
    args = sys.argv[1:] if argv is None else argv
    os.nice(NICENESS)
    warm_up(twist="--twist" in args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
