"""How much of the taught region a model holds after a short teaching on the simulator.

Run: ``.venv/bin/python benchmarks/bench_teaching.py --seconds 30 --seeds 0,1,2,3,4``
(prints a Markdown table; docs/teaching.md records a run).

For each hand style (``trace``: the whole edge once, then wander; ``wander``: wander only) and
seed: start the simulator with the hand teaching ``--region``, record ``--seconds`` at 100 Hz
through the real dynamixel-sdk (:func:`limbctl.teach.record.record`), train a Rigid Map
(:func:`limbctl.teach.train.train`), and count the share of the poses on a 1 deg pan/tilt grid
lying 2 deg or more inside the hand's region that the model contains. The guide's figures
(:mod:`limbctl.teach.guide`) at the end of the recording are printed beside it.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml

from firmware_sim.hand import STYLES, Hand
from firmware_sim.regions import grid_inside
from limbctl.envelope import RigidMap
from limbctl.geometry.gimbal import pan_tilt_to_quat
from limbctl.session import open_rig
from limbctl.teach.dataset import DatasetWriter, load_dataset
from limbctl.teach.guide import assess
from limbctl.teach.record import record
from limbctl.teach.train import train

ROOT = Path(__file__).resolve().parents[1]
#: Poses this deep (deg) or deeper inside the hand's region must be held (issue 12).
INSIDE_DEG = 2.0
#: Spacing (deg) of the grid of poses checked.
GRID_STEP_DEG = 1.0


def held_fraction(model: RigidMap, region: object) -> tuple[float, int]:
    """Share of grid poses INSIDE_DEG or more inside ``region`` that ``model`` contains."""
    poses = grid_inside(region, GRID_STEP_DEG, INSIDE_DEG)
    q = pan_tilt_to_quat(np.radians(poses[:, 0]), np.radians(poses[:, 1]))
    return float(np.mean(model.contains(q))), len(poses)


def run(region_path: Path, style: str, seconds: float, seed: int, work: Path) -> dict:
    """Teach, train and score one (style, seed); returns the row's figures."""
    spec = {**yaml.safe_load(region_path.read_text()), "style": style}
    region = Hand.from_mapping(spec, source=str(region_path)).region
    data_path, model_path = work / f"{style}-{seed}.limb", work / f"{style}-{seed}.npz"
    with open_rig(hand=spec, seed=seed) as session:
        with DatasetWriter(data_path, rig="sim") as writer:
            # the guide runs once a second, as under `limbctl record` on a terminal
            summary = record(session.rig, writer, 100.0, seconds, on_guidance=lambda guidance: None)
    data = load_dataset(data_path)
    guide = assess(data.t, np.radians(data.pan_deg), np.radians(data.tilt_deg))
    gaps_ms = 1000.0 * np.diff(data.t)
    train(data_path, model_path, options={"seed": seed})
    model = RigidMap.load(model_path)
    held, poses = held_fraction(model, region)
    return {
        "style": style,
        "seed": seed,
        "samples": summary.samples,
        "held": held,
        "poses": poses,
        "edge": model.edge,
        "edge_closed": guide.edge_closed,
        "inside_covered": guide.inside_covered,
        "ready": guide.ready,
        "gap_p99_ms": float(np.percentile(gaps_ms, 99)),
        "gap_max_ms": float(gaps_ms.max()),
    }


def time_assess(samples: int = 10_000, repeats: int = 20) -> tuple[float, float]:
    """Median and worst time (ms) of one guide assessment of ``samples`` recorded samples (the
    simulator's hand, 100 Hz, replayed from its World without the bus)."""
    from firmware_sim.world import World

    world = World(hand=Hand.from_yaml(ROOT / "examples/regions/irregular.yaml", seed=0), seed=0)
    pose = []
    for _ in range(samples):
        world.step(0.01, {1: None, 2: None})
        angles = world.joint_angles_deg()
        pose.append((angles["pan"], angles["tilt"]))
    pan, tilt = np.radians(np.array(pose)).T
    t = np.arange(samples) * 0.01
    costs = []
    for _ in range(repeats):
        begin = time.perf_counter()
        assess(t, pan, tilt)
        costs.append(1000.0 * (time.perf_counter() - begin))
    return float(np.median(costs)), float(np.max(costs))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--region", type=Path, default=ROOT / "examples/regions/irregular.yaml")
    parser.add_argument("--seconds", type=float, default=30.0)
    parser.add_argument("--seeds", default="0,1,2,3,4")
    parser.add_argument("--styles", default=",".join(STYLES))
    args = parser.parse_args()
    median_ms, worst_ms = time_assess()
    print(
        f"guide: one assessment of 10,000 samples takes {median_ms:.1f} ms (median of 20, "
        f"worst {worst_ms:.1f} ms)\n"
    )
    print(
        f"{args.region.name}, {args.seconds:g} s at 100 Hz through the SDK; held = share of "
        f"the {GRID_STEP_DEG:g} deg grid poses >= {INSIDE_DEG:g} deg inside the region\n"
    )
    print(
        "| style | seed | samples | held | edge | guide: edge closed | inside covered | ready "
        "| sample gap p99 / max |"
    )
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    with tempfile.TemporaryDirectory() as work:
        for style in args.styles.split(","):
            for seed in (int(s) for s in args.seeds.split(",")):
                r = run(args.region, style, args.seconds, seed, Path(work))
                print(
                    f"| {r['style']} | {r['seed']} | {r['samples']} | "
                    f"{100 * r['held']:.2f} % of {r['poses']} | {r['edge']} | "
                    f"{100 * r['edge_closed']:.0f} % | {100 * r['inside_covered']:.0f} % | "
                    f"{'yes' if r['ready'] else 'no'} | "
                    f"{r['gap_p99_ms']:.1f} / {r['gap_max_ms']:.1f} ms |",
                    flush=True,
                )


if __name__ == "__main__":
    main()
