"""A three-servo leader feels a twist region's edge, beside the two-servo leader as its peer.

Run: ``python benchmarks/bench_haptic3.py`` (writes docs/bench_haptic3.md; about a minute).

The three-servo follower is gated by a twist region fitted from a synthetic teaching of a square
swing outline (pan within +-30 deg, tilt within +-25 deg) with a twist band of +-30 deg about 0:
the learned edge lies near pan 30 deg in swing and near roll 30 deg in twist. The two-servo peer
is the two-servo leader's bench set-up: a 30 deg cone, edge at pan 30 deg. Both leaders are
XM430-W350s moved by the simulator's operator (firmware_sim/leader.py),
the same hand, the same law constants (limbctl/teleop/haptic.py, limbctl/teleop/haptic_push.py).

Cases:

- *exact*: the law at exactly 200 Hz on a stepped clock, the controller's part done on the
  simulated leader's registers in this process (as benchmarks/bench_haptic.py): a press 20 deg
  beyond the edge held 2.5 s then let go, in swing for both leaders, and in twist and in both
  for the three-servo one: how far beyond the edge it is held (rotation to the correction), the
  ripple, the walk back, the rest; a hand pulling the leader back inside: samples whose motor
  torque points away from the region, without and with the let-go rules; a closed excursion
  past the edge and back: the motor's and the hand's net work (passivity at the hand); a held
  gate of 50 ms while pressed.
- *transfers*: the felt cycle's bus work over the real SDK and the simulator's pty (follower
  cycle read, leader cycle read, the leader's feel write, the follower's goal write), two
  servos against three, interleaved A/B so a change of the machine's load falls on both.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import time
from pathlib import Path

import numpy as np
from felt_harness import (
    HAND,
    LEADER_IDS,
    felt_part,
    transfers_case,
)

from limbctl.envelope import Cone
from limbctl.envelope.synthetic_twist import ShoulderRegion
from limbctl.geometry.gimbal import pan_tilt_to_quat, pose_quat_scalar
from limbctl.region.twist_region import TwistRegion
from limbctl.servo.control_table import ModelNumber
from limbctl.servo.leader import FELT_MODELS
from limbctl.teleop.brake import BrakeLaw
from limbctl.teleop.haptic import FeelLaw, moved_in_deg
from limbctl.teleop.haptic_push import beyond_deg, corrected_pose, held, push_for
from tests.teleop.stepped_leader import (
    CHAINS,
    SteppedWatch,
    q_of,
    rig_of,
    run_stepped,
    stepped_leader,
)

LAW = FeelLaw()
#: Round 3's law, the peer in the same run: the goal led the leader by 0.3 deg plus the leader's
#: last step toward the region, at Profile Velocity 19 units (decisions/haptic.md, round 4).
ROUND3 = FeelLaw(return_speed_deg_s=27.0, lead_deg=0.3, walk_lead_ticks=0)
MOTOR = FELT_MODELS[ModelNumber.XM430_W350]
CAP = MOTOR.torque_of(MOTOR.units_for(LAW.cap_nm))
SQUARE = np.array([[-30.0, -25.0], [30.0, -25.0], [30.0, 25.0], [-30.0, 25.0]])
#: Presses 20 deg beyond the edge, reached in 2 s, held to 4.5 s, let go there (t, joints deg).
PRESSES = {
    "two servos, swing (pan 50)": [[0.0, 0.0, 0.0], [2.0, 50.0, 0.0]],
    "three servos, swing (pan 50)": [[0.0, 0.0, 0.0, 0.0], [2.0, 50.0, 0.0, 0.0]],
    "three servos, twist (roll 50)": [[0.0, 0.0, 0.0, 0.0], [2.0, 0.0, 0.0, 50.0]],
    "three servos, both (pan 40, tilt 10, roll -45)": [
        [0.0, 0.0, 0.0, 0.0],
        [2.0, 40.0, 10.0, -45.0],
    ],
}
#: Pressed 20 deg beyond, held to 4 s, pulled back inside by 4.2 s (t, joints deg).
PULLS = {
    "two servos, swing (pan)": [[0.0, 0.0, 0.0], [2.0, 50.0, 0.0], [4.0, 50.0, 0.0], [4.2, 0, 0]],
    "three servos, swing (pan)": [
        [0.0, 0, 0, 0],
        [2.0, 50.0, 0, 0],
        [4.0, 50.0, 0, 0],
        [4.2, 0, 0, 0],
    ],
    "three servos, twist (roll)": [
        [0.0, 0, 0, 0],
        [2.0, 0, 0, 50.0],
        [4.0, 0, 0, 50.0],
        [4.2, 0, 0, 0],
    ],
}
#: Closed excursions 10 deg past the edge and back: 20 -> 40 -> 20 deg on pan or roll.
EXCURSION_TIMES = (0.0, 1.0, 2.0, 2.5, 3.5, 4.5)
EXCURSION_ANGLES = (20.0, 20.0, 40.0, 40.0, 20.0, 20.0)


def square_region() -> TwistRegion:
    """The three-servo follower's twist region (module docstring)."""
    truth = ShoulderRegion(SQUARE, 30.0, 30.0, 0.0, 0.0, 0.0)
    return TwistRegion().fit(truth.teaching(1500, 1000, 1800, np.random.default_rng(0)))


def round3(push, present, previous, target):
    """Round 3's goal for a push of :data:`ROUND3`: at most LEAD + max(m, 0) ahead on the
    joint-space line toward ``target`` (the corrected pose's joints), m the leader's step
    toward it since ``previous``."""
    if not push.goal_current or previous is None:
        return push
    step = tuple(t - p for t, p in zip(target, present, strict=True))
    moved = moved_in_deg(present, previous, step)
    # s = min(1, (LEAD + max(m, 0)) / max_j |step_j|)
    scale = min(1.0, math.radians(ROUND3.lead_deg + max(moved, 0.0)) / max(map(abs, step)))
    goal = tuple(p + scale * d for p, d in zip(present, step, strict=True))
    return dataclasses.replace(push, goal=goal)


def stepped(
    region,
    script,
    seconds,
    let_go_s=None,
    held_cycles=(),
    stiffness=0.05,
    rules=True,
    law=LAW,
    watch=True,
):
    """The law at exactly 200 Hz on a stepped clock (module docstring; ``run_stepped``);
    ``held_cycles`` lists cycles whose gate held (Goal Current 0 written); ``rules``: the law is
    given the previous read, the period and whether the wall pushed (as the sources do), False:
    the wall alone (before round 3's let-go rules); ``law``: :data:`LAW`, or :data:`ROUND3` for
    round 3's law; ``watch``: True, today's law with the snap watch and its brake rules
    (limbctl/teleop/snap.py, limbctl/teleop/brake.py, a walking lead, two still reads to
    re-arm: round 9); "snap", the snap watch alone (round 7); False: without it (round 6; round 3
    never has it). Returns the 1 ms truth rows and each row's distance beyond the edge (deg of
    rotation; of direction for two servos)."""
    joints = len(script[0]) - 1
    _, follower, ids = CHAINS[joints]
    operator = {"script": script, "let_go_s": let_go_s, **HAND, "stiffness_nm_deg": stiffness}
    limit = MOTOR.units_for(LAW.cap_nm)
    sim, clock, servos = stepped_leader(follower, ids, "xm430-w350", limit, operator)
    rig = rig_of(joints)
    limits = tuple((j.min_rad, j.max_rad) for j in rig.joints)
    on = bool(watch) and rules and law is LAW
    brake = BrakeLaw() if watch is True else None  # "snap": round 7's watch, no brake rules
    snap = SteppedWatch(servos, rig.joints, lambda: sim.time_s, on, MOTOR, LAW, brake)
    previous = None

    def decide(k, ticks, velocity, torque, engaged, read_s):
        nonlocal previous
        # the motors' torque as Present Current reads (LeaderSource); round 3's peer did not
        read = () if law is ROUND3 else (torque,)
        if on and brake is not None:  # today's law reads the speed too: the walking lead
            read = (*read, velocity)
        past = (previous, 0.005, engaged, *read) if rules else ()
        pose = rig.ticks_to_angles(*ticks)
        q = np.asarray(pan_tilt_to_quat(*pose)) if joints == 2 else pose_quat_scalar(*pose)
        corrected = region.correct(q)
        push = push_for(law, MOTOR, pose, q, corrected, *past, limits=limits)
        if law is ROUND3 and rules:  # round 3's goal: toward the correction's joints
            push = round3(push, pose, previous, corrected_pose(corrected, pose, limits))
        if snap.on and push.goal_current:
            if not snap.snap.allows(pose, push.goal, velocity, engaged, read_s, torque):
                push = held(pose, push.distance_deg)
        previous = pose
        return pose, held(pose) if k in held_cycles else push

    rows = run_stepped(
        sim, clock, servos, rig, snap, seconds, decide, engage_at_write=True, profile_always=True
    )
    return rows, [distance(region, r["pose_deg"]) for r in rows]


def distance(region, pose_deg) -> float:
    """How far (deg) a pose of either chain (deg) lies beyond ``region`` (``beyond_deg``)."""
    q = q_of(*pose_deg)
    return beyond_deg(q, region.correct(q), len(pose_deg))


def press_case(region, script, law=LAW, watch=True) -> dict:
    rows, beyond = stepped(region, script, 6.5, let_go_s=4.5, law=law, watch=watch)
    t = np.array([r["t"] for r in rows])
    beyond = np.array(beyond)
    held = beyond[(t >= 3.0) & (t < 4.5)]
    speeds = np.abs([r["velocity_deg_s"] for r in rows])[t >= 4.5]
    window = max(
        np.convolve(speeds[:, j], np.ones(20) / 20.0, mode="valid").max()
        for j in range(speeds.shape[1])
    )
    outward, _ = outward_count(region, [r for r in rows if r["t"] >= 4.5])
    return {
        "held": float(np.mean(held)),
        "ripple": float(np.ptp(held)),
        "return": float(window),
        "peak": float(speeds.max()),
        "outward": outward,
        "rest": float(beyond[-1]),
        "deepest": float(min(beyond[t >= 4.5])),
        "peak_nm": max(abs(m) for r in rows for m in r["motor_nm"]),
    }


def excursion(joint: int, joints: int) -> list:
    points = []
    for t, angle in zip(EXCURSION_TIMES, EXCURSION_ANGLES, strict=True):
        pose = [0.0] * joints
        pose[joint] = angle
        points.append([t, *pose])
    return points


def energy_case(region, script) -> dict:
    """Net work (mJ) over the 1 ms samples beyond the edge, summed over the joints."""
    rows, beyond = stepped(region, script, 4.5)
    out = dict.fromkeys(("motor", "hand"), 0.0)
    for a, b, d in zip(rows, rows[1:], beyond[1:], strict=False):
        if d > 0.0:
            for key in out:
                out[key] += sum(np.subtract(b[f"{key}_work_j"], a[f"{key}_work_j"])) * 1e3
    return out


def outward_count(region, rows) -> tuple[int, int]:
    """1 ms samples outside the region whose joint torques point away from the correction
    (dot product with ``corrected pose - pose`` < 0); samples inside with any torque."""
    outward = inside = 0
    for r in rows:
        if not any(r["motor_nm"]):
            continue
        present = np.radians(r["pose_deg"])
        q = q_of(*r["pose_deg"])
        limits = tuple((j.min_rad, j.max_rad) for j in rig_of(len(present)).joints)
        target = corrected_pose(region.correct(q), present, limits)
        if bool(region.contains(q)):
            inside += 1
        elif float(np.dot(r["motor_nm"], np.subtract(target, present))) < 0.0:
            outward += 1
    return outward, inside


def pull_case(region, script, stiffness) -> dict:
    """Pressed 20 deg beyond, held, pulled back inside in 0.2 s: outward samples and samples
    inside with torque, without the let-go rules, with the snap watch alone and today's."""
    before = outward_count(
        region, stepped(region, script, 5.0, stiffness=stiffness, rules=False)[0]
    )
    after = outward_count(region, stepped(region, script, 5.0, stiffness=stiffness)[0])
    snap = outward_count(region, stepped(region, script, 5.0, stiffness=stiffness, watch="snap")[0])
    return {
        "before": before[0],
        "snap": snap[0],
        "after": after[0],
        "inside": f"{before[1]} / {snap[1]} / {after[1]}",
    }


def held_case(region) -> dict:
    """The twist press with the gate held 50 ms at 3.2 s (cycles 640-649): how far the hand
    takes the released leader, and whether the motors were off from the first held write."""
    rows, beyond = stepped(
        region, PRESSES["three servos, twist (roll 50)"], 4.0, held_cycles=range(640, 650)
    )
    t = np.array([r["t"] for r in rows])
    released = [r for r in rows if 3.2 + 0.0015 <= r["t"] < 3.25]
    return {
        "before": float(np.mean(np.array(beyond)[(t >= 3.0) & (t < 3.2)])),
        "peak": float(np.max(np.array(beyond)[(t >= 3.2) & (t < 3.6)])),
        "off": all(not any(r["motor_nm"]) for r in released),
        "after": float(np.mean(np.array(beyond)[t >= 3.8])),
    }


def bus_work(rounds: int = 300) -> dict:
    """The felt cycle's bus work, two servos against three, interleaved A/B."""
    kinds = {"two": ("sim", LEADER_IDS, felt_part), "three": ("sim3", (4, 5, 6), felt_part)}
    return transfers_case(kinds, rounds)


def render(presses, energies, pulls, held, transfers, load, end_load, fit_s) -> str:
    lines = [
        "# A three-servo leader feels a twist region's edge",
        "",
        "`python benchmarks/bench_haptic3.py`: the three-servo felt leader "
        "(`limbctl/teleop/haptic_push.py`, `limbctl/teleop/sources/leader.py`) beside the "
        "two-servo one as its peer, XM430-W350 leaders, the same hand (0.05 N m/deg, at most "
        "0.3 N m) and law (deadband 0.4 deg, K = 0.2 N m/deg, cap 0.4 N m, lead two ticks, "
        f"Profile Velocity {LAW.profile_velocity_units()} units). Three servos: a "
        "twist region fitted from a square swing outline (pan +-30, tilt +-25 deg) with a twist "
        f"band of +-30 deg (fitted in {fit_s:.0f} s); two servos: a 30 deg cone. Machine load at "
        f"start: {' '.join(f'{v:.2f}' for v in load)}, at the end: "
        f"{' '.join(f'{v:.2f}' for v in end_load)} (1, 5, 15 min; 2 cores, shared).",
        "",
        "## The law at exactly 200 Hz",
        "",
        "A press 20 deg beyond the edge, reached in 2 s, let go at 4.5 s; on a stepped clock in "
        "one process, so the figures are the law's, whatever the load. Beyond the edge: the "
        "rotation from the leader's orientation to the region's correction (for two servos the "
        "angle between directions). Walk back: the peak over the joints of the 20 ms mean speed "
        "after let go; 1 ms peak: the largest 1 ms sample of any joint's speed after let go; "
        "outward: 1 ms samples after let go outside the region whose joint torques point away "
        "from the correction. Each press under today's law (round 9, the snap watch with its "
        "brake rules, a walking lead and two still reads to re-arm), round 7's (the snap "
        "watch alone), round 6's (the law alone) and round "
        "3's (goal 0.3 deg "
        "ahead plus the leader's last step, 26.1 deg/s; its let-go rules are today's), in this "
        "run.",
        "",
        "| press | law | held beyond the edge (deg) | ratio to two servos | ripple (deg) | "
        "walk back (deg/s) | 1 ms peak (deg/s) | outward after let go | rest beyond (deg) | "
        f"deepest after let go (deg beyond) | peak motor torque (N m, cap {CAP:.3f}) |",
        "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    peer = presses[("two servos, swing (pan 50)", "today (round 9)")]["held"]
    for (name, law), p in presses.items():
        lines.append(
            f"| {name} | {law} | {p['held']:.3f} | {p['held'] / peer:.3f} | {p['ripple']:.3f} | "
            f"{p['return']:.1f} | {p['peak']:.1f} | {p['outward']} | {p['rest']:.3f} | "
            f"{p['deepest']:.3f} | {p['peak_nm']:.3f} |"
        )
    lines += [
        "",
        "A closed excursion 10 deg past the edge and back (20 -> 40 -> 20 deg), energy over the "
        "1 ms samples beyond the edge, summed over the joints: the hand's net work stays >= 0 "
        "(the operator gets back less than they put in) when the wall is passive.",
        "",
        "| excursion | motor net work (mJ) | hand net work (mJ) |",
        "| --- | ---: | ---: |",
        *(f"| {n} | {e['motor']:+.3f} | {e['hand']:+.3f} |" for n, e in energies.items()),
        "",
        "A hand pulling the leader back inside: pressed 20 deg beyond the edge, held to 4 s, "
        "pulled back to the middle by 4.2 s, hands of 0.05 and 0.2 N m/deg (at most 0.3 N m). "
        "The setpoints move at most RETURN_SPEED, so their loops would pull a faster leader "
        "back, away from the region; the let-go rules (decisions/haptic.md, rounds 3 and 5) "
        "leave it free once a read shows it outrunning them or its motors pulling outward, and "
        "the snap watch's brake rules (round 8) free it before the loop brakes, reading the "
        "leader every millisecond. Counted: 1 ms samples outside the region "
        "whose joint torques point away from the correction, the law without the rules "
        "(before), with them and the snap watch alone (round 7), and today's (round 9); "
        "inside: samples inside the region with any torque, by the same three laws.",
        "",
        "| pull | hand (N m/deg) | outward samples before | round 7 | today (round 9) | "
        "inside with torque: before / round 7 / today |",
        "| --- | ---: | ---: | ---: | ---: | ---: |",
        *(
            f"| {n} | {k:.2f} | {p['before']} | {p['snap']} | {p['after']} | {p['inside']} |"
            for (n, k), p in pulls.items()
        ),
        "",
        "The twist press with the gate held 50 ms at 3.2 s (a failed follower read): each held "
        "cycle releases all three servos (Goal Current 0).",
        "",
        "| beyond before (deg) | most beyond while released (deg) | motors off from the first "
        "held write | beyond after (deg) |",
        "| ---: | ---: | --- | ---: |",
        f"| {held['before']:.3f} | {held['peak']:.3f} | {'yes' if held['off'] else 'NO'} | "
        f"{held['after']:.3f} |",
        "",
        "## The felt cycle's bus work over the pty",
        "",
        "Follower cycle read, leader cycle read, the leader's feel write, the follower's goal "
        "write, through the real dynamixel-sdk on the simulator's pty (4 Mbaud profile), "
        "interleaved two/three servos per round; rounds whose reply a starved simulator missed "
        "are counted, not timed.",
        "",
        "| leader | p50 (ms) | p99 (ms) | missed | p50 ratio to two servos |",
        "| --- | ---: | ---: | ---: | ---: |",
    ]
    for kind, (p50, p99, missed) in transfers.items():
        ratio = p50 / transfers["two"][0]
        lines.append(f"| {kind} servos | {p50:.3f} | {p99:.3f} | {missed} | {ratio:.2f} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, default=Path("docs/bench_haptic3.md"))
    args = parser.parse_args(argv)
    load = os.getloadavg()
    started = time.monotonic()
    region3 = square_region()
    fit_s = time.monotonic() - started
    cone = Cone(half_angle_deg=30.0)
    presses = {
        (name, label): press_case(region3 if len(script[0]) == 4 else cone, script, law, watch)
        for name, script in PRESSES.items()
        for label, law, watch in (
            ("round 3", ROUND3, False),
            ("round 6 (the law alone)", LAW, False),
            ("round 7 (the snap watch)", LAW, "snap"),
            ("today (round 9)", LAW, True),
        )
    }
    energies = {
        "two servos, pan": energy_case(cone, excursion(0, 2)),
        "three servos, pan": energy_case(region3, excursion(0, 3)),
        "three servos, roll": energy_case(region3, excursion(2, 3)),
    }
    pulls = {
        (name, k): pull_case(region3 if len(script[0]) == 4 else cone, script, k)
        for name, script in PULLS.items()
        for k in (0.05, 0.2)
    }
    held = held_case(region3)
    print(f"exact-rate cases done in {time.monotonic() - started:.0f} s")
    transfers = bus_work()
    text = render(presses, energies, pulls, held, transfers, load, os.getloadavg(), fit_s)
    args.out.write_text(text)
    print(text)
    return 0 if all(p["held"] < 2.0 for p in presses.values()) and held["off"] else 1


if __name__ == "__main__":
    raise SystemExit(main())
