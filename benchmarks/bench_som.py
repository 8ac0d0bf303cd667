"""SOM training speed: limbctl's numba SOM vs MiniSom on the same work, plus cold/warm timings.

Run from the repository root::

    .venv/bin/python benchmarks/bench_som.py

Problem (the SOM paper's largest): 30 x 30 = 900 nodes, 5000 twist-free patterns uniform over a
90 degree cone. limbctl's SOM trains with Table I's schedule until it converges; MiniSom (bubble
neighbourhood, same grid) then trains for exactly the same number of sample presentations
(time steps x patterns), so both do one winner search and one neighbourhood update per
presentation. Ratios come from the same run.

Cold timings run in fresh processes with an empty numba cache directory (compile and write the
cache), then again with that cache filled (load only); warm is a second fit in one process.
Also reported: the RMS end-point error of the trained SOM against Lee's ideal correction over
directions uniform on the sphere (the paper's 3D error figure for this setup is 5.63e-2).

Writes docs/bench_som.md.
"""

from __future__ import annotations

import argparse
import importlib.metadata
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
COMMAND = ".venv/bin/python benchmarks/bench_som.py"


def cone_patterns(n: int, half_angle: float, seed: int) -> np.ndarray:
    """``n`` twist-free orientations with limb directions uniform inside the cone."""
    from limbctl.geometry import quat

    rng = np.random.default_rng(seed)
    chunks, count = [], 0
    while count < n:
        d = quat.normalize(rng.normal(size=(4 * n, 3)))
        d = d[quat.direction_angle(d, np.array([1.0, 0.0, 0.0])) <= half_angle]
        chunks.append(d)
        count += len(d)
    return quat.swing_from_direction(np.concatenate(chunks)[:n])


def child(args: argparse.Namespace) -> None:
    """Time import + first fit (cold) and a second fit (warm) in this process; print JSON."""
    start = time.perf_counter()
    from limbctl.envelope.som import SOM

    patterns = cone_patterns(args.patterns, np.radians(args.half_angle_deg), args.seed)
    t0 = time.perf_counter()
    som = SOM(args.rows, args.cols, seed=args.seed).fit(patterns)
    t1 = time.perf_counter()
    SOM(args.rows, args.cols, seed=args.seed).fit(patterns)
    t2 = time.perf_counter()
    print(
        json.dumps(
            {
                "import_s": t0 - start,
                "first_fit_s": t1 - t0,
                "second_fit_s": t2 - t1,
                "steps": som.steps,
            }
        )
    )


def run_child(args: argparse.Namespace, cache_dir: str) -> dict:
    env = dict(os.environ, NUMBA_CACHE_DIR=cache_dir)
    cmd = [sys.executable, __file__, "--child"]
    cmd += ["--rows", str(args.rows), "--cols", str(args.cols), "--patterns", str(args.patterns)]
    cmd += ["--half-angle-deg", str(args.half_angle_deg), "--seed", str(args.seed)]
    done = subprocess.run(cmd, env=env, check=True, capture_output=True, text=True, cwd=ROOT)
    return json.loads(done.stdout.strip().splitlines()[-1])


def rms_error(som, half_angle: float, seed: int, n: int = 20000) -> dict[str, float]:
    from limbctl.envelope.cone import Cone
    from limbctl.geometry import quat

    rng = np.random.default_rng(seed + 1000)
    q = quat.swing_from_direction(quat.normalize(rng.normal(size=(n, 3))))
    ideal = quat.limb_direction(Cone(half_angle).correct(q))
    out = {}
    for mode, k in (("none", 1), ("geometric", 8), ("idw", 2), ("topological", 8)):
        answer = quat.limb_direction(som.respond(q, interpolation=mode, k=k))
        # RMS over test directions of |d_som - d_ideal| on a unit limb
        out[f"{mode} (k={k})" if mode != "none" else "none"] = float(
            np.sqrt(np.mean(np.sum((answer - ideal) ** 2, axis=1)))
        )
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", type=int, default=30)
    parser.add_argument("--cols", type=int, default=30)
    parser.add_argument("--patterns", type=int, default=5000)
    parser.add_argument("--half-angle-deg", type=float, default=90.0)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--repeats", type=int, default=3, help="warm fits to take the best of")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "bench_som.md")
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(args)
        return

    from minisom import MiniSom

    from limbctl.envelope.som import SOM

    with tempfile.TemporaryDirectory(prefix="bench_som_numba_") as cache_dir:
        compile_run = run_child(args, cache_dir)
        cached_run = run_child(args, cache_dir)

    patterns = cone_patterns(args.patterns, np.radians(args.half_angle_deg), args.seed)
    SOM(args.rows, args.cols, seed=args.seed).fit(patterns)  # load kernels in this process
    ours = []
    for _ in range(args.repeats):
        t0 = time.perf_counter()
        som = SOM(args.rows, args.cols, seed=args.seed).fit(patterns)
        ours.append(time.perf_counter() - t0)
    presentations = som.steps * len(patterns)

    mini = MiniSom(
        args.rows,
        args.cols,
        4,
        sigma=4.0,
        learning_rate=1.0,
        neighborhood_function="bubble",
        random_seed=args.seed,
    )
    t0 = time.perf_counter()
    mini.train(patterns, presentations, random_order=False)
    minisom_s = time.perf_counter() - t0

    ours_s = min(ours)
    ratio = minisom_s / ours_s
    errors = rms_error(som, np.radians(args.half_angle_deg), args.seed)
    lines = [
        "# SOM training benchmark",
        "",
        f"Command: `{COMMAND}` (defaults). Generated by benchmarks/bench_som.py.",
        "",
        f"Problem: {args.rows} x {args.cols} = {args.rows * args.cols} nodes, "
        f"{len(patterns)} twist-free patterns uniform in a {args.half_angle_deg:g} deg cone, "
        f"seed {args.seed}. limbctl's SOM converged after {som.steps} time steps "
        f"(converged={som.converged}) = {presentations} sample presentations; MiniSom "
        f"{importlib.metadata.version('minisom')} (bubble neighbourhood, "
        "numpy) ran the same number of presentations.",
        "",
        "| | seconds |",
        "|---|---|",
        f"| limbctl SOM fit, warm (best of {args.repeats}) | {ours_s:.3f} |",
        f"| MiniSom train, same presentations | {minisom_s:.3f} |",
        f"| **ratio MiniSom / limbctl** | **{ratio:.1f}x** |",
        "",
        "Cold vs warm (fresh processes, empty `NUMBA_CACHE_DIR`, then the same cache dir):",
        "",
        "| process | import s | first fit s | second fit s |",
        "|---|---|---|---|",
        f"| 1st process (compiles, writes cache) | {compile_run['import_s']:.3f} | "
        f"{compile_run['first_fit_s']:.3f} | {compile_run['second_fit_s']:.3f} |",
        f"| 2nd process (loads cache) | {cached_run['import_s']:.3f} | "
        f"{cached_run['first_fit_s']:.3f} | {cached_run['second_fit_s']:.3f} |",
        "",
        "Accuracy of the trained SOM (RMS end-point error of a unit limb vs Lee's ideal "
        "correction, 20000 test directions uniform on the sphere; the SOM paper reports 5.63e-2 "
        "for this setup):",
        "",
        "| answer | RMS error |",
        "|---|---|",
        *[f"| {mode} | {value:.4f} |" for mode, value in errors.items()],
        "",
        f"Machine: {os.cpu_count()} CPUs (shared with other jobs); numbers vary run to run.",
        "",
    ]
    text = "\n".join(lines)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text)
    print(text)


if __name__ == "__main__":
    main()
