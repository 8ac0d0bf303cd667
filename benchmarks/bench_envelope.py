"""Accuracy and speed of the Rigid Map: the papers' answer versus the exact gate, and peers.

Run: ``.venv/bin/python benchmarks/bench_envelope.py`` (writes docs/bench_envelope.md).

Accuracy, per region (cones of 20 and 90 degrees; irregular regions, dense in the middle and
sparse at the edge: a small kidney and an egg about a 20 deg cone's size, the BEAN polygon and
its rounded KIDNEY at 113 x 78 deg; 1000 teaching samples; test commands uniform within
R + min(R, 45 deg) of the axis; the ideal is the nearest valid direction): mean angle to the
ideal, valid commands (2 deg or more inside) returned unchanged, outputs inside the true
region or within 1 deg of it, and the papers' metrics
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
from edge_figure import edge_figure
from scipy.spatial import cKDTree

from firmware_sim.hand import Hand
from limbctl.envelope import RigidMap
from limbctl.envelope import rigidmap_kernels as rk
from limbctl.envelope.synthetic import (
    BEAN,
    EGG,
    KIDNEY,
    NOTCH,
    SMALL_KIDNEY,
    ConeRegion,
    PolygonRegion,
    covered,
    to_quaternions,
    traced_teaching,
    trajectory_samples,
)
from limbctl.geometry.gimbal import pan_tilt_to_direction
from limbctl.geometry.quat import direction_angle, euclidean_distance, limb_direction
from limbctl.teach.dataset import load_dataset

ROOT = Path(__file__).resolve().parents[1]


#: The simulator's irregular hand region (examples/regions/irregular.yaml), pan/tilt degrees.
IRREGULAR = np.array(
    [[-70, 5], [-66, -18], [-52, -31], [-30, -35], [-5, -32], [22, -34], [48, -30], [68, -18],
     [80, 2], [77, 26], [64, 46], [44, 58], [24, 57], [10, 44], [-4, 36], [-18, 41],
     [-36, 52], [-55, 46], [-67, 28]], dtype=float
)  # fmt: skip


#: The scripted hand's sampling: the recorder's default rate (Hz).
HAND_RATE_HZ = 125.0
#: The recorded fixture (``limbctl record --duration 20 --seed 0`` on the simulator).
HAND_FIXTURE = ROOT / "tests" / "data" / "hand_irregular_seed0_20s.limb"


def hand_samples(seconds: float, seed: int) -> np.ndarray:
    """What ``limbctl record --duration S --seed N`` records: the simulator's scripted hand
    teaching examples/regions/irregular.yaml from the rest pose, sampled at 125 Hz (limb
    directions (n, 3); a real recording follows it to ~0.06 deg, servo ticks aside)."""
    hand = Hand.from_yaml(ROOT / "examples" / "regions" / "irregular.yaml", seed=seed)
    hand.start_from(0.0, 0.0)
    t = np.arange(int(seconds * HAND_RATE_HZ)) / HAND_RATE_HZ
    pose = np.radians([hand.pose_deg(float(x)) for x in t])
    return pan_tilt_to_direction(pose[:, 0], pose[:, 1])


def score_rows(name, region, model, train, t_fit, n_test, rng, answers) -> list[list[str]]:
    """One table row per answer (``respond`` modes and/or ``correct``) of a fitted model."""
    q_train = to_quaternions(train)
    contained = np.asarray(model.contains(q_train)).mean()
    test = region.test_directions(n_test, rng)
    ideal = region.ideal(test)
    depth = region.depth(test)
    q = to_quaternions(test)
    q_ideal = to_quaternions(ideal)
    valid = depth >= np.radians(2.0)
    valid_covered = valid & covered(test, train)
    rows = []
    for label in answers:
        if label == "correct":
            out = model.correct(q)
        else:
            mode, _, k = label.partition(" k=")
            out = model.respond(q, mode, k=int(k or 8))
        d_out = limb_direction(out)
        err = np.degrees(direction_angle(d_out, ideal))
        same = np.all(out == q, axis=1)
        out_depth = region.depth(d_out)
        near = (out_depth >= -np.radians(1.0)).mean()
        worst = max(0.0, -float(np.degrees(out_depth.min())))
        mse = np.mean(euclidean_distance(out, q_ideal) ** 2)
        err3d = np.sqrt(np.mean(np.sum((d_out - ideal) ** 2, axis=1)))
        gate = label == "correct"
        rows.append(
            [
                name,
                f"correct ({model.edge} edge)" if gate else f"respond {label}",
                f"{err.mean():.3f}",
                f"{100 * same[valid].mean():.2f}",
                f"{100 * same[valid_covered].mean():.2f} ({valid_covered.sum()})",
                f"{100 * near:.2f}",
                f"{worst:.2f}",
                f"{mse:.3e}",
                f"{err3d:.3e}",
                f"{100 * contained:.2f}" if gate else "",
                f"{t_fit:.1f}" if gate else "",
            ]
        )
    return rows


def iid_regions() -> list[tuple[str, object]]:
    """The regions taught by i.i.d. samples, with their table names."""
    return [
        ("cone 20", ConeRegion(np.radians(20.0))),
        ("cone 90", ConeRegion(np.radians(90.0))),
        ("small kidney (39 x 23 deg)", PolygonRegion(SMALL_KIDNEY)),
        ("egg (48 x 26 deg)", PolygonRegion(EGG)),
        ("bean (113 x 78 deg)", PolygonRegion()),
        ("kidney (bean rounded)", PolygonRegion(KIDNEY)),
    ]


def fit(train: np.ndarray, seed: int) -> tuple[RigidMap, float]:
    model = RigidMap(nodes=2000, layout="uniform", seed=seed)
    t = time.perf_counter()
    model.fit(to_quaternions(train))
    return model, time.perf_counter() - t


def accuracy_rows(n_train: int, n_test: int, n_strokes: int, seed: int) -> list[list[str]]:
    rows = []
    papers = ["none", "geometric k=8", "correct"]
    for name, region in iid_regions():
        rng = np.random.default_rng(seed)
        train = region.sample(n_train, rng)
        model, t_fit = fit(train, seed)
        rows += score_rows(name, region, model, train, t_fit, n_test, rng, papers)
    for name, region in (
        ("strokes: irregular", PolygonRegion(IRREGULAR)),
        ("strokes: cone 30", ConeRegion(np.radians(30.0))),
    ):
        rng = np.random.default_rng(seed)
        train = trajectory_samples(region, n_strokes, rng)
        model, t_fit = fit(train, seed)
        rows += score_rows(name, region, model, train, t_fit, n_test, rng, papers)
    # an obstacle the limb must go round, its edge traced (issue 12 item 6; bench_fit.py too)
    notch = PolygonRegion(NOTCH)
    rng = np.random.default_rng(seed)
    train, _ = traced_teaching(notch, 60.0, rng)
    model, t_fit = fit(train, seed)
    name = "traced 60 s: notch (40 x 30 deg)"
    rows += score_rows(name, notch, model, train, t_fit, n_test, rng, papers)
    return rows


def seed_rows(n_train: int, n_test: int, seeds: range) -> list[list[str]]:
    """``correct``'s mean angle to the ideal over several teaching seeds, per region."""
    rows = []
    for name, region in iid_regions():
        cells, unchanged = [], []
        for seed in seeds:
            rng = np.random.default_rng(seed)
            train = region.sample(n_train, rng)
            model, _ = fit(train, seed)
            test = region.test_directions(n_test, rng)
            q = to_quaternions(test)
            out = model.correct(q)
            err = np.degrees(direction_angle(limb_direction(out), region.ideal(test)))
            valid = region.depth(test) >= np.radians(2.0)
            unchanged.append(100 * np.all(out[valid] == q[valid], axis=1).mean())
            cells.append(f"{err.mean():.3f} ({model.edge[:2]})")
        rows.append([name, *cells, f"{min(unchanged):.2f}"])
    return rows


def corner_noise_rows(n_test: int, sigmas: tuple[float, ...], repeats: int) -> list[list[str]]:
    """How exact a BEAN-shaped edge must be: the true polygon with every corner moved by
    Gaussian noise (sigma deg in pan and in tilt), commands projected exactly onto it."""
    truth = PolygonRegion()
    test = truth.test_directions(n_test, np.random.default_rng(0))
    ideal = truth.ideal(test)
    rows = []
    for sigma in sigmas:
        errs = []
        for rep in range(repeats):
            noise = np.random.default_rng(rep).normal(0.0, sigma, BEAN.shape)
            moved = PolygonRegion(BEAN + noise).ideal(test)
            errs.append(float(np.degrees(direction_angle(moved, ideal)).mean()))
        rows.append([f"{sigma:g}", f"{np.mean(errs):.3f}", f"{min(errs):.3f} .. {max(errs):.3f}"])
    return rows


def smooth_noise_rows(n_test: int, sigmas: tuple[float, ...], repeats: int) -> list[list[str]]:
    """How exact a smooth irregular edge must be: the true KIDNEY with its edge moved along
    its normal by smooth random noise (12 cosine waves, wavelengths from the whole loop down to
    a twelfth of it, scaled to standard deviation sigma deg), commands projected exactly."""
    truth = PolygonRegion(KIDNEY)
    test = truth.test_directions(n_test, np.random.default_rng(0))
    ideal = truth.ideal(test)
    # outward unit normals of the (pan, tilt) polygon, from the central difference
    tangent = np.roll(KIDNEY, -1, axis=0) - np.roll(KIDNEY, 1, axis=0)
    normal = np.column_stack([tangent[:, 1], -tangent[:, 0]])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    x, y = KIDNEY[:, 0], KIDNEY[:, 1]
    if np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) < 0:
        normal = -normal
    phase = np.arange(len(KIDNEY)) / len(KIDNEY) * 2.0 * np.pi
    rows = []
    for sigma in sigmas:
        errs = []
        for rep in range(repeats):
            rng = np.random.default_rng(rep)
            wave = sum(
                rng.normal() * np.cos(k * phase + rng.uniform(0.0, 2.0 * np.pi))
                for k in range(1, 13)
            )
            moved = PolygonRegion(KIDNEY + (sigma * wave / wave.std())[:, None] * normal)
            errs.append(float(np.degrees(direction_angle(moved.ideal(test), ideal)).mean()))
        rows.append([f"{sigma:g}", f"{np.mean(errs):.3f}", f"{min(errs):.3f} .. {max(errs):.3f}"])
    return rows


def hand_rows(n_test: int, seeds: range, durations: tuple[float, ...]) -> list[list[str]]:
    """The simulator's hand over the irregular region, and the recorded fixture."""
    region = PolygonRegion(IRREGULAR)
    rows = []
    for seed in seeds:
        for seconds in durations:
            train = hand_samples(seconds, seed)
            model, t_fit = fit(train, seed)
            rng = np.random.default_rng(seed)
            name = f"hand {seconds:g} s, seed {seed}"
            rows += score_rows(name, region, model, train, t_fit, n_test, rng, ["correct"])
    train = limb_direction(load_dataset(HAND_FIXTURE).quaternions)
    model, t_fit = fit(train, 0)
    name = f"recorded: {HAND_FIXTURE.name}"
    rows += score_rows(
        name, region, model, train, t_fit, n_test, np.random.default_rng(0), ["correct"]
    )
    return rows


def best_of(fn, repeat: int) -> float:
    best = np.inf
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t)
    return best


def reference_problem(seed: int) -> tuple[np.ndarray, np.ndarray]:
    """The training problem the speed rows time: 2000 node positions (uniform layout) and
    1000 patterns from a 45 deg cone, as (positions (2000, 4), patterns (1000, 4))."""
    rng = np.random.default_rng(seed)
    patterns = np.ascontiguousarray(to_quaternions(ConeRegion(np.radians(45.0)).sample(1000, rng)))
    return RigidMap(nodes=2000, seed=seed).positions, patterns


def train_args(max_epochs: int) -> tuple:
    """Table I's schedule for the training kernels, ``max_epochs`` at most, tol 1e-9."""
    return (1.0, 0.15, 2 * np.pi, 1.0, 0.04, max_epochs, 1e-9)


def reference_seconds(seed: int, max_epochs: int, repeat: int = 1) -> float:
    """Seconds the numpy reference of the Rigid Map rule takes on :func:`reference_problem`."""
    pos, patterns = reference_problem(seed)
    args = train_args(max_epochs)
    return best_of(lambda: rk.train_rigid_map_reference(pos, pos.copy(), patterns, *args), repeat)


def speed_rows(seed: int) -> list[list[str]]:
    rng = np.random.default_rng(seed)
    region = ConeRegion(np.radians(45.0))
    q_train = to_quaternions(region.sample(1000, rng))
    model = RigidMap(nodes=2000, seed=seed)
    model.fit(q_train)
    pos, patterns = reference_problem(seed)
    args = train_args(1000)
    t_kernel = best_of(lambda: rk.train_rigid_map(pos, pos.copy(), patterns, *args), 3)
    t_ref = reference_seconds(seed, 1000)
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
    # the same on a hand-taught model (many more boundary arcs)
    hand, _ = fit(hand_samples(60.0, seed), seed)
    hand_batch = to_quaternions(PolygonRegion(IRREGULAR).test_directions(200_000, rng))
    hand_tree = cKDTree(hand.weights)
    t_handc = best_of(lambda: hand.correct(hand_batch), 3)
    t_handt = best_of(lambda: hand_tree.query(hand_batch), 3)
    hand_outside = hand_batch[~hand.contains(hand_batch)][:500]
    t_hand1 = min(per_call(hand.correct, hand_outside) for _ in range(5))
    t_handt1 = min(per_call(hand_tree.query, hand_outside) for _ in range(5))
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
        [
            f"hand 60 s model ({hand.mesh.edges.shape[0]} arcs): correct, 1 outside command",
            f"{t_hand1 * 1e6:.1f} us",
            f"correct/tree = {t_hand1 / t_handt1:.2f}",
        ],
        [
            "hand 60 s model: correct, 200,000 commands",
            f"{t_handc * 1e3:.1f} ms",
            f"correct/tree = {t_handc / t_handt:.2f} (tree {t_handt * 1e3:.1f} ms)",
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
    header = [
        "region",
        "answer",
        "mean angle to ideal (deg)",
        "valid unchanged (%)",
        "covered valid unchanged (%) (n)",
        "inside or within 1 deg (%)",
        "worst outside (deg)",
        "quaternion MSE",
        "3D error (RMS, unit limb)",
        "training samples contained (%)",
        "fit (s)",
    ]
    acc = table(header, accuracy_rows(args.train, args.test, args.strokes, args.seed))
    seeds = range(5)
    spread = table(
        ["region", *[f"seed {s}" for s in seeds], "valid unchanged, worst seed (%)"],
        seed_rows(args.train, args.test // 2, seeds),
    )
    corners = table(
        ["corner noise sigma (deg)", "mean angle to ideal (deg)", "range over 3 draws"],
        corner_noise_rows(args.test, (0.25, 0.5, 1.0), 3),
    )
    smooth = table(
        ["edge noise sigma (deg)", "mean angle to ideal (deg)", "range over 3 draws"],
        smooth_noise_rows(args.test, (0.1, 0.25, 0.5), 3),
    )
    hand = table(header, hand_rows(args.test, range(3), (20.0, 30.0, 60.0)))
    speed = table(["what", "time", "ratio"], speed_rows(args.seed))
    start = table(["import to first correct()", "time"], startup_rows(args.seed))
    command = "`.venv/bin/python benchmarks/bench_envelope.py " + " ".join(sys.argv[1:]) + "`"
    text = (
        "# Rigid Map: accuracy and speed\n\n"
        f"Produced by {command} (2 CPU cores shared with other work; load average "
        f"{os.getloadavg()[0]:.1f} at the end of the run).\n\n"
        "i.i.d. rows: teaching samples from the region's density; stroke rows: "
        f"{args.strokes} samples of synthetic hand strokes (`trajectory_samples`: continuous "
        "strokes 0.3 deg apart, slow edge strokes, gaps between strokes); the notch row: "
        "`synthetic.NOTCH` (a 12 x 12 deg notch cut into a 40 x 30 deg rectangle) taught "
        "for 60 s by `traced_teaching` (its edge traced 1 deg inside, then wandering), its "
        "*worst outside* how far a corrected command lands in the notch "
        "(docs/bench_fit.md: the region's own reach).\n\n"
        "Columns: *valid* = test commands 2 deg or more inside the true region; *covered* = "
        "those the taught samples surround (`synthetic.covered`: samples within 6 deg leave "
        "no empty sector wider than 150 deg; the rest of the region was never taught); "
        "*worst outside* = the farthest any output lies outside the true region.\n\n"
        "Targets for `correct`: i.i.d. rows mean angle <= 0.5 deg, >= 99% valid unchanged; "
        "hand-taught rows >= 99.5% training samples contained, >= 99% covered valid "
        "unchanged; all rows >= 99.5% inside or within 1 deg and nothing more than 2 deg "
        "outside.\n\n"
        f"## Accuracy\n\n{acc}\n\n"
        "![the gate's edges on the irregular regions](figures/edges.png)\n\n"
        "The edges of the seed-0 models above (`benchmarks/edge_figure.py`): the taught "
        "samples, the true boundary, the data-supported loops and the edge the gate took.\n\n"
        "`correct (smooth edge)`: the gate took the smooth learned edge "
        "(limbctl/region/edge_smooth.py: small circles over one window); `(traced edge)`: "
        "the edge walked out station by station (limbctl/region/edge_traced.py), for "
        "shapes one window cannot follow where the edge is taught densely enough; "
        "`(supported edge)`: the data refused both (corners, or an edge taught too sparsely) "
        "and the gate kept the loops through the outermost taught samples.\n\n"
        "## Over teaching seeds\n\n"
        "`correct`'s mean angle to the ideal (deg; `sm`/`tr`/`su`: smooth/traced/supported "
        "edge), "
        f"{args.train} samples, {args.test // 2} test commands per seed.\n\n{spread}\n\n"
        "## How exact must a sharp-cornered edge be?\n\n"
        "The BEAN's test commands reach 60 deg beyond its edge, and a far command's nearest "
        "valid direction is one of its corners. Below, the TRUE polygon with each corner "
        "moved at random (Gaussian, sigma in pan and in tilt), and every command projected "
        "exactly onto it: the mean angle to the ideal that a perfect learner with corners "
        "that far off would score. For scale: 1000 BEAN samples (seed 0) put 46 within 2 deg "
        "of its 286 deg long edge (0.08 per deg^2, about 6 per 2 deg x 20 deg edge "
        f"strip).\n\n{corners}\n\n"
        "The same question for the smooth KIDNEY: its TRUE edge moved along its normal by "
        "smooth random noise (wavelengths of 24 deg and more along its 290 deg loop). A "
        "learner must place a smooth irregular edge to about 0.2 deg to reach 0.5 deg; at "
        "0.08 samples per deg^2 the outermost sample of a 26 deg stretch lies about 0.5 deg "
        "inside the edge, and so does the noise of any estimate from it. The cones reach "
        "0.1-0.2 deg because one circle fits their whole edge.\n\n"
        f"{smooth}\n\n"
        "## Hand-taught (the simulator's scripted hand over examples/regions/irregular.yaml)\n\n"
        "`hand S s, seed N`: the hand `limbctl record --duration S --seed N` records, sampled "
        "at 125 Hz without the servos (a real recording follows it to ~0.06 deg); "
        f"`recorded`: a real 20 s recording (seed 0) kept as a test fixture.\n\n{hand}\n\n"
        f"## Speed\n\n{speed}\n\n## Start-up\n\n{start}\n"
    )
    print(text)
    edge_figure(args.out.parent / "figures" / "edges.png", args.seed)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text)


if __name__ == "__main__":
    main()
