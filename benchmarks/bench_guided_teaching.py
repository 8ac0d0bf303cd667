"""Guided teaching: a simulated teacher that answers the guide's requests until READY.

Run: ``.venv/bin/python benchmarks/bench_guided_teaching.py`` (writes
docs/bench_guided_teaching.md; ``--quick``: fewer commands and a coarser truth, as
bench_region_families.py's; ``--seeds``, ``--families`` (indices of its FAMILIES) to choose;
``--requests``: print where each round's requests come from).

The true regions are benchmarks/bench_region_families.py's (its families, truth, hand teaching
and figures are imported, not restated). Each is first taught by the simulator hand's scripted
path for TEACH_S s at RATE_HZ (:class:`firmware_sim.hand.Hand`, no bus). Then, while the guide
withholds READY TO TRAIN, the teacher reads the guide's requests as data and gives the hand one
visit per request (a hand description's ``visits:``, :class:`firmware_sim.hand_path.Visit`),
starting where the teaching so far ended; the hand's path before that time is unchanged (the same
seed plans the same path up to its first visit). Requests and visits:

- a place the twist guide has not seen turned both ways (a :class:`limbctl.teach.twist_guide.
  TwistPlace` judged and not turned) or a band limit the evidence could not support (the learned
  band's :class:`limbctl.region.twist_evidence.UnsupportedPlace`): ``twist`` at the place (one
  visit per PLACE_DEG cell: the hand turns both ways there);
- a stretch of swing edge the samples do not support (``region.swing.unsupported_edge``, as
  :mod:`limbctl.teach.edge_support` reports it) or an edge gap or an open hole of the coverage
  guide (:func:`limbctl.teach.guide.assess_directions`): ``edge`` near the place, at least the
  stretch's length (a settled stretch, :attr:`limbctl.region.evidence.Stretch.settled`, is not
  asked, as the recorder's guide does not ask it);
- an inside gap while the inside is not covered enough: ``twist`` at its middle (the hand's
  circle there covers it).

The verdict is the guide's: READY by coverage (:func:`~limbctl.teach.guide.assess_directions`),
every twist place turned both ways, and nothing unsupported (the learned region's band and
swing edge) -- the same "complete" as bench_region_families.py's. At most MAX_ROUNDS rounds and
MAX_EXTRA_S s of extra teaching. Per teaching: rounds, extra time, complete, and the figures of
:func:`bench_region_families.measure` before (the scripted teaching) and after (guided).
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_region_families import (  # noqa: E402
    FAMILIES,
    RATE_HZ,
    lattice_inside,
    make_truth,
    measure,
)

from firmware_sim.hand import Hand  # noqa: E402
from limbctl.envelope import RigidMap  # noqa: E402
from limbctl.envelope.synthetic_twist import BandRegion  # noqa: E402
from limbctl.geometry.gimbal import direction_to_pan_tilt, pose_quat_scalar  # noqa: E402
from limbctl.geometry.twist import decompose  # noqa: E402
from limbctl.teach.guide import READY_INSIDE_COVERED, assess_directions  # noqa: E402
from limbctl.teach.twist_guide import CELL_DEG, MIN_CELL_SAMPLES, TwistGuide  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]

#: Seconds of the hand's scripted teaching before the guide is asked: the families benchmark's
#: shorter hand teaching, which the guide never called complete (docs/bench_region_families.md).
TEACH_S = 30.0
#: Region seeds: 0-2 are bench_region_families.py's; 3 and 4 are used nowhere else.
SEEDS = (0, 1, 2, 3, 4)
#: Rounds of requests answered before the verdict is final: each round answers every request
#: the guide made; a request it repeats after being answered twice is one the hand cannot meet.
MAX_ROUNDS = 4
#: Extra teaching (s) at most: five minutes, about what a person would give a guide's requests
#: after a minute's teaching.
MAX_EXTRA_S = 300.0
#: Twist requests are grouped on the twist guide's cells (deg): one visit turns both ways there.
PLACE_DEG = CELL_DEG
#: Seconds the hand keeps wandering after its last visit before the samples are read (its move
#: under way when a request comes is finished first; this lets the last visit's twist settle).
SETTLE_S = 0.5


def truth_of(mapping: dict) -> BandRegion:
    """The true region of a hand's REGION.yaml mapping with a polygon and a twist band (as
    :func:`bench_region_families.make_truth` builds its families')."""
    hand = Hand.from_mapping(mapping, source="<truth>")
    band = np.vectorize(hand.band.limits_deg, otypes=[float, float])

    def band_deg(pan, tilt):
        low, high = band(pan, tilt)
        return 0.5 * (low + high), 0.5 * (high - low)

    return BandRegion(np.array(mapping["region"]["polygon"], dtype=float), band_deg)


def poses(hand: Hand, t_end: float) -> tuple[np.ndarray, np.ndarray]:
    """Times (N,) s and orientations (N, 4) of the hand's path on [0, t_end) at RATE_HZ."""
    t = np.arange(0.0, t_end, 1.0 / RATE_HZ)
    rows = np.radians([hand.pose_deg(float(s)) for s in t])
    return t, np.array([pose_quat_scalar(*r) for r in rows])


def requests(t: np.ndarray, q: np.ndarray, seed: int) -> tuple[list[dict], bool, str]:
    """The guide's requests for a teaching (times (N,) s, orientations (N, 4)) as visit
    mappings without a time, whether the guide calls it complete (module docstring), and where
    the requests come from, in words (``--requests`` prints it each round)."""
    d, _ = decompose(q)
    coverage = assess_directions(t, d)
    twist = TwistGuide()
    for row in q:
        twist.add(row)
    told = twist.assess()
    region = RigidMap(twist=True, seed=seed).fit(q).region
    wanted: list[dict] = []
    cells: set[tuple[int, int]] = set()

    def turn(pan: float, tilt: float) -> None:
        key = (math.floor(pan / PLACE_DEG), math.floor(tilt / PLACE_DEG))
        if key not in cells:
            cells.add(key)
            wanted.append({"at": [pan, tilt], "do": "twist"})

    for place in told.places:
        if place.samples >= MIN_CELL_SAMPLES and not place.turned:  # judged, not turned
            turn(place.pan_deg, place.tilt_deg)  # where its samples lie, inside the region
    for place in region.unsupported:
        turn(float(place.pan_deg), float(place.tilt_deg))
    asked = [s for s in region.swing.unsupported_edge if not s.settled]
    for stretch in asked:
        wanted.append(
            {
                "at": [float(stretch.pan_deg), float(stretch.tilt_deg)],
                "do": "edge",
                "length_deg": float(stretch.length_deg),
            }
        )
    if not coverage.ready:
        for gap in coverage.edge_gaps:
            wanted.append({"at": list(gap.middle_deg), "do": "edge"})
        for hole in coverage.holes:
            if hole.open and hole.edge_deg is not None:
                wanted.append({"at": list(hole.edge_deg), "do": "edge"})
        if coverage.inside_covered < READY_INSIDE_COVERED:
            for gap in coverage.inside_gaps:
                wanted.append({"at": list(gap.middle_deg), "do": "twist"})
    unturned = sum(p.samples >= MIN_CELL_SAMPLES and not p.turned for p in told.places)
    stretches = ", ".join(
        f"({s.pan_deg:+.1f}, {s.tilt_deg:+.1f}) {s.distance_deg:.2f} deg"
        + (" settled" if s.settled else " held" if s.held else "")
        for s in region.swing.unsupported_edge
    )
    gaps = ", ".join(
        f"({g.middle_deg[0]:+.1f}, {g.middle_deg[1]:+.1f})" for g in coverage.edge_gaps
    )
    why = (
        f"twist places not turned {unturned}, band places unsupported {len(region.unsupported)}; "
        f"swing stretches {len(region.swing.unsupported_edge)} [{stretches}]; coverage "
        f"{'READY' if coverage.ready else 'not ready'}: edge closed "
        f"{100 * coverage.edge_closed:.1f} %, edge gaps [{gaps}], open holes "
        f"{sum(h.open for h in coverage.holes)}, inside covered "
        f"{100 * coverage.inside_covered:.1f} %"
    )
    complete = (
        coverage.ready
        and told.cells > 0
        and told.turned == told.cells
        and not region.unsupported
        and not asked
    )
    return wanted, complete, why


def guided(mapping: dict, seed: int, teach_s: float = TEACH_S, say: bool = False) -> dict:
    """Teach for ``teach_s`` s, then answer the guide's requests round by round (module
    docstring); the taught orientations before (M, 4) and after (N, 4) and the rounds' figures.
    ``say``: print where each round's requests come from."""
    visits: list[dict] = []
    t_end = teach_s
    hand = Hand.from_mapping(mapping, seed=seed, source="<family>")
    t, q = poses(hand, t_end)
    first_q = q
    asked = []
    rounds = 0
    while True:
        wanted, complete, why = requests(t, q, seed)
        if say:
            print(f"  at {t_end:.0f} s, {len(wanted)} requests: {why}", flush=True)
        asked.append(len(wanted))
        left = sorted({v["do"] for v in wanted})
        if complete or rounds == MAX_ROUNDS or t_end - teach_s >= MAX_EXTRA_S or not wanted:
            break
        rounds += 1
        visits += [dict(v, after_s=t_end) for v in wanted]
        hand = Hand.from_mapping(dict(mapping, visits=visits), seed=seed, source="<guided>")
        hand.pose_deg(t_end + 1e3)  # plans the path through every visit (the hand is lazy)
        spans = [s for s in hand.path.visit_spans if s[2].after_s == t_end]
        t_end = (max(s[1] for s in spans) if spans else t_end) + SETTLE_S
        t, q = poses(hand, t_end)
        assert np.allclose(q[: len(first_q)], first_q), "the scripted teaching changed"
    return {
        "q_before": first_q,
        "q": q,
        "rounds": rounds,
        "extra_s": t_end - teach_s,
        "complete": complete,
        "asked": asked,
        "visits": len(visits),
        "left": left,
        "edge_closed": assess_directions(t, decompose(q)[0]).edge_closed,
    }


def worst_swing_place(truth: BandRegion, q: np.ndarray, seed: int) -> tuple[float, float, int]:
    """Where (pan_deg, tilt_deg) the region learned from ``q`` (N, 4) reaches farthest past the
    true outline (on :func:`bench_region_families.measure`'s lattice), and how many lattice
    directions lie more than 1 deg outside."""
    model = RigidMap(twist=True, seed=seed).fit(q)
    d = lattice_inside(truth, 15.0)
    depth = truth.swing.depth(d)
    mine = np.flatnonzero(model.region.swing.mesh.contains(d))
    k = mine[np.argmin(depth[mine])]
    pan, tilt = direction_to_pan_tilt(d[k])
    return math.degrees(pan), math.degrees(tilt), int(np.sum(depth[mine] < -math.radians(1.0)))


def run(
    quick: bool,
    seeds: tuple[int, ...],
    families: tuple[str, ...],
    where: bool = False,
    say: bool = False,
) -> list[dict]:
    """Every family and seed; one row each."""
    rows = []
    for family in families:
        for seed in seeds:
            start = time.perf_counter()
            truth, mapping = make_truth(family, seed)
            g = guided(mapping, seed, say=say)
            before = measure(truth, g["q_before"], seed, quick)
            after = measure(truth, g["q"], seed, quick)
            inside = float(np.mean(truth.contains(g["q"])))
            if where:
                row_where = worst_swing_place(truth, g["q"], seed)
                print(
                    f"worst swing excess at pan {row_where[0]:+.1f}, tilt {row_where[1]:+.1f}; "
                    f"{row_where[2]} directions more than 1 deg outside",
                    flush=True,
                )
            row = {"family": family, "seed": seed, "inside": inside}
            keys = ("rounds", "extra_s", "complete", "asked", "visits", "left", "edge_closed")
            row.update({k: g[k] for k in keys})
            row.update(samples=len(g["q"]), before=before, after=after)
            row["seconds"] = time.perf_counter() - start
            print(_line(row), flush=True)
            rows.append(row)
    return rows


def _line(r: dict) -> str:
    a, b = r["after"], r["before"]
    return (
        f"{r['family']} seed {r['seed']}: {r['rounds']} rounds, +{r['extra_s']:.0f} s, "
        f"requests {r['asked']}, complete {r['complete']} (measure: {a['complete']}); swing "
        f"+{b['swing_excess']:.2f} -> +{a['swing_excess']:.2f}, twist +{b['twist_excess']:.2f} "
        f"-> +{a['twist_excess']:.2f} deg, coverage {100 * b['coverage']:.2f} -> "
        f"{100 * a['coverage']:.2f} %, error {a['err_mean']:.3f} (p95 {a['err_p95']:.2f}), "
        f"taught inside {100 * r['inside']:.1f} %, {r['seconds']:.0f} s"
    )


def write(rows: list[dict], path: Path, command: str) -> None:
    """The markdown report (figures only; the reading is written by hand below a marker)."""
    load = os.getloadavg()[0]
    lines = [
        "# Guided teaching: the simulator hand answers the guide until READY",
        "",
        f"Produced by `{command}` (2 CPU cores shared with other work; load average {load:.1f} "
        "at the end of the run).",
        "",
        f"Each true region of benchmarks/bench_region_families.py is taught by the simulator "
        f"hand's scripted path for {TEACH_S:.0f} s, then the hand visits every place the guide "
        f"names (benchmarks/bench_guided_teaching.py), at most {MAX_ROUNDS} rounds and "
        f"{MAX_EXTRA_S:.0f} s. Before: the scripted teaching alone; after: with the visits. "
        "Excess: how far the learned region reaches past the truth (target <= 1 deg); coverage: "
        "the true region 2 deg inside held; error: `correct()` to the true nearest orientation.",
        "",
        "| family | seed | rounds | extra (s) | requests per round | complete | swing excess "
        "before -> after (deg) | twist excess before -> after (deg) | coverage before -> "
        "after | error mean | p95 |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        a, b = r["after"], r["before"]
        lines.append(
            f"| {r['family']} | {r['seed']} | {r['rounds']} | {r['extra_s']:.0f} | "
            f"{', '.join(map(str, r['asked']))} | {'yes' if r['complete'] else 'no'} | "
            f"{b['swing_excess']:.2f} -> **{a['swing_excess']:.2f}** | {b['twist_excess']:.2f} "
            f"-> **{a['twist_excess']:.2f}** | {100 * b['coverage']:.2f} -> "
            f"{100 * a['coverage']:.2f} % | {a['err_mean']:.3f} | {a['err_p95']:.2f} |"
        )
    done = [r for r in rows if r["complete"]]
    lines += ["", "## Summary", ""]
    lines.append(f"- complete: {len(done)} of {len(rows)} guided teachings.")
    if rows:
        lines.append(
            f"- rounds: mean {np.mean([r['rounds'] for r in rows]):.1f}, most "
            f"{max(r['rounds'] for r in rows)}; extra teaching: mean "
            f"{np.mean([r['extra_s'] for r in rows]):.0f} s, most "
            f"{max(r['extra_s'] for r in rows):.0f} s."
        )
    if done:
        worst_s = max(done, key=lambda r: r["after"]["swing_excess"])
        worst_t = max(done, key=lambda r: r["after"]["twist_excess"])
        lines.append(
            f"- complete teachings: worst swing excess {worst_s['after']['swing_excess']:.2f} "
            f"deg ({worst_s['family']}, seed {worst_s['seed']}), worst twist excess "
            f"{worst_t['after']['twist_excess']:.2f} deg ({worst_t['family']}, seed "
            f"{worst_t['seed']}); coverage least "
            f"{100 * min(r['after']['coverage'] for r in done):.2f} %; error mean "
            f"{np.mean([r['after']['err_mean'] for r in done]):.3f} deg, p95 worst "
            f"{max(r['after']['err_p95'] for r in done):.2f} deg."
        )
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer commands, a coarser truth")
    parser.add_argument(
        "--families", type=int, nargs="+", default=list(range(len(FAMILIES))), help="indices"
    )
    parser.add_argument("--seeds", type=int, nargs="+", default=list(SEEDS), help="region seeds")
    parser.add_argument(
        "--where", action="store_true", help="print where the swing reaches farthest past"
    )
    parser.add_argument(
        "--requests", action="store_true", help="print where each round's requests come from"
    )
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "bench_guided_teaching.md")
    args = parser.parse_args(argv)
    families = tuple(FAMILIES[k] for k in args.families)
    rows = run(args.quick, tuple(args.seeds), families, args.where, args.requests)
    flags = " --quick" * args.quick
    if families != FAMILIES:
        flags += " --families " + " ".join(map(str, args.families))
    if tuple(args.seeds) != SEEDS:
        flags += " --seeds " + " ".join(map(str, args.seeds))
    write(rows, args.out, f".venv/bin/python benchmarks/bench_guided_teaching.py{flags}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
