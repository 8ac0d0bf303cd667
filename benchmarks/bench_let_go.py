"""What a let go asks of the felt leader's loop: how soon the wall must go, and what the hold costs.

Run: ``python benchmarks/bench_let_go.py`` (writes docs/bench_let_go.md; about six minutes).

Everything runs on the stepped 200 Hz clock of bench_haptic's exact-rate cases (the simulator
in this process, the controller's part done on the leader servos' registers every 5 ms, its
write 1 ms after its read): the law's own figures, whatever the machine's load. A hand presses
the XM430-W350 leader beyond a cone's edge (pan 30 deg) and lets go at once: its torque drops
to 0 from one 0.5 ms physics step to the next, the hardest let go for the wall.

Three sweeps:

- *phase*: today's law (limbctl/teleop/haptic.py and haptic_push.py, with the snap watch,
  limbctl/teleop/snap.py, and its brake rules, limbctl/teleop/brake.py, a walking lead and two
  still reads to re-arm: round 9), round 7's (the snap watch without the
  brake rules) and round 6's (the law alone) in the same run, the let go falling 0-4 ms after a
  cycle's read. Without the watch the first read that can see the let go is the next one, so
  the loop's first write after it lands 6 - phase ms later; the watch reads the leader's speed
  and torque every millisecond between the cycles;
- *oracle cut*: the same presses under round 4's law, but the controller writes Goal Current 0
  (no torque) a chosen 1-6 ms after the let go, knowing when it happened: how soon a wall must
  go so that no 1 ms sample pulls the leader outward;
- *lead*: the goal's lead (1, 2, 3 ticks) against how far the wall holds the hand and how fast
  the let go snaps: the hold's cost, before any controller can act;
- *release*: the hand's bound falls to 0 over 10-100 ms instead of at once (the three laws,
  every phase), followed until the leader rests.
"""

from __future__ import annotations

import argparse
import math
import os
import time
from pathlib import Path

import numpy as np
from felt_harness import EDGE_DEG, exact_rate_case, pan_of, round4_push

from limbctl.servo.ticks import TICKS_PER_REV
from limbctl.teleop.brake import BrakeLaw
from limbctl.teleop.haptic import FeelLaw
from limbctl.teleop.haptic_push import push_for

#: The presses: hand stiffness (N m/deg) and how far beyond the edge it means to go (deg),
#: the let-go cases of docs/bench_haptic.md (the 0.2 N m/deg hand's 5 deg is the one whose
#: snap is fastest there).
PRESSES = ((0.02, 5.0), (0.05, 20.0), (0.2, 5.0), (0.2, 20.0))
#: The let go: after the hand's script has held the press for 3 s.
LET_GO_S = 5.0
#: Samples kept after the let go (s): the snap and its braking end within 15 ms; 60 ms shows
#: the walk that follows.
AFTER_S = 0.06
TICK_DEG = 360.0 / TICKS_PER_REV
#: The laws compared in the same run: round 6's (the law alone), round 7's (the snap watch) and
#: today's (round 9: the snap watch with its brake rules, a walking lead and two still reads
#: to re-arm): label, snap watch, brake rules.
LAWS = (("round 6", False, None), ("round 7", True, None), ("round 9", True, BrakeLaw()))
#: How long the hand takes to let go (ms): at once, then 10-100 ms.
RELEASES_MS = (0.0, 10.0, 20.0, 50.0, 100.0)
#: After a slow let go the run goes on this long past its end (s): the walk back from 2 deg at
#: 13.7 deg/s takes about 0.15 s.
WALK_S = 0.3


def let_go(
    stiffness: float,
    beyond: float,
    phase_ms: float = 0.0,
    push_fn=None,
    release_ms: float = 0.0,
    after_s: float = AFTER_S,
    cut_ms=None,
    watch=True,
    brake=BrakeLaw(),
):
    """One press let go ``phase_ms`` after a cycle's read; the 1 ms samples after it.

    ``push_fn``: the law (today's :func:`push_for` when None, or :func:`round4_push`).
    ``cut_ms``: the oracle writes Goal Current 0 this long after the let go (None: never).
    ``release_ms``: how long the hand takes to let go; ``after_s``: how long the run goes on.
    ``watch``: the snap watch on (only with today's law and no oracle cut); ``brake``: its
    brake rules (None: round 7's watch, the snap rule alone).
    Returns the outward samples (outside the region with the motor pulling away from it:
    count, first and last in ms after the let go, largest in N m), the 1 ms peak speed
    (deg/s), where the leader sat before the let go and where it is at the end (deg beyond the
    edge).
    """
    script = [[0.0, 0.0, 0.0], [2.0, EDGE_DEG + beyond, 0.0], [LET_GO_S, EDGE_DEG + beyond, 0.0]]
    t_let_go = LET_GO_S + phase_ms / 1000.0
    cut_s = None if cut_ms is None else t_let_go + cut_ms / 1000.0
    rows = exact_rate_case(
        stiffness,
        script,
        t_let_go + after_s,
        let_go_s=t_let_go,
        push_fn=push_fn or push_for,
        cut_s=cut_s,
        release_s=release_ms / 1000.0,
        snap_watch=watch,
        brake=brake,
    )["rows"]
    t = np.array([r["t"] for r in rows])
    pan, velocity, motor = pan_of(rows), pan_of(rows, "velocity_deg_s"), pan_of(rows, "motor_nm")
    after = t > t_let_go + 1e-9
    # toward the region is pan decreasing: the motor pulls outward where its torque is > 0
    outward = after & (pan > EDGE_DEG) & (motor > 0.0)
    when = (t[outward] - t_let_go) * 1e3
    return {
        "outward": int(np.sum(outward)),
        "first_ms": float(when.min()) if outward.any() else math.nan,
        "last_ms": float(when.max()) if outward.any() else math.nan,
        "largest": float(np.max(motor[outward], initial=0.0)),
        "peak": float(np.max(-velocity[after])),
        "held": float(pan[~after][-1] - EDGE_DEG),
        "end": float(pan[-1] - EDGE_DEG),
        "deepest": float(max(EDGE_DEG - np.min(pan[after]), 0.0)),
    }


def first_write_ms(phase_ms: float) -> float:
    """When the loop's first write after a let go lands (ms after it): the next read that can
    see it (reads every 5 ms; one at the let go's own instant still sees the hand) plus 1 ms."""
    next_read = (math.floor(phase_ms / 5.0) + 1) * 5.0
    return next_read + 1.0 - phase_ms


def lead_push(lead_ticks: int):
    """Today's push with the goal led by ``lead_ticks`` (one and a half times that beyond
    2 deg, as today's law does with its two); the motors' torque is passed on as read."""
    law = FeelLaw(lead_deg=lead_ticks * TICK_DEG)

    def push(_law, *args):
        return push_for(law, *args)

    return push


def fmt_ms(value: float) -> str:
    return "-" if math.isnan(value) else f"{value:.0f}"


def render(phases, cuts, leads, releases, load, end_load, seconds) -> str:
    law = FeelLaw()
    lines = [
        "# What a let go asks of the felt leader's loop",
        "",
        "`python benchmarks/bench_let_go.py`: the exact-rate cases of docs/bench_haptic.md "
        "(stepped 200 Hz clock, the controller's write 1 ms after its read, XM430-W350 leader, "
        f"edge at pan {EDGE_DEG:g} deg, today's law: deadband {law.deadband_deg:g} deg, "
        f"K = {law.gain_nm_per_deg:g} N m/deg, cap {law.cap_nm:g} N m, goal two ticks ahead). "
        "The hand lets go at once: its torque drops to 0 between two 0.5 ms physics steps. "
        "Outward samples are 1 ms samples after the let go with the leader outside the region "
        "and the motor pulling it away from the region. "
        f"Load at start {load[0]:.2f}, at the end {end_load[0]:.2f} (1 min; 2 cores, shared); "
        f"{seconds:.0f} s.",
        "",
        "## By where the let go falls in the 5 ms cycle",
        "",
        "Round 6's law (the law alone: its first write after the let go lands 2-6 ms after "
        "it), round 7's (the snap watch reads the leader's speed every millisecond "
        "between the cycles and lets a held wall go as it starts to snap) and today's (round 9: "
        "the same watch also reads the motors' torque and applies the brake rules; a wall "
        "walking its leader back leads two ticks more; a freed wall comes back on two still "
        "cycle reads), in this "
        "run.",
        "",
        "| hand (N m/deg) | pressed beyond (deg) | law | let go after a read (ms) | first write "
        "after it, law alone (ms) | outward samples | first, last (ms) | largest outward (N m) "
        "| 1 ms peak speed (deg/s) |",
        "| ---: | ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: |",
        *(
            f"| {r['stiffness']:g} | {r['beyond']:g} | {r['law']} | {r['phase']:g} | "
            f"{first_write_ms(r['phase']):g} | {r['outward']} | {fmt_ms(r['first_ms'])}, "
            f"{fmt_ms(r['last_ms'])} | {r['largest']:.3f} | {r['peak']:.1f} |"
            for r in phases
        ),
        "",
        "## The wall cut a chosen time after the let go (an oracle that knows when it came)",
        "",
        "Round 4's law, and Goal Current 0 written that long after the let go, nothing after: "
        "the leader coasts "
        "on its friction from there (it is not walked to the edge in these runs; end = 60 ms "
        "after the let go).",
        "",
        "| hand (N m/deg) | pressed beyond (deg) | cut after (ms) | outward samples | "
        "largest outward (N m) | 1 ms peak speed (deg/s) | beyond the edge at the end (deg) |",
        "| ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
        *(
            f"| {r['stiffness']:g} | {r['beyond']:g} | {r['cut']:g} | {r['outward']} | "
            f"{r['largest']:.3f} | {r['peak']:.1f} | {r['end']:.2f} |"
            for r in cuts
        ),
        "",
        "## The goal's lead: the hold against the snap",
        "",
        "Today's law with Goal Position led by 1, 2 (today's) or 3 ticks; let go at a read "
        "(phase 0). The snap's 1 ms peak comes 2-3 ms after the let go, before the first "
        "write of any loop slower than 333 Hz.",
        "",
        "| hand (N m/deg) | pressed beyond (deg) | lead (ticks) | held beyond the edge (deg) "
        "| 1 ms peak speed (deg/s) | outward samples |",
        "| ---: | ---: | ---: | ---: | ---: | ---: |",
        *(
            f"| {r['stiffness']:g} | {r['beyond']:g} | {r['lead']} | {r['held']:.2f} | "
            f"{r['peak']:.1f} | {r['outward']} |"
            for r in leads
        ),
        "",
        "## How fast the hand lets go",
        "",
        "The three laws; the hand's bound falls linearly to 0 over the release time. Each row "
        "is the worst of five runs, the let go falling 0, 1, 2, 3 and 4 ms after a read, "
        f"followed {WALK_S:g} s past the release: outward samples (the most in one run, and "
        "summed over the five), the "
        "1 ms peak speed, and where the leader rests (least and most beyond the edge; it never "
        "went inside in any run: deepest inside is the last column).",
        "",
        "| hand (N m/deg) | pressed beyond (deg) | release (ms) | law | outward samples | "
        "summed | largest outward (N m) | 1 ms peak speed (deg/s) | rest beyond the edge (deg) "
        "| deepest inside (deg) |",
        "| ---: | ---: | ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: |",
        *(
            f"| {r['stiffness']:g} | {r['beyond']:g} | {r['release']:g} | {r['law']} | "
            f"{r['outward']} | {r['summed']} | "
            f"{r['largest']:.3f} | {r['peak']:.1f} | {r['rest_min']:.2f}-{r['rest_max']:.2f} | "
            f"{r['deepest']:.3f} |"
            for r in releases
        ),
        "",
    ]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, default=Path("docs/bench_let_go.md"))
    args = parser.parse_args(argv)
    load, started = os.getloadavg(), time.monotonic()
    phases, cuts, leads, releases = [], [], [], []
    for stiffness, beyond in PRESSES:
        base = {"stiffness": stiffness, "beyond": beyond}
        for law, watch, brake in LAWS:
            for phase in (0.0, 1.0, 2.0, 3.0, 4.0):
                run = let_go(stiffness, beyond, phase, watch=watch, brake=brake)
                phases.append({**base, "law": law, "phase": phase, **run})
        for cut in (1, 2, 3, 4, 5, 6):
            run = let_go(stiffness, beyond, cut_ms=cut, push_fn=round4_push)
            cuts.append({**base, "cut": cut, **run})
        for lead in (1, 2, 3):
            run = let_go(stiffness, beyond, push_fn=lead_push(lead))
            leads.append({**base, "lead": lead, **run})
        for release in RELEASES_MS:
            for law, watch, brake in LAWS:
                after = release / 1000.0 + WALK_S
                runs = [
                    let_go(stiffness, beyond, phase, None, release, after, None, watch, brake)
                    for phase in (0.0, 1.0, 2.0, 3.0, 4.0)
                ]
                releases.append(
                    {
                        **base,
                        "law": law,
                        "release": release,
                        "outward": max(r["outward"] for r in runs),
                        "summed": sum(r["outward"] for r in runs),
                        "largest": max(r["largest"] for r in runs),
                        "peak": max(r["peak"] for r in runs),
                        "rest_min": min(r["end"] for r in runs),
                        "rest_max": max(r["end"] for r in runs),
                        "deepest": max(r["deepest"] for r in runs),
                    }
                )
        print(f"hand {stiffness:g} N m/deg, {beyond:g} deg: done")
    elapsed = time.monotonic() - started
    text = render(phases, cuts, leads, releases, load, os.getloadavg(), elapsed)
    args.out.write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
