"""The leader feels the edge, by leader model: the wall on an XM430-W350, XL330-M288, XL330-M077.

Run: ``python benchmarks/bench_haptic_models.py`` (writes docs/bench_haptic_models.md; about
four minutes).

An XL330's position loop is much softer than an XM430's (stall torque at the same error, but
the stall torque is 8-19 times smaller), so a lead of two ticks (round 5) gave its wall a
fraction of its cap. Round 6's law sets the lead from the loop's stiffness and caps the
XL330-M288 at 0.12 N m, so a let go snaps back under 30 deg/s even without the snap watch;
round 7 adds the snap watch (limbctl/teleop/snap.py), round 8 its brake rules
(limbctl/teleop/brake.py), today's (round 9) a walking lead and two still reads to
re-arm. The four run here, on the same hands, in one run:

- *let go*: the simulated operator presses 5 or 20 deg beyond the edge (pan 30 deg of a 30 deg
  cone) at several stiffnesses, bounded at 0.3 N m, and lets go at 5 s; every 1 ms sample after
  it (stepped clock, exactly 200 Hz, in this process: the law's own figures);
- *cap*: the XL330-M288's let go at caps from 0.10 to 0.26 N m (half its stall torque), the law
  alone (without the snap watch): why its cap is 0.12;
- *pty*: the real 200 Hz loop through the real dynamixel-sdk on the simulator's pty, with each
  XL330 leader (firmware 52: its Indirect Data at 208), pushed 20 deg beyond and let go.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import tempfile
import time
from pathlib import Path

import numpy as np
from felt_harness import EDGE_DEG, HAND, exact_rate_case, felt_motor, pan_of, run_case

from limbctl.teleop.brake import BrakeLaw
from limbctl.teleop.haptic import TICK_DEG, FeelLaw

#: Today's brake rules (rounds 8 and 9).
BRAKE = BrakeLaw()

MODELS = {"XM430-W350": "xm430-w350", "XL330-M288": "xl330-m288@53", "XL330-M077": "xl330-m077@53"}
#: (hand stiffness N m/deg, how far beyond the edge it means to go, deg).
HANDS = [(0.02, 5.0), (0.05, 5.0), (0.05, 20.0), (0.1, 5.0), (0.2, 5.0), (0.2, 20.0)]
#: Round 5's lead: two ticks, three deeper, on every model.
ROUND5 = FeelLaw(lead_deg=2 * TICK_DEG, walk_lead_ticks=0)  # round 5: no walking lead
M288_CAPS = [0.10, 0.11, 0.12, 0.13, 0.14, 0.16, 0.20, 0.26]


def round5_motor(model: str):
    """The table's motor as round 5 had it: half the stall torque, no let-go cap."""
    return dataclasses.replace(felt_motor(model), let_go_cap_nm=None)


def cap_of(motor) -> float:
    """The torque (N m) of the Goal Current the law's cap comes to on ``motor``."""
    return motor.torque_of(motor.units_for(motor.cap_nm(FeelLaw().cap_nm)))


def let_go(
    model: str, stiffness: float, beyond: float, law=None, motor=None, watch=True, brake=BRAKE
):
    """A press of ``stiffness`` to ``beyond`` deg past the edge let go at 5 s (stepped clock);
    ``watch``: with the snap watch, ``brake``: its brake rules (None: without). The held pose
    and torque, the return, the outward samples."""
    script = [[0.0, 0.0, 0.0], [2.0, EDGE_DEG + beyond, 0.0]]
    case = {"model": model, "law": law, "motor": motor, "snap_watch": watch, "brake": brake}
    rows = exact_rate_case(stiffness, script, 7.0, let_go_s=5.0, **case)["rows"]
    t = np.array([r["t"] for r in rows])
    pan, motor_nm = pan_of(rows), pan_of(rows, "motor_nm")
    velocity = pan_of(rows, "velocity_deg_s")
    held, after = (t >= 4.0) & (t < 5.0), t >= 5.0
    window = np.convolve(velocity[after], np.ones(20) / 20.0, mode="valid")
    outward = (pan > EDGE_DEG) & (motor_nm > 0.0) & after
    return {
        "held": float(np.mean(pan[held]) - EDGE_DEG),
        "held_nm": float(-np.mean(motor_nm[held])),
        "peak": float(np.max(-velocity[after])),
        "mean20": float(np.max(-window)),
        "outward": int(np.sum(outward)),
        "rest": float(pan[-1] - EDGE_DEG),
        "deepest": float(max(0.0, EDGE_DEG - np.min(pan[after]))),
        "inside": int(np.sum((pan < EDGE_DEG) & (motor_nm != 0.0))),
    }


def let_go_rows() -> list[dict]:
    rows = []
    for name, model in MODELS.items():
        for stiffness, beyond in HANDS:
            for law_name, law, motor, watch, brake in (
                ("round 5", ROUND5, round5_motor(model), False, None),
                ("round 6", None, None, False, None),
                ("round 7", None, None, True, None),
                ("round 9", None, None, True, BRAKE),
            ):
                out = let_go(model, stiffness, beyond, law, motor, watch, brake)
                rows.append({"model": name, "k": stiffness, "beyond": beyond, "law": law_name})
                rows[-1].update(out)
                print(rows[-1], flush=True)
    return rows


def cap_rows() -> list[dict]:
    rows = []
    for cap in M288_CAPS:
        motor = dataclasses.replace(felt_motor("xl330-m288@53"), let_go_cap_nm=cap)
        runs = [let_go("xl330-m288@53", k, b, motor=motor, watch=False) for k, b in HANDS]
        rows.append(
            {
                "cap": cap,
                "peak": max(r["peak"] for r in runs),
                "outward": max(r["outward"] for r in runs),
                "held_nm": max(r["held_nm"] for r in runs),
                "rest": max(r["rest"] for r in runs),
            }
        )
        print(rows[-1], flush=True)
    return rows


def pty_rows(workdir: Path) -> list[dict]:
    rows = []
    script = [[0.0, 0.0, 0.0], [2.0, EDGE_DEG + 20.0, 0.0], [5.0, EDGE_DEG + 20.0, 0.0]]
    for model in ("xl330-m288", "xl330-m077"):
        operator = {"script": script, "let_go_s": 5.0, **HAND}
        summary, source, _, truth = run_case(workdir, f"push-{model}", operator, 7.0, model)
        t = np.array([r["t"] for r in truth])
        pan, motor_nm = pan_of(truth), pan_of(truth, "motor_nm")
        velocity = pan_of(truth, "velocity_deg_s")
        held, after = (t >= 3.0) & (t < 5.0), t >= 5.0
        rows.append(
            {
                "model": model,
                "cap": cap_of(felt_motor(model)),
                "held": float(np.mean(pan[held]) - EDGE_DEG),
                "held_nm": float(-np.mean(motor_nm[held])),
                "largest": float(np.max(np.abs(motor_nm))),
                "peak": float(np.max(-velocity[after])),
                "outward": int(np.sum((pan > EDGE_DEG) & (motor_nm > 0.0))),
                "rest": float(np.mean(pan[after][-200:]) - EDGE_DEG),
                "deepest": float(max(0.0, EDGE_DEG - np.min(pan[after]))),
                "inside": int(np.sum((pan < EDGE_DEG) & (motor_nm != 0.0))),
                "rate": summary.cycles / summary.elapsed_s,
                "felt": not any("the loop runs at" in e for e in source.feel_stats.events),
            }
        )
        print(rows[-1], flush=True)
    return rows


def model_table() -> list[str]:
    lines = [
        "| model | stall torque (N m) | loop stiffness (N m/deg, simulated) | cap (N m) | "
        "lead, round 5 (ticks) | lead today (ticks) |",
        "| --- | ---: | ---: | ---: | --- | --- |",
    ]
    law = FeelLaw()
    for name, model in MODELS.items():
        motor = felt_motor(model)
        cap = cap_of(motor)
        normal = round(law.lead_for_deg(law.deadband_deg + 0.1, motor) / TICK_DEG)
        deeper = round(law.lead_for_deg(law.held_within_deg + 0.1, motor) / TICK_DEG)
        why = "half stall" if motor.let_go_cap_nm is None else "let-go cap"
        lines.append(
            f"| {name} | {motor.stall_torque_nm:g} | {motor.loop_nm_per_deg:.4g} | "
            f"{cap:.3f} ({why}) | 2, 3 deeper | {normal}, {deeper} deeper |"
        )
    return lines


def render(let_go_table, caps, pty, load_start, load_end) -> str:
    def load(values) -> str:
        return " ".join(f"{v:.2f}" for v in values)

    lines = [
        "# The leader feels the edge, by leader model",
        "",
        "`python benchmarks/bench_haptic_models.py`: the haptic law (`limbctl/teleop/haptic.py`) "
        "on felt leaders of each model the controller supports, the simulated operator "
        "(`firmware_sim/leader.py`) pressing past a 30 deg cone's edge (pan 30 deg). Machine "
        f"load at start: {load(load_start)}, at the end: {load(load_end)} (1, 5, 15 min; 2 "
        "cores, shared).",
        "",
        "## Each model's wall",
        "",
        "The simulator's position loop reaches a model's stall torque at 2 deg of error "
        "(`firmware_sim/torque.py`, `LeaderMotor.loop_stall_error_deg`). Today's lead is the "
        "whole ticks nearest 0.9 of the loop's error at the cap, and, deeper than a hand within "
        "the cap holds the leader, the least that gives the cap wherever it sits in its tick "
        "(`FeelLaw.lead_for_deg`). Round 5 led by two ticks (three deeper) on every model, "
        "with half the stall torque as the cap.",
        "",
        *model_table(),
        "",
        "## Let go, by model and hand (stepped clock, exactly 200 Hz)",
        "",
        "The hand (bounded at 0.3 N m, damping 0.02 N m s/rad) presses from the middle to "
        "5 or 20 deg beyond the edge in 2 s and lets go at 5 s. Held: the mean over the last "
        "second before the let go. After the let go, every 1 ms sample: the peak speed, the "
        "largest 20 ms mean, the samples outside the region whose motor torque points away "
        "from it, the rest 2 s later, how far inside the edge it went; and over the whole run "
        "the 1 ms samples inside the region with any motor torque. Round 5: two ticks of lead, "
        "half the stall torque; round 6: the lead from the loop, the XL330-M288 at 0.12 N m; "
        "round 7: round 6 with the snap watch; round 9 (today): with its brake rules, a walking "
        "lead and two still reads to re-arm.",
        "",
        "| model | hand (N m/deg) | pressed beyond (deg) | law | held beyond (deg) | "
        "held torque (N m) | 1 ms peak (deg/s) | 20 ms mean (deg/s) | outward samples | "
        "rest beyond (deg) | deepest inside (deg) | inside with torque |",
        "| --- | ---: | ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
        *(
            f"| {r['model']} | {r['k']:g} | {r['beyond']:g} | {r['law']} | {r['held']:.2f} | "
            f"{r['held_nm']:.3f} | {r['peak']:.1f} | {r['mean20']:.1f} | {r['outward']} | "
            f"{r['rest']:.3f} | {r['deepest']:.3f} | {r['inside']} |"
            for r in let_go_table
        ),
        "",
        "## The XL330-M288's cap",
        "",
        "Today's lead, the cap swept, the law alone (without the snap watch, which would hide "
        "what the cap stores); over the six hands above, the largest of each figure. "
        "A let go spends what the loop stored holding the hand: about "
        "`0.46 tau / sqrt(KP J)` of peak speed (KP the loop's stiffness, J the leader's "
        "inertia, 1e-3 kg m^2 simulated), plus the read's rounding of the lead.",
        "",
        "| cap (N m) | largest 1 ms peak (deg/s) | most outward samples | largest held torque "
        "(N m) | largest rest beyond (deg) |",
        "| ---: | ---: | ---: | ---: | ---: |",
        *(
            f"| {c['cap']:.2f} | {c['peak']:.1f} | {c['outward']} | {c['held_nm']:.3f} | "
            f"{c['rest']:.3f} |"
            for c in caps
        ),
        "",
        "## Over the pty: an XL330 leader pushed 20 deg beyond, held 3 s, let go",
        "",
        "The real loop at 200 Hz with today's law, the hand of the push case "
        f"(stiffness {HAND['stiffness_nm_deg']} N m/deg, bounded at {HAND['max_torque_nm']} "
        "N m, more than either XL330's cap: it holds the leader deep). The start's rate check "
        "and pace watch are set against 50 Hz so a loaded machine does not stop the run; the "
        "loop's achieved rate is given.",
        "",
        "| model | cap (N m) | held beyond (deg) | held torque (N m) | largest torque (N m) | "
        "1 ms return peak (deg/s) | outward samples | rest beyond (deg) | deepest inside "
        "(deg) | inside with torque | loop rate (Hz) | felt to the end |",
        "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- |",
        *(
            f"| {p['model']} | {p['cap']:.3f} | {p['held']:.2f} | {p['held_nm']:.3f} | "
            f"{p['largest']:.3f} | {p['peak']:.1f} | {p['outward']} | {p['rest']:.3f} | "
            f"{p['deepest']:.3f} | {p['inside']} | {p['rate']:.0f} | "
            f"{'yes' if p['felt'] else 'no: the pace was lost'} |"
            for p in pty
        ),
        "",
    ]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, default=Path("docs/bench_haptic_models.md"))
    args = parser.parse_args(argv)
    load_start = os.getloadavg()
    started = time.perf_counter()
    table = let_go_rows()
    caps = cap_rows()
    with tempfile.TemporaryDirectory() as tmp:
        pty = pty_rows(Path(tmp))
    args.out.write_text(render(table, caps, pty, load_start, os.getloadavg()))
    print(f"wrote {args.out} in {time.perf_counter() - started:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
