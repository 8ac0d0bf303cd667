"""Accuracy and speed of the Rigid Map: the papers' answer versus the exact gate, and peers.

Run: ``.venv/bin/python benchmarks/bench_envelope.py`` (writes docs/bench_envelope.md).

Accuracy, per region (cones of 20 and 90 degrees, the irregular BEAN polygon; 1000 teaching
samples; test commands uniform within R + min(R, 45 deg) of the axis; the ideal is the nearest
valid direction): mean angle to the ideal, valid commands (2 deg or more inside) returned
unchanged, outputs inside the true region or within 1 deg of it, and the papers' metrics
(quaternion MSE against the ideal, RMS 3D end-point error of a unit limb).

Speed, as ratios measured side by side: training kernel versus the straightforward numpy
reference of the same rule; correct() versus a scipy cKDTree nearest-neighbour query on the same
weights (one command from Python, and 200,000 in a batch); cold and warm import-to-first-answer.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from limbctl.envelope import RigidMap
from limbctl.envelope import rigidmap_kernels as rk
from limbctl.envelope.synthetic import (
    ConeRegion,
    PolygonRegion,
    to_quaternions,
    trajectory_samples,
)
from limbctl.quat import direction_angle, euclidean_distance, limb_direction

ROOT = Path(__file__).resolve().parents[1]


#: The simulator's irregular hand region (examples/regions/irregular.yaml), pan/tilt degrees.
IRREGULAR = np.array(
    [[-70, 5], [-66, -18], [-52, -31], [-30, -35], [-5, -32], [22, -34], [48, -30], [68, -18],
     [80, 2], [77, 26], [64, 46], [44, 58], [24, 57], [10, 44], [-4, 36], [-18, 41],
     [-36, 52], [-55, 46], [-67, 28]], dtype=float
)  # fmt: skip


def accuracy_rows(n_train: int, n_test: int, n_strokes: int, seed: int) -> list[list[str]]:
    rows = []
    regions = [
        ("cone 20", ConeRegion(np.radians(20.0)), "iid"),
        ("cone 90", ConeRegion(np.radians(90.0)), "iid"),
        ("bean", PolygonRegion(), "iid"),
        ("strokes: irregular", PolygonRegion(IRREGULAR), "strokes"),
        ("strokes: cone 30", ConeRegion(np.radians(30.0)), "strokes"),
    ]
    for name, region, kind in regions:
        rng = np.random.default_rng(seed)
        model = RigidMap(nodes=2000, layout="uniform", seed=seed)
        if kind == "iid":
            train = region.sample(n_train, rng)
        else:
            train = trajectory_samples(region, n_strokes, rng)
        q_train = to_quaternions(train)
        t_fit = time.perf_counter()
        model.fit(q_train)
        t_fit = time.perf_counter() - t_fit
        contained = model.contains(q_train).mean()
        test = region.test_directions(n_test, rng)
        ideal = region.ideal(test)
        depth = region.depth(test)
        q = to_quaternions(test)
        q_ideal = to_quaternions(ideal)
        valid = depth >= np.radians(2.0)
        answers = {
            "respond none": model.respond(q, "none"),
            "respond geometric k=8": model.respond(q, "geometric", k=8),
            "correct": model.correct(q),
        }
        for label, out in answers.items():
            d_out = limb_direction(out)
            err = np.degrees(direction_angle(d_out, ideal))
            unchanged = np.all(out[valid] == q[valid], axis=1).mean()
            near = (region.depth(d_out) >= -np.radians(1.0)).mean()
            mse = np.mean(euclidean_distance(out, q_ideal) ** 2)
            err3d = np.sqrt(np.mean(np.sum((d_out - ideal) ** 2, axis=1)))
            rows.append(
                [
                    name,
                    label,
                    f"{err.mean():.3f}",
                    f"{100 * unchanged:.2f}",
                    f"{100 * near:.2f}",
                    f"{mse:.3e}",
                    f"{err3d:.3e}",
                    f"{100 * contained:.2f}" if label == "correct" else "",
                    f"{t_fit:.1f}" if label == "correct" else "",
                ]
            )
    return rows


def best_of(fn, repeat: int) -> float:
    best = np.inf
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t)
    return best


def speed_rows(seed: int) -> list[list[str]]:
    rng = np.random.default_rng(seed)
    region = ConeRegion(np.radians(45.0))
    q_train = to_quaternions(region.sample(1000, rng))
    model = RigidMap(nodes=2000, seed=seed)
    model.fit(q_train)
    pos = model.positions
    patterns = np.ascontiguousarray(q_train)
    args = (1.0, 0.15, 2 * np.pi, 1.0, 0.04, 1000, 1e-9)
    t_kernel = best_of(lambda: rk.train_rigid_map(pos, pos.copy(), patterns, *args), 3)
    t_ref = best_of(lambda: rk.train_rigid_map_reference(pos, pos.copy(), patterns, *args), 1)
    t_fit = best_of(lambda: RigidMap(nodes=2000, seed=seed).fit(q_train), 1)
    tree = cKDTree(model.weights)
    singles = to_quaternions(region.test_directions(2000, rng))
    outside = singles[~model.contains(singles)][:500]

    def per_call(fn, items):
        t = time.perf_counter()
        for x in items:
            fn(x)
        return (time.perf_counter() - t) / len(items)

    t_corr1 = min(per_call(model.correct, outside) for _ in range(5))
    t_tree1 = min(per_call(tree.query, outside) for _ in range(5))
    batch = to_quaternions(ConeRegion(np.radians(90.0)).test_directions(200_000, rng))
    t_corrb = best_of(lambda: model.correct(batch), 3)
    t_treeb = best_of(lambda: tree.query(batch), 3)
    return [
        ["train kernel (numba)", f"{t_kernel * 1e3:.1f} ms", ""],
        ["train reference (numpy)", f"{t_ref * 1e3:.0f} ms", f"{t_ref / t_kernel:.0f}x slower"],
        ["full fit (map + refinement + gate)", f"{t_fit * 1e3:.0f} ms", ""],
        ["correct, 1 outside command", f"{t_corr1 * 1e6:.1f} us", ""],
        [
            "cKDTree.query, 1 command",
            f"{t_tree1 * 1e6:.1f} us",
            f"correct/tree = {t_corr1 / t_tree1:.2f}",
        ],
        ["correct, 200,000 commands", f"{t_corrb * 1e3:.1f} ms", ""],
        [
            "cKDTree.query, 200,000",
            f"{t_treeb * 1e3:.1f} ms",
            f"correct/tree = {t_corrb / t_treeb:.2f}",
        ],
    ]


STARTUP = """
import time
t = time.perf_counter()
import numpy as np
from limbctl.envelope import RigidMap
m = RigidMap.load({path!r})
m.correct(np.array([0.5, 0.5, 0.5, 0.5]))
print(time.perf_counter() - t)
"""


def startup_rows(seed: int) -> list[list[str]]:
    rng = np.random.default_rng(seed)
    model = RigidMap(nodes=2000, seed=seed).fit(
        to_quaternions(ConeRegion(np.radians(45.0)).sample(1000, rng))
    )
    with tempfile.TemporaryDirectory() as tmp:
        path = model.save(Path(tmp) / "model.npz")
        env = {"NUMBA_CACHE_DIR": str(Path(tmp) / "numba-cache"), "PATH": "/usr/bin:/bin"}
        times = []
        for _ in range(2):
            out = subprocess.run(
                [sys.executable, "-c", STARTUP.format(path=str(path))],
                capture_output=True,
                text=True,
                env=env,
                check=True,
                cwd=ROOT,
            )
            times.append(float(out.stdout.strip()))
    return [
        ["cold (empty numba cache: compiles)", f"{times[0]:.2f} s"],
        ["warm (cached kernels)", f"{times[1]:.2f} s"],
    ]


def table(header: list[str], rows: list[list[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--train", type=int, default=1000)
    parser.add_argument("--test", type=int, default=20000)
    parser.add_argument("--strokes", type=int, default=7500, help="samples of hand strokes")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "bench_envelope.md")
    args = parser.parse_args()
    acc = table(
        [
            "region",
            "answer",
            "mean angle to ideal (deg)",
            "valid unchanged (%)",
            "inside or within 1 deg (%)",
            "quaternion MSE",
            "3D error (RMS, unit limb)",
            "training samples contained (%)",
            "fit (s)",
        ],
        accuracy_rows(args.train, args.test, args.strokes, args.seed),
    )
    speed = table(["what", "time", "ratio"], speed_rows(args.seed))
    start = table(["import to first correct()", "time"], startup_rows(args.seed))
    command = "`.venv/bin/python benchmarks/bench_envelope.py " + " ".join(sys.argv[1:]) + "`"
    text = (
        "# Rigid Map: accuracy and speed\n\n"
        f"Produced by {command} (2 CPU cores shared with other work; load average "
        f"{os.getloadavg()[0]:.1f} at the end of the run).\n\n"
        "i.i.d. rows: teaching samples from the region's density; stroke rows: "
        f"{args.strokes} samples of synthetic hand strokes (`trajectory_samples`: continuous "
        "strokes 0.3 deg apart, slow edge strokes, gaps between strokes).\n\n"
        "Targets for `correct`: mean angle <= 0.5 deg; >= 99% valid unchanged; "
        ">= 99.5% inside or within 1 deg.\n\n"
        f"## Accuracy\n\n{acc}\n\n## Speed\n\n{speed}\n\n## Start-up\n\n{start}\n"
    )
    print(text)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text)


if __name__ == "__main__":
    main()
