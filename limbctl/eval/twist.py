"""`limbctl eval`'s twist experiment: ``RigidMap(twist=True).correct()`` on a learned
ShoulderRegion and the engines' clamp on the true one, against the true nearest orientation."""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from limbctl.envelope import RigidMap
from limbctl.envelope.synthetic import _cap_directions, rounded
from limbctl.envelope.synthetic_twist import SHOULDER, ShoulderRegion
from limbctl.geometry.quat import geodesic_distance
from limbctl.geometry.twist import compose


@dataclass(frozen=True)
class TwistScale:
    """Teaching (uniform, edge, stops), commands, seeds, truth lattice (deg) and the map's nodes."""

    teaching: tuple[int, int, int]
    commands: int
    seeds: tuple[int, ...]
    truth_step_deg: float
    nodes: int


#: The experiment's sizes by eval scale: full is a 60 s teaching at 125 Hz (7500 samples).
SCALES = {
    "full": TwistScale((2500, 1900, 3100), 4000, (0, 1, 2), 0.25, 2000),
    "quick": TwistScale((2500, 1900, 3100), 2000, (0,), 0.4, 2000),
    "smoke": TwistScale((700, 500, 800), 400, (0,), 0.6, 200),
}
FIELDS = tuple(
    "seed outside learned_mean_deg learned_p95_deg clamp_mean_deg clamp_p95_deg deep "
    "deep_unchanged within_1deg".split()
)


def trial(scale: TwistScale, seed: int) -> dict[str, float]:
    """One teaching and its commands: the figures of :data:`FIELDS`."""
    truth = ShoulderRegion(rounded(SHOULDER))
    rng = np.random.default_rng(seed)
    taught = truth.teaching(*scale.teaching, rng)
    model = RigidMap(nodes=scale.nodes, seed=seed, twist=True).fit(taught)
    b = truth.boundary(scale.truth_step_deg)
    both = np.vstack([b, -b])
    tree = cKDTree(both)
    reach = truth.swing.radius + math.radians(30.0)
    d = _cap_directions(scale.commands, truth.swing.axis, reach, rng)
    c, h = truth.band(d)
    q = compose(d, c + (h + math.radians(40.0)) * rng.uniform(-1.0, 1.0, scale.commands))
    inside = truth.contains(q)
    chord, idx = tree.query(q)
    # geodesic angle of a chord between unit quaternions: 4 asin(chord / 2)
    depth = 4.0 * np.arcsin(np.clip(chord / 2.0, 0.0, 1.0))
    out = model.correct(q)
    outside = ~inside & (depth <= math.radians(30.0))
    learned = np.degrees(geodesic_distance(out[outside], both[idx][outside]))
    clamp = np.degrees(geodesic_distance(truth.clamp(q[outside]), both[idx][outside]))
    deep = inside & (depth >= math.radians(2.0))
    held = truth.contains(out)
    gap = np.zeros(out.shape[0])
    gap[~held] = np.degrees(4.0 * np.arcsin(np.clip(tree.query(out[~held])[0] / 2.0, 0.0, 1.0)))
    return {
        "seed": seed,
        "outside": int(outside.sum()),
        "learned_mean_deg": float(learned.mean()),
        "learned_p95_deg": float(np.percentile(learned, 95)),
        "clamp_mean_deg": float(clamp.mean()),
        "clamp_p95_deg": float(np.percentile(clamp, 95)),
        "deep": int(deep.sum()),
        "deep_unchanged": float(np.mean(np.all(out[deep] == q[deep], axis=1))),
        "within_1deg": float(np.mean(gap <= 1.0)),
    }


def run_twist(out: Path, scale_name: str) -> list[str]:
    """Run the experiment at ``scale_name`` into ``out`` (twist.csv, twist.md); the headline."""
    scale = SCALES[scale_name]
    done = out / "twist.csv"
    if done.exists() and f"Scale `{scale_name}`" in _read(out / "twist.md"):
        # a rerun into the same folder resumes, as the grid does: the finished table is kept
        with open(done, newline="") as fh:
            rows = [{k: float(v) for k, v in row.items()} for row in csv.DictReader(fh)]
    else:
        rows = [trial(scale, seed) for seed in scale.seeds]
        with open(done, "w", newline="") as fh:
            writer = csv.DictWriter(fh, fieldnames=FIELDS)
            writer.writeheader()
            writer.writerows(rows)
    learned = np.mean([r["learned_mean_deg"] for r in rows])
    clamp = np.mean([r["clamp_mean_deg"] for r in rows])
    headline = [
        f"twist: learned exact correction {learned:.2f} deg from the true nearest orientation "
        f"on average, the engines' clamp on the true region {clamp:.2f} deg "
        f"({sum(r['outside'] for r in rows):.0f} commands up to 30 deg outside)"
    ]
    lines = [
        "# Twist: the learned exact correction against the engines' clamp",
        "",
        f"Scale `{scale_name}`: teaching {sum(scale.teaching)} samples (uniform, edge, stops) of "
        "the rounded `SHOULDER` region with a band narrowing as the limb rises; commands up to "
        "30 deg beyond the outline and 40 deg past the band; the true nearest orientation by "
        f"brute force over the true boundary sampled {scale.truth_step_deg} deg apart.",
        "",
        "| seed | commands outside | learned correct(): mean (deg) | p95 | engines' clamp on "
        "the true region: mean (deg) | p95 | >= 2 deg inside | passed unchanged | answers "
        "within 1 deg of the true region |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['seed']:.0f} | {r['outside']:.0f} | {r['learned_mean_deg']:.3f} | "
            f"{r['learned_p95_deg']:.2f} | {r['clamp_mean_deg']:.2f} | {r['clamp_p95_deg']:.2f} "
            f"| {r['deep']:.0f} | {100 * r['deep_unchanged']:.2f} % | "
            f"{100 * r['within_1deg']:.2f} % |"
        )
    (out / "twist.md").write_text("\n".join([*lines, "", *headline, ""]))
    return headline


def _read(path: Path) -> str:
    return path.read_text() if path.exists() else ""
