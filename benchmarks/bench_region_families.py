"""Region families: does the learned three-servo region stay within the taught truth?

Run: ``.venv/bin/python benchmarks/bench_region_families.py`` (writes
docs/bench_region_families.md; ``--quick``: one seed, fewer commands, a coarser truth).

True regions of the benchmark's own making, drawn from a seed (none of them the shipped ones):
a swing outline in (pan, tilt) deg, star-shaped about a random centre with random bays (smooth
dents) and a notch (a sharp narrow one), and over it a twist band whose centre and half-width
vary with pan and tilt, written as a simulator REGION.yaml ``twist:`` mapping
(:mod:`firmware_sim.twist_band`): linear, curved (quadratic terms and Gaussian bumps), or
linear about a centre near 180 deg so the band crosses +-180. Each is taught four ways:
i.i.d. samples (uniform, along the swing edge, at the twist stops: :meth:`ShoulderRegion.
teaching`), sparse (1500) and dense (7500), and the simulator hand's own paths
(:class:`firmware_sim.hand.Hand`, its poses at 125 Hz, no bus) for 30 s and 60 s;
learned by ``RigidMap(twist=True)`` as ``limbctl train`` builds it. Per teaching:

- swing excess: the farthest (deg) a direction of the learned swing region lies outside the true
  outline, read on the region's own edge (:func:`edge_excess`: its widened arcs EDGE_STEP_DEG
  apart and the round caps about their ends), where the farthest point lies; a lattice of
  directions misses a thin sliver and reads short by up to half its spacing;
- twist excess: over those directions inside the true outline, the farthest (deg) a learned
  band limit lies past the true one;
- coverage: the share of the true region's orientations 2 deg or more inside (swing and twist;
  a lattice of directions, PROBE_TWISTS twists each) the learned region contains;
- correction: ``correct()``'s mean and p95 geodesic error (deg) to the true nearest orientation
  (brute force over the true boundary sampled TRUTH_STEP_DEG apart) for commands outside, up to
  30 deg; and how much farther from the command the answer lies than that nearest orientation
  (mean, deg): where two places of the true boundary lie almost equally near a command, a small
  difference of shape moves the answer far from the true nearest at almost no extra distance;
- guide: whether the teaching would be called complete: the twist guide turned every place
  both ways (:class:`limbctl.teach.twist_guide.TwistGuide`) and the learned band lists no place
  the evidence could not support (:func:`limbctl.region.twist_evidence.unsupported_places`).
"""

from __future__ import annotations

import argparse
import math
import os
import time
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from firmware_sim.hand import Hand
from limbctl.envelope import RigidMap
from limbctl.envelope.synthetic import _cap_directions
from limbctl.envelope.synthetic_twist import BandRegion
from limbctl.geometry.gimbal import pan_tilt_to_direction, pose_quat_scalar
from limbctl.geometry.quat import geodesic_distance
from limbctl.geometry.twist import compose, wrap
from limbctl.region import twist_band, twist_evidence
from limbctl.region.evidence import edge_stations
from limbctl.teach.twist_guide import TwistGuide

ROOT = Path(__file__).resolve().parents[1]

#: Families: the band's form (the outline always has bays and a notch).
FAMILIES = ("linear band", "curved band with bumps", "linear band across +-180 deg")
#: Teachings: i.i.d. (uniform, edge, stops) sample counts, or the hand's seconds.
TEACHINGS = {
    "i.i.d. sparse (1500)": ("iid", (500, 400, 600)),
    "i.i.d. dense (7500)": ("iid", (2500, 1900, 3100)),
    "hand 30 s": ("hand", 30.0),
    "hand 60 s": ("hand", 60.0),
}
#: Region seeds (full run; --quick takes the first).
SEEDS = (0, 1, 2)
#: The recorder's rate (Hz) the hand's poses are read at.
RATE_HZ = 125.0
#: Lattice (deg) of directions the twist excess and coverage are read on.
LATTICE_DEG = 1.0
#: Spacing (deg) of the edge stations the swing excess is read on: reads short by at most half.
EDGE_STEP_DEG = 0.02
#: Points on each round cap about a widened arc's end: a 1 deg cap's chord errs 0.01 deg.
CAP_POINTS = 24
#: Twists per direction of the coverage probes.
PROBE_TWISTS = 9
#: The truth's boundary lattice (deg) (--quick: 0.5): the brute force errs up to ~0.15 deg at 0.25.
TRUTH_STEP_DEG = 0.25
#: Commands per teaching (--quick: 800).
COMMANDS = 3000


def outline(rng: np.random.Generator) -> np.ndarray:
    """A star-shaped outline (V, 2) (pan, tilt deg) with two bays and a notch.

    ``r(phi) = R (1 + 0.06 noise) (1 - sum bays) (1 - notch)``: a bay of depth 0.25-0.45 R and
    half-width 20-35 deg of polar angle (a Gaussian dent), a notch of depth 0.35-0.5 R and
    half-width 6 deg (a triangle).
    """
    centre = np.array([rng.uniform(-20, 20), rng.uniform(-10, 15)])
    radius = rng.uniform(38.0, 50.0)
    phi = np.radians(np.arange(0.0, 360.0, 5.0))
    r = radius * (1.0 + 0.06 * rng.uniform(-1, 1, phi.size))
    for _ in range(2):
        at, depth, width = rng.uniform(0, 2 * math.pi), rng.uniform(0.25, 0.45), rng.uniform(20, 35)
        off = np.degrees(np.abs(wrap(phi - at)))
        r *= 1.0 - depth * np.exp(-0.5 * (off / width) ** 2)
    at, depth = rng.uniform(0, 2 * math.pi), rng.uniform(0.35, 0.5)
    off = np.degrees(np.abs(wrap(phi - at)))
    r *= 1.0 - depth * np.clip(1.0 - off / 6.0, 0.0, 1.0)
    pts = centre + r[:, None] * np.stack([np.cos(phi), np.sin(phi)], axis=1)
    pts[:, 1] = np.clip(pts[:, 1], -70.0, 70.0)
    return pts


def twist_mapping(family: str, rng: np.random.Generator) -> dict:
    """The band of a family as a REGION.yaml ``twist:`` mapping (random coefficients)."""
    c = [rng.uniform(-20, 20), rng.uniform(-0.35, 0.35), rng.uniform(-0.35, 0.35)]
    h = [rng.uniform(35, 60), rng.uniform(-0.25, 0.25), rng.uniform(-0.35, 0.0)]
    if family.startswith("linear band across"):
        c[0] = rng.uniform(165, 185)
    if family.startswith("curved"):
        quad = [float(v) for v in rng.uniform(-0.004, 0.004, 3)]
        bumps = [
            [float(rng.uniform(-30, 30)), float(rng.uniform(-25, 25)), float(h), float(w)]
            for h, w in zip(rng.choice([-1, 1], 2) * rng.uniform(6, 12, 2), rng.uniform(8, 14, 2))
        ]
        return {
            "centre_deg": {"linear": [float(v) for v in c], "quadratic": quad, "bumps": bumps[:1]},
            "half_width_deg": {"linear": [float(v) for v in h], "bumps": bumps[1:]},
        }
    return {"centre_deg": [float(v) for v in c], "half_width_deg": [float(v) for v in h]}


def make_truth(family: str, seed: int) -> tuple[BandRegion, dict]:
    """The true region of a family and seed and its REGION.yaml mapping (the hand's)."""
    rng = np.random.default_rng([seed, FAMILIES.index(family)])
    while True:
        poly = outline(rng)
        mapping = {
            "region": {"polygon": [[float(p), float(t)] for p, t in poly]},
            "speed_deg_s": 40,
            "twist": twist_mapping(family, rng),
        }
        try:  # refused when the half width leaves 3..170 deg somewhere: draw again
            hand = Hand.from_mapping(mapping, seed=0, source="<family>")
        except ValueError:
            continue
        band = np.vectorize(hand.band.limits_deg, otypes=[float, float])

        def band_deg(pan, tilt, band=band):
            low, high = band(pan, tilt)
            return 0.5 * (low + high), 0.5 * (high - low)

        return BandRegion(poly, band_deg), mapping


def teach(truth: BandRegion, mapping: dict, how: tuple, seed: int) -> np.ndarray:
    """Taught orientations (N, 4): i.i.d. draws or the hand's path at RATE_HZ."""
    kind, size = how
    if kind == "iid":
        return truth.teaching(*size, np.random.default_rng([seed, 99]))
    hand = Hand.from_mapping(mapping, seed=seed, source="<family>")
    rows = [hand.pose_deg(t) for t in np.arange(0.0, size, 1.0 / RATE_HZ)]
    return np.array([pose_quat_scalar(*np.radians(r)) for r in rows])


def lattice_inside(region: BandRegion, extra_deg: float) -> np.ndarray:
    """Directions (K, 3) on a LATTICE_DEG lattice of (pan, tilt) over the outline's box."""
    poly = np.degrees(region.swing.polygon)
    lo, hi = poly.min(axis=0) - extra_deg, poly.max(axis=0) + extra_deg
    tilt = np.arange(lo[1], hi[1], LATTICE_DEG)
    rows = []
    for t in tilt:
        dp = LATTICE_DEG / max(math.cos(math.radians(t)), 0.05)
        pan = np.arange(lo[0], hi[0], dp)
        rows.append(pan_tilt_to_direction(np.radians(pan), np.full(pan.shape, math.radians(t))))
    return np.vstack(rows)


def edge_excess(mesh, depth) -> float:
    """The farthest (deg) the region of ``mesh`` (a :class:`~limbctl.region.mesh.DirectionMesh`)
    lies outside a truth whose signed ``depth`` ((N, 3) -> (N,) rad, negative outside) is given:
    read on its boundary, where the farthest point of a region lies (inside, a step outward is
    still in the region and farther), unless the region closes over a pocket of the outside (a
    bay's middle may then stand farther than its bridged mouth): stations along every widened
    arc EDGE_STEP_DEG apart, and CAP_POINTS points on the round cap of radius ``m`` about each
    arc end (a widened arc holds every direction within its margin ``m`` of the arc, its ends
    included)."""
    stations, _ = edge_stations(mesh, math.radians(EDGE_STEP_DEG))
    worst = float(np.max(-depth(stations)))
    # each vertex's cap: the widest margin of the arcs that meet there
    m = np.zeros(mesh.vertices.shape[0])
    np.maximum.at(m, mesh.edges[:, 0], mesh.margins)
    np.maximum.at(m, mesh.edges[:, 1], mesh.margins)
    capped = np.flatnonzero(m > 0.0)
    if capped.size:
        x, r = mesh.vertices[capped], m[capped][:, None]
        # a tangent frame at each vertex: u from +z (or +y near the z axis), v = x cross u
        helper = np.where(np.abs(x[:, 2:3]) < 0.9, [[0.0, 0.0, 1.0]], [[0.0, 1.0, 0.0]])
        u = np.cross(helper, x)
        u /= np.linalg.norm(u, axis=1, keepdims=True)
        v = np.cross(x, u)
        for phi in np.linspace(0.0, 2.0 * math.pi, CAP_POINTS, endpoint=False):
            # the point r along the great circle from x toward the tangent cos(phi) u + sin(phi) v
            p = np.cos(r) * x + np.sin(r) * (math.cos(phi) * u + math.sin(phi) * v)
            worst = max(worst, float(np.max(-depth(p))))
    return math.degrees(max(0.0, worst))


def measure(
    truth: BandRegion, q_taught: np.ndarray, seed: int, quick: bool, step: float | None = None
) -> dict:
    """The figures of one teaching (module docstring); ``step``: the truth's boundary lattice
    (deg) the correction is judged on (None: TRUTH_STEP_DEG, 0.5 with ``quick``)."""
    model = RigidMap(twist=True, seed=seed).fit(q_taught)
    region = model.region
    d = lattice_inside(truth, 15.0)
    mine = region.swing.mesh.contains(d)
    depth = truth.swing.depth(d)
    swing_excess = edge_excess(region.swing.mesh, truth.swing.depth)
    both = mine & (depth >= 0.0)
    lc, lh = region.band.at(d[both])
    tc, th = truth.band(d[both])
    off = wrap(lc - tc)
    past = np.fmax(off + lh - th, -off + lh - th)
    twist_excess = float(np.degrees(max(0.0, past.max()))) if past.size else 0.0
    # coverage: 2 deg inside in swing and in twist
    deep = d[depth >= math.radians(2.0)]
    c, h = truth.band(deep)
    keep = h > math.radians(2.0)
    frac = np.linspace(-1.0, 1.0, PROBE_TWISTS)
    rows = np.repeat(np.flatnonzero(keep), PROBE_TWISTS)
    probes = compose(
        deep[rows], c[rows] + np.tile(frac, keep.sum()) * (h[rows] - math.radians(2.0))
    )
    coverage = float(np.mean(model.contains(probes)))
    # correction against the true nearest
    step = step or (0.5 if quick else TRUTH_STEP_DEG)
    b = truth.boundary(step)
    tree = cKDTree(np.vstack([b, -b]))
    rng = np.random.default_rng([seed, 5])
    n = 800 if quick else COMMANDS
    dirs = _cap_directions(n, truth.swing.axis, truth.swing.radius + math.radians(30.0), rng)
    c, h = truth.band(dirs)
    q = compose(dirs, c + (h + math.radians(40.0)) * rng.uniform(-1.0, 1.0, n))
    chord, idx = tree.query(q)
    dist = 4.0 * np.arcsin(np.clip(chord / 2.0, 0.0, 1.0))
    outside = ~truth.contains(q) & (dist <= math.radians(30.0))
    answer = model.correct(q[outside])
    err = np.degrees(geodesic_distance(answer, tree.data[idx[outside]]))
    farther = np.degrees(geodesic_distance(answer, q[outside]) - dist[outside])
    # the guide: every place turned both ways, no unsupported stretch
    guide = TwistGuide()
    for row in q_taught:
        guide.add(row)
    told = guide.assess()
    places = region.unsupported
    # the swing guide's check (limbctl/teach/edge_support.py): stretches the edge would bridge
    # a settled stretch (held where the learned edge stood near the samples) is not asked
    stretches = [s for s in region.swing.unsupported_edge if not s.settled]
    return {
        "swing_excess": swing_excess,
        "twist_excess": twist_excess,
        "coverage": coverage,
        "err_mean": float(err.mean()),
        "err_p95": float(np.percentile(err, 95)),
        "farther_mean": float(farther.mean()),
        "complete": (told.cells > 0 and told.turned == told.cells and not places and not stretches),
        "places": len(places),
        "stretches": len(stretches),
    }


def run(
    quick: bool,
    seeds: tuple[int, ...] | None = None,
    step: float | None = None,
    teachings: tuple[str, ...] = tuple(TEACHINGS),
) -> list[dict]:
    """Every family, seed (``seeds``, else SEEDS, the first with ``quick``) and teaching of
    ``teachings``, the correction judged on a truth lattice ``step`` deg apart (None: default)."""
    rows = []
    for family in FAMILIES:
        for seed in seeds or (SEEDS[:1] if quick else SEEDS):
            truth, mapping = make_truth(family, seed)
            for name in teachings:
                how = TEACHINGS[name]
                start = time.perf_counter()
                q = teach(truth, mapping, how, seed)
                inside = float(np.mean(truth.contains(q)))
                row = {"family": family, "seed": seed, "teaching": name, "samples": len(q)}
                row.update(measure(truth, q, seed, quick, step), inside=inside)
                row["seconds"] = time.perf_counter() - start
                print(_line(row), flush=True)
                rows.append(row)
    return rows


def _line(r: dict) -> str:
    return (
        f"{r['family']} seed {r['seed']} {r['teaching']}: swing +{r['swing_excess']:.2f}, twist "
        f"+{r['twist_excess']:.2f} deg, coverage {100 * r['coverage']:.2f} %, error "
        f"{r['err_mean']:.3f} (p95 {r['err_p95']:.2f}, {r['farther_mean']:+.3f} farther), "
        f"complete {r['complete']} "
        f"({r['places']} places, {r['stretches']} edge stretches), taught inside "
        f"{100 * r['inside']:.1f} %, {r['seconds']:.0f} s"
    )


def write(rows: list[dict], path: Path, quick: bool, command: str) -> None:
    """The markdown report."""
    load = os.getloadavg()[0]
    lines = [
        "# Region families: the learned three-servo region against its truth",
        "",
        f"Produced by `{command}` (2 CPU cores shared with other work; load average {load:.1f} "
        "at the end of the run).",
        "",
        "Families of true regions drawn from seeds (benchmarks/bench_region_families.py: star-"
        "shaped outlines with two bays and a notch; twist bands linear in pan and tilt, curved "
        "with quadratic terms and bumps, or linear about a centre near 180 deg), taught by "
        "i.i.d. samples and by the simulator hand's paths, learned by `RigidMap(twist=True)`. "
        "Excess: how far the learned region reaches past the truth (target <= 1 deg); coverage: "
        "the true region 2 deg inside held; error: `correct()` to the true nearest orientation "
        "(target mean <= 0.5 deg); farther: how much farther from the command the answer lies "
        "than the true nearest (near ties of the true boundary move the answer far at almost no "
        "cost); complete: the guide would say READY (every place turned both "
        "ways, no unsupported stretch); places: stretches the band could not support; edge: "
        "stretches of the swing edge the samples do not reach, settled ones not counted "
        "(limbctl/teach/edge_support.py).",
        "",
        "| family | seed | teaching | samples | swing excess (deg) | twist excess (deg) "
        "| coverage 2 deg inside | error mean (deg) | p95 | farther than the nearest, mean (deg) "
        "| complete | places | edge |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['family']} | {r['seed']} | {r['teaching']} | {r['samples']} | "
            f"{r['swing_excess']:.2f} | **{r['twist_excess']:.2f}** | {100 * r['coverage']:.2f} % "
            f"| {r['err_mean']:.3f} | {r['err_p95']:.2f} | {r['farther_mean']:+.3f} "
            f"| {'yes' if r['complete'] else 'no'} "
            f"| {r['places']} | {r['stretches']} |"
        )
    lines += ["", "## Per family", ""]
    lines += [
        "| family | worst swing excess | worst twist excess | coverage (complete teachings), "
        "least | error mean (all), mean | error p95, worst | READY withheld |",
        "|---|---|---|---|---|---|---|",
    ]
    for family in FAMILIES:
        fr = [r for r in rows if r["family"] == family]
        done = [r["coverage"] for r in fr if r["complete"]]
        least = f"{100 * min(done):.2f} %" if done else "none complete"
        lines.append(
            f"| {family} | {max(r['swing_excess'] for r in fr):.2f} | "
            f"{max(r['twist_excess'] for r in fr):.2f} | {least} | "
            f"{np.mean([r['err_mean'] for r in fr]):.3f} | "
            f"{max(r['err_p95'] for r in fr):.2f} | "
            f"{sum(not r['complete'] for r in fr)} of {len(fr)} |"
        )
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one seed, fewer commands")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "bench_region_families.md")
    parser.add_argument(
        "--no-cap", action="store_true", help="the band without its evidence cap (as before)"
    )
    parser.add_argument(
        "--cone-only",
        dest="cone_only",
        action="store_true",
        help="the evidence cap as a fixed cone only (before it read the local slope)",
    )
    parser.add_argument(
        "--seeds",
        type=lambda text: tuple(int(v) for v in text.split(",")),
        help="region seeds, e.g. 3,4,5 (default 0,1,2; --quick: 0); 0-2 tuned the cap",
    )
    parser.add_argument(
        "--truth-step",
        dest="truth_step",
        type=float,
        help=f"the true boundary's lattice (deg) the correction error is judged on (default "
        f"{TRUTH_STEP_DEG}, --quick 0.5): a perfect answer scores about 0.2 deg at 0.5",
    )
    parser.add_argument(
        "--teachings",
        type=lambda text: tuple(v.strip() for v in text.split(",")),
        help="only the teachings whose names contain these words, e.g. dense "
        f"(names: {'; '.join(TEACHINGS)})",
    )
    args = parser.parse_args(argv)
    teachings = tuple(TEACHINGS)
    if args.teachings:
        teachings = tuple(n for n in TEACHINGS if any(w in n for w in args.teachings))
        if not teachings:
            parser.error(f"no teaching matches {args.teachings}; the names: {list(TEACHINGS)}")
    if args.truth_step is not None and not 0.05 <= args.truth_step <= 2.0:
        parser.error("--truth-step must be 0.05-2.0 deg (finer costs memory and time)")
    if args.no_cap:  # the band as read before the cap: limits kept, nothing cut
        twist_band.cap_limits = lambda up, lo, *_: (up, lo, 0.0 * up, 0.0 * lo)
    if args.cone_only:  # the fixed cone alone, as before the cap read the local slope
        twist_evidence._along_slope = lambda cone, nodes, *_: (
            *cone,
            np.zeros(len(nodes), dtype=bool),
            np.zeros(len(nodes), dtype=bool),
        )
    rows = run(args.quick, args.seeds, args.truth_step, teachings)
    flags = " --quick" * args.quick + " --no-cap" * args.no_cap + " --cone-only" * args.cone_only
    if args.seeds:
        flags += " --seeds " + ",".join(str(v) for v in args.seeds)
    if args.truth_step is not None:
        flags += f" --truth-step {args.truth_step:g}"
    if args.teachings:
        flags += " --teachings " + ",".join(args.teachings)
    command = f".venv/bin/python benchmarks/bench_region_families.py{flags}"
    write(rows, args.out, args.quick, command)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
