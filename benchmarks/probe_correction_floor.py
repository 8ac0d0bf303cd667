"""Where the three-servo correction's error to the true nearest orientation comes from.

Run: ``.venv/bin/python benchmarks/probe_correction_floor.py --seeds 17,18`` (prints a table).

For the region families' teachings (benchmarks/bench_region_families.py: its truths, teachings and
commands), each command ``q`` outside the truth with ``t`` its true nearest orientation (a brute
force over the true boundary STEP_DEG apart), split by the face ``t`` lies on (swing: on the
outline; twist: on a band limit):

- ``corr``: ``angle(correct(q), t)``, what the families' benchmark reports;
- ``lrn``: ``angle(n, t)``, ``n`` the learned region's own nearest (the same brute force over the
  learned outline and band); ``exc``: how much farther from ``q`` ``correct(q)`` is than ``n``;
- ``ev``: the angle from ``t`` to the nearest taught sample; ``reach``: how close to the true
  limit at ``t`` the samples within REACH_DEG of its direction came (swing depth or twist short of
  the stop, the least); ``inset``: how far inside the truth the learned limit lies at ``t``'s
  direction (negative: past it);
- ``ideal X``: the error of the true region shrunk by X deg in swing and in twist (no learning):
  what a uniform inset alone costs.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from limbctl.envelope import RigidMap
from limbctl.envelope.synthetic import _cap_directions
from limbctl.envelope.synthetic_twist import BandRegion
from limbctl.geometry.quat import geodesic_distance
from limbctl.geometry.twist import compose, decompose, wrap

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_correction as bc  # noqa: E402  (boundary lattices)
import bench_region_families as fam  # noqa: E402  (truths, teachings)

#: Boundary lattice (deg) of every brute force: errs ~0.1 deg (the families' benchmark's).
STEP_DEG = 0.25
#: Samples this near (deg) a true nearest's direction count for its reach (a few sample spacings).
REACH_DEG = 3.0
#: Uniform insets (deg) of the ideal shrunk truths.
IDEAL_DEG = (0.0, 0.25, 0.5, 1.0)
#: Outline vertex noise (deg) of the jittered truths (the vertices lie ~3.5 deg apart).
JITTER_DEG = (0.1, 0.25, 0.5)
#: Command distance bins (deg) the error is also read in.
BINS = (0.0, 2.0, 10.0, 30.0)
TEACHINGS = ("i.i.d. sparse (1500)", "i.i.d. dense (7500)", "hand 60 s")


def faces(lat, inside, edge, band, step):
    """Boundary points (M, 4) of ``bc.boundary`` with their face (M,): 0 swing, 1 twist."""
    b = bc.boundary(lat, inside, edge, band, step)
    half = b.shape[0] // 2
    c, h = band(lat[inside])
    n_twist = 2 * int(np.sum(h < math.pi))
    face = np.r_[np.ones(n_twist), np.zeros(half - n_twist)]
    return b, np.r_[face, face]


def commands(truth, seed, n):
    """The families' benchmark's commands and their true nearest (outside, within 30 deg)."""
    lat = bc.directions_box(truth, 5.0, STEP_DEG)
    edge = truth.swing.boundary[:: max(1, int(round(STEP_DEG / 0.05)))]
    b, face = faces(lat, truth.swing.contains(lat), edge, truth.band, STEP_DEG)
    tree = cKDTree(b)
    rng = np.random.default_rng([seed, 5])
    dirs = _cap_directions(n, truth.swing.axis, truth.swing.radius + math.radians(30.0), rng)
    c, h = truth.band(dirs)
    q = compose(dirs, c + (h + math.radians(40.0)) * rng.uniform(-1.0, 1.0, n))
    t, dist = bc.nearest(tree, q)
    keep = ~truth.contains(q) & (dist <= math.radians(30.0))
    return q[keep], t[keep], face[tree.query(q[keep])[1]].astype(int)


def ideal(truth, q, t, inset_deg):
    """Error (deg) of the true region shrunk by ``inset_deg`` in swing and twist."""
    x = math.radians(inset_deg)
    lat = bc.directions_box(truth, 2.0, STEP_DEG / 2)
    depth = truth.swing.depth(lat)
    edge = lat[np.abs(depth - x) <= math.radians(STEP_DEG / 4)]
    band = lambda d: (truth.band(d)[0], truth.band(d)[1] - x)  # noqa: E731
    tree = cKDTree(bc.boundary(lat, depth >= x, edge, band, STEP_DEG))
    return np.degrees(geodesic_distance(bc.nearest(tree, q)[0], t))


def jittered(truth, q, t, sigma_deg, seed):
    """Error (deg) of the true band over the true outline with its vertices moved by Gaussian
    noise ``sigma_deg`` (deg, pan and tilt): a shape error without an inset."""
    rng = np.random.default_rng([seed, 77])
    poly = np.degrees(truth.swing.polygon)
    other = BandRegion(poly + rng.normal(0.0, sigma_deg, poly.shape), truth.band_deg)
    lat = bc.directions_box(other, 5.0, STEP_DEG)
    edge = other.swing.boundary[:: max(1, int(round(STEP_DEG / 0.05)))]
    tree = cKDTree(bc.boundary(lat, other.swing.contains(lat), edge, other.band, STEP_DEG))
    return np.degrees(geodesic_distance(bc.nearest(tree, q)[0], t))


def decompose_teaching(truth, q_taught, seed, q, t, face):
    """Per-command figures (dict of (N,) arrays, deg) of one teaching (module docstring)."""
    model = RigidMap(twist=True, seed=seed).fit(q_taught)
    mesh, lband = model.region.swing.mesh, model.region.band.at
    lat = bc.directions_box(truth, bc.EDGE_RING_DEG + 2.0, STEP_DEG)
    mine = mesh.contains(lat)
    edge = bc.learned_edge(mesh, lat, mine)
    n, n_dist = bc.nearest(cKDTree(bc.boundary(lat, mine, edge, lband, STEP_DEG)), q)
    a = model.correct(q)
    s_q = np.vstack([q_taught, -q_taught])
    ev = bc.nearest(cKDTree(s_q), t)[1]
    d_t, tau_t = decompose(t)
    d_s, tau_s = decompose(q_taught)
    tc, th = truth.band(d_t)
    side = np.sign(wrap(tau_t - tc))
    near = cKDTree(d_s).query_ball_point(d_t, 2.0 * math.sin(math.radians(REACH_DEG) / 2.0))
    s_depth = truth.swing.depth(d_s)
    sc, sh = truth.band(d_s)
    reach = np.full(len(q), np.nan)
    for i, idx in enumerate(near):
        if not idx:
            continue
        if face[i] == 0:
            reach[i] = s_depth[idx].min()
        else:
            reach[i] = np.min(side[i] * wrap(sc[idx] + side[i] * sh[idx] - tau_s[idx]))
    inset = np.empty(len(q))
    sw = face == 0
    e_dist = bc.nearest(cKDTree(edge), d_t[sw])[1] / 2.0  # a chord on S^2 read as on S^3
    inset[sw] = np.where(mesh.contains(d_t[sw]), -e_dist, e_dist)
    lc, lh = lband(d_t[~sw])
    s = side[~sw]
    inset[~sw] = s * wrap(tc[~sw] + s * th[~sw] - (lc + s * lh))
    deg = np.degrees
    return {
        "corr": deg(geodesic_distance(a, t)),
        "lrn": deg(geodesic_distance(n, t)),
        "exc": deg(geodesic_distance(q, a) - n_dist),
        "ev": deg(ev),
        "reach": deg(reach),
        "inset": deg(inset),
        "dist": deg(geodesic_distance(q, t)),
        "dx": deg(geodesic_distance(q, a) - geodesic_distance(q, t)),
    }


def _row(r: dict, m: np.ndarray) -> str:
    """One printed row: each measure's mean / p95 over the commands ``m``, then the search's
    misses, the reach's median, how much farther than ``t`` the answer lies, and the error by
    the command's distance (deg)."""
    cells = [
        f"{k} {np.nanmean(r[k][m]):.3f}/{np.nanpercentile(r[k][m], 95):.2f}"
        for k in ("corr", "lrn", "ev", "reach", "inset", "dist")
    ]
    exc, dx = r["exc"][m], r["dx"][m]
    by_distance = " ".join(
        f"{np.mean(r['corr'][m & (r['dist'] > lo) & (r['dist'] <= hi)]):.3f}"
        for lo, hi in zip(BINS[:-1], BINS[1:])
    )
    return (
        " | ".join(cells)
        + f" | exc p95/max {np.percentile(exc, 95):.3f}/{exc.max():.3f}"
        + f" (over 0.3: {np.sum(exc > 0.3)}) | reach median {np.nanmedian(r['reach'][m]):.3f}"
        + f" | farther than t {np.mean(dx):.3f} (p5 {np.percentile(dx, 5):.2f},"
        + f" p95 {np.percentile(dx, 95):.2f}) | by distance {by_distance}"
    )


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="17,18")
    parser.add_argument("--commands", type=int, default=fam.COMMANDS)
    parser.add_argument("--no-ideal", action="store_true")
    args = parser.parse_args(argv)
    for family in fam.FAMILIES:
        for seed in (int(v) for v in args.seeds.split(",")):
            truth, mapping = fam.make_truth(family, seed)
            q, t, face = commands(truth, seed, args.commands)
            if not args.no_ideal:
                errs = " ".join(f"{x}: {ideal(truth, q, t, x).mean():.3f}" for x in IDEAL_DEG)
                print(f"{family} seed {seed} ideal inset (deg: mean error) {errs}", flush=True)
                errs = " ".join(
                    f"{x}: {jittered(truth, q, t, x, seed).mean():.3f}" for x in JITTER_DEG
                )
                print(f"{family} seed {seed} jittered outline (deg: mean error) {errs}", flush=True)
            for name in TEACHINGS:
                taught = fam.teach(truth, mapping, fam.TEACHINGS[name], seed)
                r = decompose_teaching(truth, taught, seed, q, t, face)
                for f, label in ((0, "swing"), (1, "twist"), (None, "all")):
                    m = np.ones(len(q), bool) if f is None else face == f
                    print(f"{family} | {seed} | {name} | {label} n={m.sum()} | " + _row(r, m))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
