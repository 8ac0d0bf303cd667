"""Does the learned swing region stay within the taught evidence? Random outlines with bays.

Run: ``nice -n 10 .venv/bin/python benchmarks/bench_swing_families.py [--quick]`` (writes
docs/bench_swing_families.md; ``--quick`` fewer outlines, prints only).

A *family* is a random swing outline in (pan, tilt) degrees: an ellipse of random semi-axes
(18-36 x 12-24 deg, centre near the rest pose) with one to three dents cut into its edge, each
either a *notch* (radial walls, 6-14 deg wide, 5-11 deg deep) or a *bay* (a smooth dent, 10-22
deg wide, 4-9 deg deep), at random places round the outline. Each outline is taught four ways:

- ``iid sparse``: 600 samples from the region's density (``PolygonRegion.sample``: dense in the
  middle, 0.3 of it at the edge);
- ``iid dense``: 6000 such samples;
- ``hand 30 s`` and ``hand 60 s``: the simulator's hand (firmware_sim/hand.py) over the outline
  as a polygon region, at 125 Hz (it traces the edge about 1 deg inside, then wanders).

Every figure is on the region alone (:class:`limbctl.region.TaughtRegion`, default settings):

- *excess* (deg): the farthest direction the learned region holds outside the true outline, the
  larger of a 0.1 deg (pan, tilt) grid over the outline's box grown by 4 deg and the region's own
  edge (``bench_region_families.edge_excess``: a grid misses a sliver thinner than its step).
  The bound is 1 deg (docs/region.md).
- *coverage*: of the grid's directions 2 deg or more inside the truth, the share the region holds.
- *correction error*: of test commands outside the truth (uniform about the outline), the angle
  between ``correct()``'s direction and the true nearest direction, mean and 95th percentile.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from firmware_sim.hand import Hand
from limbctl.envelope.synthetic import PolygonRegion, to_quaternions
from limbctl.geometry.gimbal import pan_tilt_to_direction
from limbctl.geometry.quat import direction_angle, limb_direction
from limbctl.region import TaughtRegion

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_region_families import edge_excess  # noqa: E402  (the swing excess on the edge)

ROOT = Path(__file__).resolve().parents[1]
#: Grid step (deg) of the excess and coverage scans: fine enough that the scan's own error
#: (half a diagonal, 0.07 deg) is small beside the 1 deg bound.
GRID_DEG = 0.1
#: How far (deg) past the outline's box the excess scan looks: beyond the largest margin (0.75)
#: plus the farthest a bridged bay could reach.
SCAN_PAD_DEG = 4.0
#: Teaching rate (Hz) of the hand, as the recorder samples.
RATE_HZ = 125.0
#: Test commands per teaching for the correction error.
N_TEST = 6000
TEACHINGS = ("iid sparse", "iid dense", "hand 30 s", "hand 60 s")


def random_outline(rng: np.random.Generator) -> tuple[np.ndarray, list[str]]:
    """A random outline (V, 2) in (pan, tilt) deg, counter-clockwise, and its dents' names."""
    a, b = rng.uniform(18.0, 36.0), rng.uniform(12.0, 24.0)
    centre = rng.uniform(-8.0, 8.0, size=2)
    kinds = rng.choice(["notch", "bay"], size=int(rng.integers(1, 4)))
    # dents 120 deg apart round the centre, jittered: no two overlap
    at = rng.permutation([0.0, 120.0, 240.0])[: len(kinds)] + rng.uniform(0.0, 40.0, len(kinds))
    points: list[tuple[float, float]] = []  # (angle deg, radius as a fraction of the ellipse)
    names = []
    dents = []
    for kind, c in zip(kinds, at, strict=True):
        r_here = float(np.hypot(a * np.cos(np.radians(c)), b * np.sin(np.radians(c))))
        if kind == "notch":
            width, depth = rng.uniform(6.0, 14.0), rng.uniform(5.0, 11.0)
        else:
            width, depth = rng.uniform(10.0, 22.0), rng.uniform(4.0, 9.0)
        depth = min(depth, 0.5 * r_here)
        half = float(np.degrees(0.5 * width / r_here))
        dents.append((kind, c, half, depth / r_here))
        names.append(f"{kind} {width:.0f} x {depth:.0f} deg at {c % 360:.0f}")
    for theta in np.arange(0.0, 360.0, 2.0):
        radius = 1.0
        for kind, c, half, frac in dents:
            off = abs((theta - c + 180.0) % 360.0 - 180.0)
            if off <= half:
                radius = min(
                    radius,
                    1.0
                    - frac * (1.0 if kind == "notch" else 0.5 * (1.0 + np.cos(np.pi * off / half))),
                )
        points.append((theta, radius))
    for kind, c, half, frac in dents:
        if kind == "notch":
            # radial walls: at each wall the outline steps between the ellipse and the floor
            points += [((c - half) % 360.0, 1.0), ((c - half) % 360.0 + 1e-6, 1.0 - frac)]
            points += [((c + half) % 360.0 - 1e-6, 1.0 - frac), ((c + half) % 360.0, 1.0)]
    points.sort()
    theta = np.radians([p[0] for p in points])
    radius = np.array([p[1] for p in points])
    outline = np.stack(
        [centre[0] + a * radius * np.cos(theta), centre[1] + b * radius * np.sin(theta)], axis=1
    )
    return outline, names


def teach(outline: np.ndarray, kind: str, seed: int) -> np.ndarray:
    """Taught directions (N, 3) of one teaching of ``outline`` (see the module docstring)."""
    truth = PolygonRegion(outline)
    rng = np.random.default_rng(seed)
    if kind.startswith("iid"):
        return truth.sample(600 if kind == "iid sparse" else 6000, rng)
    seconds = float(kind.split()[1])
    hand = Hand.from_mapping({"region": {"polygon": outline.tolist()}}, seed=seed)
    hand.start_from(*hand.region.center_deg)
    pose = np.radians([hand.pose_deg(t) for t in np.arange(int(seconds * RATE_HZ)) / RATE_HZ])
    return pan_tilt_to_direction(pose[:, 0], pose[:, 1])


class Scan:
    """The grid of directions about one outline, with the truth's depth where it is needed."""

    def __init__(self, outline: np.ndarray) -> None:
        self.truth = PolygonRegion(outline)
        lo, hi = outline.min(axis=0) - SCAN_PAD_DEG, outline.max(axis=0) + SCAN_PAD_DEG
        pan, tilt = np.meshgrid(
            np.arange(lo[0], hi[0], GRID_DEG), np.arange(lo[1], hi[1], GRID_DEG)
        )
        self.pan, self.tilt = pan.ravel(), tilt.ravel()
        self.d = pan_tilt_to_direction(np.radians(self.pan), np.radians(self.tilt))
        self.q = to_quaternions(self.d)
        self.inside = self.truth.contains(self.d)
        deep = self.truth.depth(self.d[self.inside])
        self.deep = np.zeros(self.d.shape[0], dtype=bool)
        self.deep[np.flatnonzero(self.inside)[deep >= np.radians(2.0)]] = True

    def excess(self, region: TaughtRegion) -> tuple[float, tuple[float, float]]:
        """The farthest (deg) the region reaches outside the truth, and where (pan, tilt) on the
        grid (nan where the grid holds none; the edge's reading may be the larger)."""
        on_edge = edge_excess(region.mesh, self.truth.depth)
        held = np.flatnonzero(np.asarray(region.contains(self.q)) & ~self.inside)
        if held.size == 0:
            return on_edge, (float("nan"), float("nan"))
        out = -self.truth.depth(self.d[held])
        k = int(np.argmax(out))
        where = (float(self.pan[held[k]]), float(self.tilt[held[k]]))
        return max(float(np.degrees(out[k])), on_edge), where

    def coverage(self, region: TaughtRegion) -> float:
        """The share of the grid 2 deg or more inside the truth the region holds."""
        return float(np.asarray(region.contains(self.q[self.deep])).mean())


def correction_error(truth: PolygonRegion, region: TaughtRegion, seed: int) -> tuple[float, float]:
    """Mean and 95th percentile (deg) of the correction error of commands outside the truth."""
    test = truth.test_directions(N_TEST, np.random.default_rng(10_000 + seed))
    test = test[~truth.contains(test)]
    out = limb_direction(region.correct(to_quaternions(test)))
    err = np.degrees(direction_angle(out, truth.ideal(test)))
    return float(err.mean()), float(np.percentile(err, 95))


def run(outlines: int, teachings=TEACHINGS, verbose: bool = True, first: int = 0) -> list[dict]:
    """One row per (outline, teaching): the figures of the module docstring, for the outlines
    of seeds ``first`` .. ``first + outlines - 1``."""
    rows = []
    for seed in range(first, first + outlines):
        outline, names = random_outline(np.random.default_rng(seed))
        scan = Scan(outline)
        for kind in teachings:
            taught = teach(outline, kind, seed)
            t0 = time.perf_counter()
            region = TaughtRegion().fit(taught)
            t_fit = time.perf_counter() - t0
            worst, where = scan.excess(region)
            mean, p95 = correction_error(scan.truth, region, seed)
            row = dict(
                seed=seed,
                dents=", ".join(names),
                teaching=kind,
                samples=taught.shape[0],
                edge=region.edge,
                excess=worst,
                where=where,
                coverage=scan.coverage(region),
                mean=mean,
                p95=p95,
                fit=t_fit,
            )
            rows.append(row)
            if verbose:
                print(
                    f"{seed:3d} {kind:10s} {row['edge']:9s} excess {worst:5.2f} at "
                    f"({where[0]:6.1f}, {where[1]:5.1f})  coverage {100 * row['coverage']:6.2f} "
                    f"%  err {mean:.3f}/{p95:.3f}  [{row['dents']}]",
                    flush=True,
                )
    return rows


def summary(rows: list[dict]) -> list[str]:
    """Markdown table lines: per teaching, the worst excess and the coverage and error spread."""
    lines = [
        "| teaching | outlines | worst excess (deg) | excess > 0.8 deg | coverage 2 deg inside, "
        "min / mean (%) | correction error mean / p95 (deg) | edges taken |",
        "|---|---|---|---|---|---|---|",
    ]
    for kind in TEACHINGS:
        sel = [r for r in rows if r["teaching"] == kind]
        if not sel:
            continue
        ex = np.array([r["excess"] for r in sel])
        cov = 100 * np.array([r["coverage"] for r in sel])
        edges = {}
        for r in sel:
            edges[r["edge"]] = edges.get(r["edge"], 0) + 1
        lines.append(
            f"| {kind} | {len(sel)} | {ex.max():.2f} | {int((ex > 0.8).sum())} | "
            f"{cov.min():.2f} / {cov.mean():.2f} | {np.mean([r['mean'] for r in sel]):.3f} / "
            f"{np.mean([r['p95'] for r in sel]):.3f} | "
            + ", ".join(f"{k} {v}" for k, v in sorted(edges.items()))
            + " |"
        )
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="3 outlines, print only")
    parser.add_argument("--outlines", type=int, default=8, help="random outlines (seeds 0..)")
    parser.add_argument("--first", type=int, default=0, help="the first outline's seed")
    parser.add_argument(
        "--out", type=Path, default=ROOT / "docs" / "bench_swing_families.md", help="report"
    )
    args = parser.parse_args()
    outlines = 3 if args.quick else args.outlines
    t0 = time.perf_counter()
    rows = run(outlines, first=args.first)
    lines = summary(rows)
    print("\n".join(lines))
    print(f"({time.perf_counter() - t0:.0f} s)")
    if args.quick:
        return
    worst = sorted(rows, key=lambda r: -r["excess"])[:8]
    text = "\n".join(
        [
            "# Swing outlines with bays and notches: does the region stay within the evidence?",
            "",
            "Written by `nice -n 10 .venv/bin/python benchmarks/bench_swing_families.py "
            f"--outlines {outlines}" + (f" --first {args.first}" if args.first else "") + "` "
            f"({outlines} random outlines, seeds {args.first}-{args.first + outlines - 1}; see "
            "its docstring for the "
            "families, the teachings and the figures). Bound: excess at most 1 deg.",
            "",
            *lines,
            "",
            "The largest excesses (outline seed, teaching, where):",
            "",
            "| seed | dents | teaching | edge | excess (deg) | at (pan, tilt) |",
            "|---|---|---|---|---|---|",
            *(
                f"| {r['seed']} | {r['dents']} | {r['teaching']} | {r['edge']} | "
                f"{r['excess']:.2f} | ({r['where'][0]:.1f}, {r['where'][1]:.1f}) |"
                for r in worst
            ),
            "",
        ]
    )
    args.out.write_text(text)


if __name__ == "__main__":
    main()
