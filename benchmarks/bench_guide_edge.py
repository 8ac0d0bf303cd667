"""The coverage guide's edge on the region families: closed with and without a trace across a dent.

Run: ``.venv/bin/python benchmarks/bench_guide_edge.py`` (writes docs/bench_guide_edge.md;
``--seeds`` region seeds, ``--seconds`` teaching lengths).

The true regions are benchmarks/bench_region_families.py's (star-shaped outlines with two bays
and a narrow notch, every family). Each is taught by the simulator hand's own path
(:class:`firmware_sim.hand.Hand`, hand seeds ``seed`` and ``seed + 50``) for each length at
RATE_HZ, and its directions are assessed by :func:`limbctl.teach.guide.assess_directions` twice:
as it is, and with the trace across a dent (``_traced_across``) switched off, the guide before
it, as its peer. Per teaching: the share of the edge closed, the edge gaps (2 deg bins each), and
whether the guide says READY by coverage. A teaching long enough to have traced the whole edge
should close it; a short one, the hand partway round, should keep its long gaps.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_region_families import FAMILIES, RATE_HZ, make_truth  # noqa: E402

from firmware_sim.hand import Hand  # noqa: E402
from limbctl.geometry.gimbal import pan_tilt_to_direction  # noqa: E402
from limbctl.teach import guide  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
#: Hand seeds per region seed: the seed itself and this far on (another path round the same edge).
HAND_SEED_OFFSET = 50


def directions(mapping: dict, hand_seed: int, seconds: float) -> tuple[np.ndarray, np.ndarray]:
    """Times (N,) s and limb directions (N, 3) of the hand's path over ``seconds`` at RATE_HZ."""
    hand = Hand.from_mapping(mapping, seed=hand_seed, source="<family>")
    t = np.arange(0.0, seconds, 1.0 / RATE_HZ)
    pan_tilt = np.radians([hand.pose_deg(float(s))[:2] for s in t])
    return t, pan_tilt_to_direction(pan_tilt[:, 0], pan_tilt[:, 1])


def assessed(t: np.ndarray, d: np.ndarray, bridge: bool) -> guide.Guidance:
    """The guide's verdict, with the trace across a dent or (``bridge`` False) without it."""
    real = guide._traced_across
    if not bridge:
        guide._traced_across = lambda *_: np.zeros(0, dtype=np.int64)
    try:
        return guide.assess_directions(t, d)
    finally:
        guide._traced_across = real


def run(seeds: list[int], lengths: list[float]) -> list[dict]:
    rows = []
    for seconds in lengths:
        for seed in seeds:
            for family in FAMILIES:
                _, mapping = make_truth(family, seed)
                for hand_seed in (seed, seed + HAND_SEED_OFFSET):
                    t, d = directions(mapping, hand_seed, seconds)
                    before, after = assessed(t, d, False), assessed(t, d, True)
                    rows.append(
                        {
                            "seconds": seconds,
                            "family": family,
                            "seed": seed,
                            "hand": hand_seed,
                            "before": before,
                            "after": after,
                        }
                    )
                    print(_line(rows[-1]), flush=True)
    return rows


def _gaps(g: guide.Guidance) -> str:
    return ", ".join(str(round(gap.fraction * guide.EDGE_BINS)) for gap in g.edge_gaps) or "-"


def _line(r: dict) -> str:
    b, a = r["before"], r["after"]
    return (
        f"{r['seconds']:.0f} s {r['family']} seed {r['seed']} hand {r['hand']}: closed "
        f"{100 * b.edge_closed:.1f} -> {100 * a.edge_closed:.1f} %, gaps [{_gaps(b)}] -> "
        f"[{_gaps(a)}], ready {b.ready} -> {a.ready}"
    )


def write(rows: list[dict], path: Path, command: str) -> None:
    lines = [
        "# The coverage guide's edge on the region families",
        "",
        f"Produced by `{command}`. " + " ".join(__doc__.split("\n\n")[2:]).replace("\n", " "),
        "",
        "| teaching (s) | family | seed | hand seed | edge closed without -> with | gaps (bins) "
        "without -> with | READY without -> with |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        b, a = r["before"], r["after"]
        lines.append(
            f"| {r['seconds']:.0f} | {r['family']} | {r['seed']} | {r['hand']} | "
            f"{100 * b.edge_closed:.1f} -> {100 * a.edge_closed:.1f} % | {_gaps(b)} -> "
            f"{_gaps(a)} | {'yes' if b.ready else 'no'} -> {'yes' if a.ready else 'no'} |"
        )
    lines += ["", "| teaching (s) | teachings | closed without | with | READY without | with |"]
    lines.append("|---|---|---|---|---|---|")
    for seconds in sorted({r["seconds"] for r in rows}):
        part = [r for r in rows if r["seconds"] == seconds]
        b = [r["before"].edge_closed for r in part]
        a = [r["after"].edge_closed for r in part]
        lines.append(
            f"| {seconds:.0f} | {len(part)} | {100 * min(b):.1f}-{100 * max(b):.1f} % | "
            f"{100 * min(a):.1f}-{100 * max(a):.1f} % | {sum(r['before'].ready for r in part)} | "
            f"{sum(r['after'].ready for r in part)} |"
        )
    path.write_text("\n".join(lines) + "\n")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[3, 4, 7, 14, 15, 16])
    parser.add_argument("--seconds", type=float, nargs="+", default=[10.0, 60.0])
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "bench_guide_edge.md")
    args = parser.parse_args(argv)
    rows = run(args.seeds, args.seconds)
    command = "python benchmarks/bench_guide_edge.py " + " ".join(argv or sys.argv[1:])
    write(rows, args.out, command.strip())
    return 0


if __name__ == "__main__":
    sys.exit(main())
