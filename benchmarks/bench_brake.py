"""The brake rules over the pty: a hand pulls a held felt leader back inside, again and again.

Run: ``python benchmarks/bench_brake.py [--runs N]`` (writes docs/bench_brake.md; about a
minute per ten runs).

The real 200 Hz loop through the real dynamixel-sdk on the simulator's pty (as
docs/bench_haptic.md's push case): the simulated operator presses the XM430-W350 leader 20 deg
beyond a 30 deg cone's edge (pan 50) in 2 s, holds it there to 4 s, then heads back inside
(target pan 50 -> 0 in 0.2 s, a 0.05 N m/deg hand bounded at 0.3 N m). The servo's setpoint
walks at 13.7 deg/s; the hand takes the leader faster, so the servo's loop would brake it:
an outward pull while it is still outside. Today's source (round 9: the snap watch with its
brake rules, limbctl/teleop/brake.py, judging each cycle's read as soon as it is read, a freed
wall back only on two still cycle reads, and the walking lead of limbctl/teleop/haptic.py)
against round 8's (the brake rules without those three) and round 7's (the snap rule alone,
no brake rules), in turn in one run. Counted on the simulator's ground truth
from 4 s on: samples outside the region with the motor pulling outward (their number, the
largest, the span from the first to the last), samples inside with any torque, and how the
wall was let go (the brake rules, the snap rule). The pty's timing varies from run to run (the
watch's reads come 1-3 ms apart, around the cycle's own work), so each source runs several
times.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np
from felt_harness import EDGE_DEG, HAND, pan_of, run_case

from limbctl.teleop.brake import BrakeLaw
from limbctl.teleop.haptic import VELOCITY_UNIT_DEG_S, FeelLaw
from limbctl.teleop.snap import SnapLaw, SnapWatch

#: Pressed 20 deg beyond by 2 s, held to 4 s, pulled back to the middle by 4.2 s.
PULL = [[0.0, 0.0, 0.0], [2.0, EDGE_DEG + 20.0, 0.0], [4.0, EDGE_DEG + 20.0, 0.0], [4.2, 0.0, 0.0]]
PULL_S = 4.0
#: Round 8's law: no walking lead.
ROUND8_LAW = FeelLaw(walk_lead_ticks=0)
#: The wall's setpoint speed (deg/s) the brake rules compare with.
WALK_DEG_S = FeelLaw().profile_velocity_units() * VELOCITY_UNIT_DEG_S
#: The sources compared: label, the watch factory and the law (None: the source's own, today's).
SOURCES = (
    ("today (round 9)", None, None),
    (
        "round 8",
        lambda: SnapWatch(SnapLaw(), brake=BrakeLaw(), walk_deg_s=WALK_DEG_S),
        ROUND8_LAW,
    ),
    ("without the brake rules (round 7)", lambda: SnapWatch(SnapLaw()), ROUND8_LAW),
)


def pull_once(workdir: Path, name: str, watch, law) -> dict:
    """One pull back over the pty; what the ground truth shows from the pull on."""
    operator = {"script": PULL, **HAND}
    _, source, _, rows = run_case(workdir, name, operator, 4.6, watch=watch, law=law)
    t = np.array([r["t"] for r in rows])
    pan, motor = pan_of(rows), pan_of(rows, "motor_nm")
    after = t >= PULL_S
    # toward the region is pan decreasing: the motor pulls outward where its torque is > 0
    outward = after & (pan > EDGE_DEG) & (motor > 0.0)
    return {
        "outward": int(np.sum(outward)),
        "largest": float(np.max(motor[outward], initial=0.0)),
        "span_ms": float(np.ptp(t[outward]) * 1e3) if outward.any() else 0.0,
        "inside": int(np.sum(after & (pan < EDGE_DEG) & (motor != 0.0))),
        "brakes": source.snap.brakes,
        "cuts": source.snap.cuts,
        "reads": source.snap.reads,
    }


def render(results: dict, runs: int, load, end_load, seconds: float) -> str:
    lines = [
        "# The brake rules over the pty: a hand pulls a held leader back inside",
        "",
        "`python benchmarks/bench_brake.py`: the real 200 Hz loop over the simulator's pty, an "
        "XM430-W350 leader pressed 20 deg beyond a 30 deg cone's edge, held, then pulled back "
        "to the middle (target pan 50 -> 0 in 0.2 s, hand 0.05 N m/deg, at most 0.3 N m). "
        "Counted on the simulator's 1 ms ground truth from the pull on: samples outside the "
        "region with the motor pulling outward, samples inside with any torque; how the wall "
        "was let go: by the brake rules or the snap rule (the law's own cycle rules otherwise). "
        f"{runs} runs of each source, alternately. Load at start {load[0]:.2f}, at the end "
        f"{end_load[0]:.2f} (1 min; 2 cores, shared); {seconds:.0f} s.",
        "",
        "| source | runs with an outward sample | outward samples, summed | most in one run | "
        "largest outward (N m) | longest span (ms) | inside with torque | let go by the brake "
        "rules / the snap rule (runs) |",
        "| --- | ---: | ---: | ---: | ---: | ---: | ---: | --- |",
    ]
    for label, rows in results.items():
        lines.append(
            f"| {label} | {sum(1 for r in rows if r['outward'])} of {len(rows)} | "
            f"{sum(r['outward'] for r in rows)} | {max(r['outward'] for r in rows)} | "
            f"{max(r['largest'] for r in rows):.3f} | {max(r['span_ms'] for r in rows):.1f} | "
            f"{sum(r['inside'] for r in rows)} | {sum(1 for r in rows if r['brakes'])} / "
            f"{sum(1 for r in rows if r['cuts'])} |"
        )
    lines += [
        "",
        "Each run (outward samples, largest in N m, span in ms; the watch's reads):",
        "",
        "| source | run | outward | largest (N m) | span (ms) | watch reads |",
        "| --- | ---: | ---: | ---: | ---: | ---: |",
    ]
    for label, rows in results.items():
        lines += [
            f"| {label} | {k + 1} | {r['outward']} | {r['largest']:.3f} | {r['span_ms']:.1f} | "
            f"{r['reads']} |"
            for k, r in enumerate(rows)
        ]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, default=Path("docs/bench_brake.md"))
    parser.add_argument("--runs", type=int, default=10, help="runs of each source (10)")
    args = parser.parse_args(argv)
    if args.runs < 1:
        parser.error("--runs must be at least 1")
    load, started = os.getloadavg(), time.monotonic()
    results: dict[str, list[dict]] = {label: [] for label, _, _ in SOURCES}
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(args.runs):
            for label, watch, law in SOURCES:
                results[label].append(pull_once(Path(tmp), f"pull-{k}", watch, law))
                print(f"run {k + 1}/{args.runs} {label}: {results[label][-1]}", flush=True)
    text = render(results, args.runs, load, os.getloadavg(), time.monotonic() - started)
    args.out.write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
