"""Compile the training's and the gate's kernels ahead: in a low-priority background process
while ``limbctl record`` teaches, or in the foreground for ``limbctl prepare``."""

from __future__ import annotations

import argparse
import contextlib
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator, Sequence
from importlib import resources
from pathlib import Path
from typing import TextIO

import numpy as np
import yaml

from limbctl.geometry import jit

#: The warm-up's priority: the lowest, so the recorder's sampling (and anything else) goes first.
NICENESS = 19
#: Length (s) of the synthetic teaching: a short real one, enough to try every edge strategy.
TEACHING_S = 30.0
#: Commands of the small batch asked of the model: the park check's 13 probes.
SMALL_BATCH = 13
#: Commands of the larger batch: past ``correct_kernels.SINGLE_ROWS``, as a start and a route ask.
LARGE_BATCH = 65
#: Twist band half-widths (deg), limb low and high, of data/demo_region3.yaml: a narrowing band.
TWIST_HALF_DEG = (49.0, 23.0)


def _demo_polygon(name: str = "demo_region.yaml") -> np.ndarray:
    """A packaged demo region's polygon (V, 2), (pan, tilt) degrees."""
    text = resources.files("limbctl").joinpath("data", name).read_text()
    return np.asarray(yaml.safe_load(text)["region"]["polygon"], dtype=np.float64)


def _write_teaching(path: Path, twist: bool = False) -> None:
    """Write a synthetic teaching of the (``twist``: three-servo) demo region as a dataset."""
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


#: What :func:`warm_up` reports of a stage: compiling, compiled, already cached, waiting for lock.
START, DONE, READY, WAIT = "start", "done", "ready", "wait"


def warm_up(
    twist: bool = False, wait: bool = False, report: Callable[[str, str], None] | None = None
) -> bool:
    """Compile the kernels of a (``twist``: three-servo) rig's stages not yet prepared, calling
    ``report(stage, event)``; whether it ran (not without a cache, or locked and no ``wait``)."""
    tell = report or (lambda stage, event: None)
    train_stage, gate_stage = jit.stage("train", twist), jit.stage("gate", twist)
    with jit.warming(wait=(lambda: tell(train_stage, WAIT)) if wait else None) as mine:
        if not mine:
            return False
        if jit.prepared(train_stage) and jit.prepared(gate_stage):
            tell(train_stage, READY)
            tell(gate_stage, READY)
            return True
        from limbctl.envelope import RigidMap, load_model
        from limbctl.teach.dataset import load_dataset
        from limbctl.teach.train import train

        with tempfile.TemporaryDirectory(prefix="limbctl-warm-") as tmp:
            data, model_path = Path(tmp) / "warm.limb", Path(tmp) / "warm.npz"
            tell(train_stage, START)
            _write_teaching(data, twist)
            # the options `limbctl train` passes by default (and sets for a three-servo dataset)
            train(data, model_path, "rigidmap", {"seed": 0, **({"twist": True} if twist else {})})
            taught = load_dataset(data).quaternions
            # a library user's fit: bare (N, 4) orientations, the model's default options
            library = RigidMap(twist=twist).fit(np.ascontiguousarray(taught))
            jit.mark_prepared(train_stage)
            tell(train_stage, DONE)
            tell(gate_stage, START)
            small, large = (np.ascontiguousarray(taught[:n]) for n in (SMALL_BATCH, LARGE_BATCH))
            for model in (load_model(model_path), library):
                for q in (small[0], small, large):
                    model.contains(q)
                    model.correct(q)
            jit.mark_prepared(gate_stage)
            tell(gate_stage, DONE)
    return True


@contextlib.contextmanager
def warming_in_background(twist: bool = False) -> Iterator[subprocess.Popen | None]:
    """Start the warm-up of a rig's stages in a low-priority session if needed; yields it."""
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


#: ``limbctl prepare --rig all``: a packaged rig per joint count (all the kernels depend on).
ALL_RIGS = ("sim", "sim3")


class _Progress:
    """``limbctl prepare``'s line per stage: what compiles, numba's compiles so far, how long."""

    def __init__(self, out: TextIO, stages: int) -> None:
        self.out, self.stages, self.index = out, stages, 0
        self.live = out.isatty()
        self.label, self.count, self.start = "", 0, 0.0

    def compiled(self) -> None:
        """One of numba's compiles ended (a kernel or one of numba's helpers)."""
        self.count += 1
        if self.live and self.label:
            seconds = time.perf_counter() - self.start
            line = f"\r{self.label} {self.count} numba compiles, {seconds:.0f} s"
            print(line, end="", file=self.out, flush=True)

    def __call__(self, rig: str, stage: str, event: str) -> None:
        if event == START:
            self.index += 1
            self.label = f"[{self.index}/{self.stages}] {rig}: {stage} ..."
            self.count, self.start = 0, time.perf_counter()
            print(self.label, end="" if self.live else "\n", file=self.out, flush=True)
        elif event == DONE:
            seconds = time.perf_counter() - self.start
            prefix = "\r" + self.label if self.live else self.label
            print(
                f"{prefix} {self.count} numba compiles, {seconds:.1f} s", file=self.out, flush=True
            )
            self.label = ""
        elif event == WAIT:
            line = f"{rig}: waiting for a warm-up already running (`limbctl record` starts one)"
            print(line, file=self.out, flush=True)
        else:
            self.index += 1
            line = f"[{self.index}/{self.stages}] {rig}: {stage} ... already in the cache"
            print(line, file=self.out, flush=True)


def run_prepare(rigs: Sequence[str], out: TextIO = sys.stdout) -> int:
    """``limbctl prepare``: compile and cache the kernels of ``rigs``; returns the exit status
    (ConfigError when no cache folder is writable)."""
    import numba.core.event as numba_event

    from limbctl.errors import ConfigError
    from limbctl.servo.profiles import load_rig_profile

    twists = {rig: load_rig_profile(rig).twists for rig in rigs}
    folder = jit.cache_dir()
    if folder is None:
        raise ConfigError(
            "no writable folder for the compiled kernels (tried "
            + ", ".join(str(f) for f in jit.cache_candidates())
            + "): set NUMBA_CACHE_DIR to a writable folder and run `limbctl prepare` again"
        )
    print(f"limbctl prepare: compiling the numba kernels into {folder}", file=out, flush=True)
    progress = _Progress(out, 2 * len(twists))

    class Listener(numba_event.Listener):
        def on_start(self, event: numba_event.Event) -> None:
            pass

        def on_end(self, event: numba_event.Event) -> None:
            progress.compiled()

    start = time.perf_counter()
    with numba_event.install_listener("numba:compile", Listener()):
        for rig, twist in twists.items():
            warm_up(
                twist, wait=True, report=lambda stage, event, rig=rig: progress(rig, stage, event)
            )
    seconds = time.perf_counter() - start
    print(
        f"limbctl prepare: done in {seconds:.1f} s; the compiled kernels are in {folder} (a "
        "changed kernel source or numba version starts a new folder: run it again then)",
        file=out,
        flush=True,
    )
    return 0


#: ``limbctl prepare``'s help, description and ``--rig`` option (limbctl.cli's parser).
HELP = (
    "compile and cache the numba kernels for both rigs so the first train, teleop and library "
    "fit after install do not compile"
)
DESCRIPTION = (
    "Compile the kernels of training, the gate and a library fit into the cache (NUMBA_CACHE_DIR "
    "sets it) after install or upgrade; else `limbctl record` compiles them while you teach."
)
RIG_HELP = (
    "all (default: two and three servos), sim (two servos: pan, tilt), sim3 (three: and "
    "roll), or a rig profile (its number of servos)"
)


def prepare_job(args: argparse.Namespace) -> int:
    """``limbctl prepare``: :func:`run_prepare` of ``args.rig`` (``all``: :data:`ALL_RIGS`)."""
    return run_prepare(ALL_RIGS if args.rig == "all" else (args.rig,))


def main(argv: list[str] | None = None) -> int:
    """The background process: lowest priority, then :func:`warm_up`."""
    args = sys.argv[1:] if argv is None else argv
    os.nice(NICENESS)
    warm_up(twist="--twist" in args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
