"""Random operators press a felt leader past the edge and let go: how fast does it return?

Run: ``python benchmarks/bench_random_presses.py`` (writes docs/bench_random_presses.md; about
three minutes). ``--runs N --first-seed S``: operators S .. S+N-1 on two servos and S+1000 ..
S+1000+N-1 on three.

Everything runs on the stepped 200 Hz clock of the felt-leader tests
(``tests.teleop.stepped_leader.felt_at_200_hz``: the simulator in this process, today's law with
its snap watch and brake rules, an XM430-W350 leader): the law's own figures, whatever the
machine's load. Each operator is drawn from its seed, none of them used to tune anything: a
target pose 2-15 deg beyond the edge in any direction (two servos: the 30 deg cone; three: the
square region with its +-30 deg twist band), reached in 1-3 s and held 1.5-3 s, a hand of 0.03-0.3
N m/deg bounded at 0.2-0.8 N m (weaker and stronger than the wall's cap), and a let go at once
or over 20-300 ms. Per run: the push the hand feels at the let go (the motors' torque's size),
and the fastest the leader turns on any 1 ms sample after it (the size of its joints' velocity).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # for tests.teleop.stepped_leader
from limbctl.servo.control_table import ModelNumber
from limbctl.servo.leader import FELT_MODELS
from limbctl.teleop.haptic import FeelLaw
from limbctl.teleop.haptic_push import beyond_deg
from tests.teleop.stepped_leader import felt_at_200_hz, q_of, region_of

#: The documented bound on a return's speed (deg/s, docs/haptic.md).
RETURN_BOUND_DEG_S = 30.0
#: The wall's cap on the stepped clock's XM430-W350 leader (N m, whole current units).
MOTOR = FELT_MODELS[ModelNumber.XM430_W350]
CAP_NM = MOTOR.torque_of(MOTOR.units_for(FeelLaw().cap_nm))
#: Seeds of the three-servo operators start this far after the two-servo ones.
THREE_SERVO_OFFSET = 1000
#: Where the target poses are drawn (deg): wide enough to pass every edge, and kept only when
#: 2-15 deg beyond it (a press a hand makes, not a throw across the rig).
BOX_DEG, BEYOND_DEG = 70.0, (2.0, 15.0)
#: Seconds followed after the let go: the snap ends within 15 ms, the walk back within 1 s.
AFTER_S = 1.5


def operator(seed: int, joints: int) -> dict:
    """The operator of ``seed`` for a chain of ``joints`` joints: its press and its hand."""
    rng = np.random.default_rng(seed)
    region = region_of(joints)
    while True:
        pose = list(rng.uniform(-BOX_DEG, BOX_DEG, joints))
        q = q_of(*pose)
        beyond = beyond_deg(q, region.correct(q), joints)
        if BEYOND_DEG[0] <= beyond <= BEYOND_DEG[1]:
            break
    ramp = rng.uniform(1.0, 3.0)
    return {
        "pose": pose,
        "beyond": beyond,
        "ramp": ramp,
        "let_go": ramp + rng.uniform(1.5, 3.0),
        "stiffness": rng.uniform(0.03, 0.3),
        "max_torque": rng.uniform(0.2, 0.8),
        # half let go at once, half over 20-300 ms
        "release": float(rng.choice([0.0, rng.uniform(0.02, 0.3)])),
    }


def press(seed: int, joints: int) -> dict:
    """One operator's press and let go: its draw, the push held at the let go (N m), the fastest
    1 ms sample after it (deg/s) and how many samples passed the bound."""
    op = operator(seed, joints)
    script = [[0.0] * (joints + 1), [op["ramp"], *op["pose"]]]
    rows = felt_at_200_hz(
        script,
        op["let_go"] + AFTER_S,
        op["stiffness"],
        op["let_go"],
        max_torque_nm=op["max_torque"],
        release_s=op["release"],
    )
    before = [r for r in rows if r["t"] < op["let_go"]]
    after = [r for r in rows if r["t"] >= op["let_go"]]
    speeds = np.array([np.linalg.norm(r["velocity_deg_s"]) for r in after])
    return {
        **op,
        "seed": seed,
        "joints": joints,
        "held": float(np.linalg.norm(before[-1]["motor_nm"])),
        "felt": max(float(np.linalg.norm(r["motor_nm"])) for r in before),
        "peak": float(speeds.max()),
        "over": int(np.sum(speeds > RETURN_BOUND_DEG_S)),
    }


def render(runs: list[dict], command: str, seconds: float, load: tuple) -> str:
    """The report: a summary per chain, then every run."""
    out = [
        "# Random operators press a felt leader past the edge and let go",
        "",
        f"Produced by `{command}` ({seconds:.0f} s, load average {load[0]:.1f} at the start). "
        + (__doc__ or "").split("\n\n")[2].replace("\n", " ").strip(),
        "",
        f"The wall's cap: {CAP_NM:.3f} N m. The bound: {RETURN_BOUND_DEG_S:.0f} deg/s on every "
        "1 ms sample after the let go.",
        "",
        "| chain | runs | felt at most (N m) | over the bound | peak at most (deg/s) | "
        "let go at once, held >= 0.35 N m: peak | at once, held < 0.35 N m: peak | "
        "over 20-300 ms: peak |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for joints in (2, 3):
        mine = [r for r in runs if r["joints"] == joints]
        if not mine:
            continue
        strong = [r["peak"] for r in mine if r["release"] == 0.0 and r["held"] >= 0.35]
        weak = [r["peak"] for r in mine if r["release"] == 0.0 and r["held"] < 0.35]
        slow = [r["peak"] for r in mine if r["release"] > 0.0]
        over = sum(r["over"] > 0 for r in mine)
        out.append(
            f"| {joints} servos | {len(mine)} | {max(r['felt'] for r in mine):.3f} | "
            f"{over} of {len(mine)} | {max(r['peak'] for r in mine):.1f} | {_span(strong)} | "
            f"{_span(weak)} | {_span(slow)} |"
        )
    out += [
        "",
        "| seed | servos | target (deg) | beyond (deg) | hand (N m/deg) | hand bound (N m) | "
        "let go over (ms) | held at the let go (N m) | peak (deg/s) | samples over |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in runs:
        target = ", ".join(f"{v:+.1f}" for v in r["pose"])
        out.append(
            f"| {r['seed']} | {r['joints']} | {target} | {r['beyond']:.1f} | {r['stiffness']:.3f} "
            f"| {r['max_torque']:.2f} | {1000 * r['release']:.0f} | {r['held']:.3f} | "
            f"{r['peak']:.1f} | {r['over']} |"
        )
    return "\n".join(out) + "\n"


def _span(values: list[float]) -> str:
    """``min-max (n)`` of ``values``, or a dash."""
    return f"{min(values):.1f}-{max(values):.1f} ({len(values)})" if values else "-"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--runs", type=int, default=30, help="operators per chain (30)")
    parser.add_argument("--first-seed", type=int, default=5000, help="the first operator (5000)")
    parser.add_argument("--out", type=Path, default=Path("docs/bench_random_presses.md"))
    args = parser.parse_args(argv)
    load, started = os.getloadavg(), time.monotonic()
    runs = []
    for joints, first in ((2, args.first_seed), (3, args.first_seed + THREE_SERVO_OFFSET)):
        for k, seed in enumerate(range(first, first + args.runs), 1):
            run = press(seed, joints)
            runs.append(run)
            print(
                f"[{k}/{args.runs}] {joints} servos, operator {seed}: held {run['held']:.3f} N m, "
                f"peak {run['peak']:.1f} deg/s",
                flush=True,
            )
    command = "python benchmarks/bench_random_presses.py" + "".join(
        f" {a}" for a in (argv if argv is not None else sys.argv[1:])
    )
    seconds = time.monotonic() - started
    args.out.write_text(render(runs, command, seconds, load), encoding="utf-8")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
