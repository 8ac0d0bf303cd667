"""Time to reach a command inside a non-convex region, against its distance at the slew limit.

Random outlines with a bay and a notch (``tests.teleop.bays``), seeds the tests
do not use, on both rigs: two servos (the outline) and three (the outline under a twist band
whose centre and width vary linearly with pan and tilt). For each region, random start and
target poses inside; the gate starts at one and is given the other every cycle until its
written pose is within 1e-3 rad of it (or 3 x distance / step + 400 cycles pass: *not
reached*). The distance is the shortest path inside the region: of limb directions on two
servos (the outline's visibility graph), on three that plus the twist to turn (``L + |dtau|``,
the route that turns while it swings).

Part two leads one gate through random targets in turn, each from where the last was reached,
on regions *fitted* to a 60 s traced teaching of such an outline (TaughtRegion, TwistRegion:
what a model file holds, with the bays the fit drew), seeds from 2000 (``--fitted-seeds``).

Part three times the gate's ``start`` (where the roadmap is built) and ``step`` (the whole
cycle's gate work, routing included) on such fitted regions, commands jumping between random
poses inside, after one warm-up jump (the kernels compile at their first call).

    python benchmarks/bench_reach.py [--seeds 12] [--pairs 10] [--fitted-seeds 6] [--no-route]
        [--out FILE]

``--seeds 0 --fitted-seeds 0`` runs part three alone. Step times are wall clock (what a cycle
waits) and the thread's CPU time (what the gate costs, whatever else shares the cores).

``--no-route`` measures the gate as it was before routing (its sub-goal is always the target).
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # for tests.teleop.bays (the random outlines, a test helper)

from limbctl.geometry import scalar  # noqa: E402
from limbctl.geometry.gimbal import pan_tilt_roll_scalar  # noqa: E402
from limbctl.geometry.twist import decompose, wrap  # noqa: E402
from limbctl.teleop.gate import Gate, GateLimits  # noqa: E402
from tests.teleop.bays import (  # noqa: E402
    InsidePaths,
    OutlineBandRegion,
    OutlineRegion,
    bay_outline,
    inside_points,
    teaching,
)

#: The default slew step: 120 deg/s at 200 Hz (limbctl teleop's defaults).
STEP = math.radians(120.0 / 200.0)
#: Seeds of the regions measured start here: the tests use 0-99.
SEED0 = 1000
#: Seeds of the fitted regions led through targets in turn (``--fitted-seeds``).
FITTED_SEED0 = 2000
ROLL = math.radians(179.0)


def make_gate(region, rig: int):
    """A gate over ``region`` with the sim rigs' wide hard limits and the default step."""
    lo = (math.radians(-170), math.radians(-85), -ROLL)[:rig]
    hi = (math.radians(170), math.radians(85), ROLL)[:rig]
    return Gate(region, GateLimits(lo, hi, STEP, max(3.0 * STEP, math.radians(1.0))))


def start_at(gate, q: np.ndarray, rig: int) -> None:
    """Start ``gate`` at pose ``q`` (4,)."""
    if rig == 2:
        gate.start(*scalar.pan_tilt(scalar.limb(q), 0.0))
    else:
        gate.start(*pan_tilt_roll_scalar(q, 0.0, 0.0, -ROLL, ROLL))


def error(gate, q: np.ndarray, rig: int) -> float:
    """How far (rad) the gate's last pose is from ``q``."""
    chain = gate.chain
    return chain.distance(chain.point_at(gate.safe_pose), chain.point(q))


def reach(gate, target: np.ndarray, rig: int, limit: int) -> int | None:
    """Cycles until the gate's pose is within 1e-3 rad of ``target``, None past ``limit``."""
    for n in range(1, limit + 1):
        gate.step(target)
        if error(gate, target, rig) < 1e-3:
            return n
    return None


def distance(paths: InsidePaths, a: np.ndarray, b: np.ndarray, rig: int) -> tuple[float, bool]:
    """The distance (rad) a reach needs: the shortest path of directions inside, plus the
    twist to turn on three servos; and whether that path of directions is bent (0.5 deg or more
    longer than the straight way: a wall between the two)."""
    (da, ta), (db, tb) = decompose(a), decompose(b)
    length = paths.length(da, db)
    bent = length > float(np.arccos(np.clip(da @ db, -1.0, 1.0))) + math.radians(0.5)
    return (length if rig == 2 else length + abs(float(wrap(tb - ta)))), bent


def reach_table(rig: int, seeds: int, pairs: int, route: bool) -> list[dict]:
    """One row per start/target pair: its distance, whether bent, cycles."""
    rows = []
    for seed in range(SEED0, SEED0 + seeds):
        rng = np.random.default_rng(seed)
        region = OutlineRegion(bay_outline(rng)) if rig == 2 else OutlineBandRegion.random(rng)
        paths = InsidePaths(region)
        pts = inside_points(region, 2 * pairs, rng)
        for a, b in zip(pts[0::2], pts[1::2], strict=True):
            gate = make_gate(region, rig)
            if not route:
                gate.router.subgoal = lambda current, target: target
            start_at(gate, a, rig)
            length, bent = distance(paths, a, b, rig)
            n = reach(gate, b, rig, int(3 * length / STEP) + 400)
            rows.append({"seed": seed, "L": length, "bent": bent, "cycles": n})
    return rows


def fitted(rig: int, seed: int):
    """A region fitted from a 60 s traced teaching of a random outline (:func:`teaching`)."""
    from limbctl.region.taught import TaughtRegion
    from limbctl.region.twist_region import TwistRegion

    rng = np.random.default_rng(seed)
    truth = OutlineRegion(bay_outline(rng)) if rig == 2 else OutlineBandRegion.random(rng)
    samples = teaching(truth, 60.0, rng)
    return truth, (TaughtRegion() if rig == 2 else TwistRegion()).fit(samples)


def fitted_reach_table(
    rig: int, seeds: int, pairs: int, route: bool, seed0: int = FITTED_SEED0
) -> list[dict]:
    """Rows as :func:`reach_table`'s on regions *fitted* to a traced teaching (what a model file
    holds), one gate led through ``pairs`` targets in turn, each from where the last was reached
    (as an operator leads it): targets inside the truth that the fitted region contains, the
    distance measured in the truth; seeds from ``seed0``."""
    rows = []
    for seed in range(seed0, seed0 + seeds):
        truth, region = fitted(rig, seed)
        paths = InsidePaths(truth)
        pts = inside_points(truth, 20 * (pairs + 1), np.random.default_rng(seed + 1))
        pts = pts[np.asarray(region.contains(pts), dtype=bool)][: pairs + 1]
        gate = make_gate(region, rig)
        if not route:
            gate.router.subgoal = lambda current, target: target
        start_at(gate, pts[0], rig)
        at = pts[0]
        for b in pts[1:]:
            length, bent = distance(paths, at, b, rig)
            n = reach(gate, b, rig, int(3 * length / STEP) + 400)
            rows.append({"seed": seed, "L": length, "bent": bent, "cycles": n})
            at = gate.chain.quat(gate.chain.point_at(gate.safe_pose))
    return rows


def timing(rig: int, seed: int, route: bool, pairs: int) -> dict:
    """Gate ``step`` times (us) on a fitted region, commands jumping between random poses
    inside (the first cycle of each jump included)."""
    truth, region = fitted(rig, seed)
    rng = np.random.default_rng(seed + 1)
    pts = inside_points(truth, 4 * pairs, rng)
    pts = pts[np.asarray(region.contains(pts), dtype=bool)][: 2 * pairs]
    warm = make_gate(region, rig)  # the kernels compile at their first call: not timed
    start_at(warm, pts[0], rig)
    for _ in range(5):
        warm.step(pts[1])
    times, first, starts, cpu = [], [], [], []
    for a, b in zip(pts[0::2], pts[1::2], strict=True):
        gate = make_gate(region, rig)
        if not route:
            gate.router.subgoal = lambda current, target: target
            gate.router.prepare = lambda seed: None
        t0 = time.perf_counter()
        start_at(gate, a, rig)
        starts.append(time.perf_counter() - t0)
        for k in range(int(3 * error(gate, b, rig) / STEP) + 100):
            t0, c0 = time.perf_counter(), time.thread_time()
            gate.step(b)
            dt, dc = time.perf_counter() - t0, time.thread_time() - c0
            (first if k == 0 else times).append(dt)
            cpu.append(dc)
    t, f, c = 1e6 * np.asarray(times), 1e6 * np.asarray(first), 1e6 * np.asarray(cpu)
    return {
        "cpu_p99": float(np.percentile(c, 99)),
        "cpu_max": float(c.max()),
        "p50": float(np.percentile(t, 50)),
        "p99": float(np.percentile(t, 99)),
        "max": float(t.max()),
        "first_p50": float(np.percentile(f, 50)),
        "first_max": float(f.max()),
        "start_ms": 1e3 * float(np.median(starts)),
    }


def summary(rows: list[dict]) -> dict:
    """Reached count, worst ratio of time to distance / step, worst excess cycles."""
    done = [r for r in rows if r["cycles"] is not None]
    excess = [r["cycles"] - r["L"] / STEP for r in done]
    ratio = [r["cycles"] * STEP / r["L"] for r in done if r["L"] > math.radians(5.0)]
    bent = [r for r in rows if r["bent"]]
    return {
        "pairs": len(rows),
        "reached": len(done),
        "bent": len(bent),
        "bent_reached": sum(r["cycles"] is not None for r in bent),
        "excess_p50": float(np.percentile(excess, 50)) if excess else float("nan"),
        "excess_max": float(max(excess)) if excess else float("nan"),
        "ratio_max": float(max(ratio)) if ratio else float("nan"),
    }


def reach_rows(lines: list[str], table) -> None:
    """Append the reach table's header and one row per rig, ``table(rig)`` giving its rows."""
    lines += [
        "| rig | pairs | reached | bent paths | bent reached | excess cycles p50 | "
        "excess cycles max | worst time / (distance / step) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for rig in (2, 3):
        s = summary(table(rig))
        lines.append(
            f"| {rig} servos | {s['pairs']} | {s['reached']} | {s['bent']} | "
            f"{s['bent_reached']} | {s['excess_p50']:.1f} | {s['excess_max']:.1f} | "
            f"{s['ratio_max']:.3f} |"
        )
        print(lines[-1], flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=12)
    ap.add_argument("--pairs", type=int, default=10)
    ap.add_argument("--no-route", action="store_true", help="the gate as before routing")
    ap.add_argument(
        "--fitted-seeds", type=int, default=6, help="fitted regions, targets led in turn"
    )
    ap.add_argument(
        "--fitted-from",
        type=int,
        default=FITTED_SEED0,
        help=f"the first fitted region's seed (default {FITTED_SEED0}; "
        "docs/bench_reach.md says which were run)",
    )
    ap.add_argument("--timing-pairs", type=int, default=6)
    ap.add_argument("--out", default=None, help="write the tables to this markdown file")
    args = ap.parse_args()
    route = not args.no_route
    lines = [
        f"routing {'on' if route else 'off (--no-route: the gate before routing)'}; step "
        f"{math.degrees(STEP):.2f} deg; seeds {SEED0}-{SEED0 + args.seeds - 1}, "
        f"{args.pairs} pairs each",
        "",
    ]
    reach_rows(lines, lambda rig: reach_table(rig, args.seeds, args.pairs, route))
    lines += [
        "",
        f"Fitted regions (seeds {args.fitted_from}-{args.fitted_from + args.fitted_seeds - 1}), "
        f"one gate led through {args.pairs} targets in turn on each",
        "",
    ]
    if args.fitted_seeds:
        seeds, seed0 = args.fitted_seeds, args.fitted_from
        reach_rows(lines, lambda rig: fitted_reach_table(rig, seeds, args.pairs, route, seed0))
    lines += [
        "",
        "| rig (fitted region) | start ms (p50) | step p50 us | p99 us | max us | first step "
        "of a jump p50 us | its max us | CPU p99 us | CPU max us |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for rig in (2, 3):
        t = timing(rig, SEED0 + 500, route, args.timing_pairs)
        lines.append(
            f"| {rig} servos | {t['start_ms']:.0f} | {t['p50']:.0f} | {t['p99']:.0f} | "
            f"{t['max']:.0f} | "
            f"{t['first_p50']:.0f} | {t['first_max']:.0f} | {t['cpu_p99']:.0f} | "
            f"{t['cpu_max']:.0f} |"
        )
        print(lines[-1], flush=True)
    load = " / ".join(f"{x:.1f}" for x in os.getloadavg())
    lines += ["", f"{platform.machine()}, {os.cpu_count()} cores, load average {load} at the end"]
    text = "\n".join(lines) + "\n"
    print(text)
    if args.out:
        with open(args.out, "a", encoding="utf-8") as fh:
            fh.write(text + "\n")


if __name__ == "__main__":
    main()
