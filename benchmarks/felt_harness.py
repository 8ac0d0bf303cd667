"""The felt-leader benchmarks' shared harness: the real loop over the simulator's pty with a leader
held by the simulated operator (:func:`run_case`), the two-servo law at exactly 200 Hz on a stepped
clock in this process (:func:`exact_rate_case`, :func:`exact_cases`: docs/bench_haptic.md's
exact-rate section; the stepped loop itself is ``tests.teleop.stepped_leader.run_stepped``), and
the felt cycle's bus work timed over the pty (:func:`transfers_case`).

Used by benchmarks/bench_haptic.py (two servos), benchmarks/bench_haptic3.py (two and three
servos), benchmarks/bench_let_go.py, benchmarks/bench_haptic_models.py and
benchmarks/bench_brake.py. The follower's region in the two-servo runs is a 30 deg cone around +x:
along pan (tilt 0) the edge lies at pan :data:`EDGE_DEG`.
"""

from __future__ import annotations

import json
import sys
import threading
import time
from contextlib import ExitStack
from pathlib import Path

import numpy as np

from calib.profile import default_sim_profile
from limbctl.envelope import Cone
from limbctl.errors import BusError
from limbctl.jobs import gate_for
from limbctl.servo.leader import FEEL_DATA, encode_feel
from limbctl.servo.rig import Rig
from limbctl.servo.setup import configure_servos
from limbctl.session import open_rig
from limbctl.teleop.brake import BrakeLaw
from limbctl.teleop.commands import command_from_pan_tilt
from limbctl.teleop.haptic import FeelLaw
from limbctl.teleop.haptic_push import held, push_for
from limbctl.teleop.loop import LoopConfig, run
from limbctl.teleop.sources import LeaderSource

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # for tests.teleop.stepped_leader
from tests.teleop.stepped_leader import SteppedWatch, motor_of, run_stepped, stepped_leader

EDGE_DEG = 30.0
LEADER_IDS = (3, 4)
#: The simulated operator's hand: N m/deg, N m s/rad, bound N m.
HAND = {"stiffness_nm_deg": 0.05, "damping_nm_s_rad": 0.02, "max_torque_nm": 0.3}

#: The controller's :class:`LeaderMotor` for a simulator model key (``"xl330-m288@53"``).
felt_motor = motor_of


def pan_of(rows, key="pose_deg"):
    """The first joint's column of ``key`` over the 1 ms truth rows, shape (n,)."""
    return np.array([r[key][0] for r in rows])


def contact_energy(rows) -> dict:
    """Energy over the samples beyond the edge (a closed path: in and out at the edge), mJ:
    the motor's net work (the sampled wall's leak when > 0), the hand's net work (what the
    operator put in; passive at the hand when >= 0) and what the leader's friction took."""
    pan = pan_of(rows)[1:]
    motor = np.diff([r["motor_work_j"][0] for r in rows])[pan > EDGE_DEG].sum()
    hand = np.diff([r["hand_work_j"][0] for r in rows])[pan > EDGE_DEG].sum()
    # energy balance over a closed path: friction took what the motor and the hand put in
    return {"motor_mj": 1e3 * motor, "hand_mj": 1e3 * hand, "friction_mj": 1e3 * (motor + hand)}


class LoopFault(RuntimeError):
    """A case's loop ended in a fault (on a starved machine: the simulator missed replies)."""


def run_case(
    workdir: Path,
    name: str,
    operator: dict,
    seconds: float,
    model="xm430-w350",
    watch=None,
    law=None,
):
    """:func:`run_once`, run again once if the set-up met a garbled reply (a busy machine)."""
    try:
        return run_once(workdir, name, operator, seconds, model, watch, law)
    except (BusError, LoopFault) as exc:
        print(f"{name}: {exc}; running it again")
        return run_once(workdir, name, operator, seconds, model, watch, law)


def run_once(
    workdir: Path, name: str, operator: dict, seconds: float, model: str, watch=None, law=None
):
    """Run the 200 Hz loop over the pty, the follower gated by the cone, a leader of ``model``
    held by ``operator`` for ``seconds`` of the simulator's clock. ``watch``: a factory of the
    source's snap watch instead of its own (a peer's rules); ``law``: the source's feel law
    instead of today's (a peer's). Returns the loop's summary, the source, the cycles' pushes
    ``(t, distance_deg, goal_current, torque_nm)`` and the leader's 1 ms truth rows from the
    operator's start (``t`` in operator time, s)."""
    log = workdir / f"{name}.jsonl"
    log.write_text("")
    cone = workdir / "cone.npz"
    sim = default_sim_profile()
    if not cone.exists():
        metadata = {"rig": sim.name, "calibration": sim.calibration.to_dict()}
        Cone(half_angle_deg=EDGE_DEG).save(cone, metadata=metadata)
    gate = gate_for(cone, sim, 200.0, 120.0)
    leader = {"ids": list(LEADER_IDS), "model": model, "log": str(log)}
    pushes: list[tuple[float, float, int, float]] = []
    with open_rig(extra_ids=LEADER_IDS, sim_options={"leader": leader}) as session:
        rig = session.rig
        limits = {**rig.tick_limits(), **dict.fromkeys(LEADER_IDS, (0, 4095))}
        configure_servos(rig.bus, limits)
        # the start's rate check and the pace watch against 50 Hz: a shared machine's load
        # must not stop the run (the loop runs at 200 Hz; what it achieved is reported)
        source = LeaderSource(rig, LEADER_IDS, rate_hz=50.0, law=law)
        if watch is not None:
            source.snap = watch()
        stop = threading.Event()
        out: dict = {}

        def observe(cycle) -> None:
            push = source.last_push
            if cycle.complete and push is not None:
                pushes.append((cycle.t, push.distance_deg, push.goal_current, push.torque_nm))

        with source:
            rig.set_torque(True)
            config = LoopConfig(on_cycle=observe)
            thread = threading.Thread(
                target=lambda: out.update(s=run(rig, gate, source, config, stop=stop))
            )
            thread.start()
            session.simulator.set_operator(operator)
            start = session.simulator.truth()["leader"]["t"]
            # the operator's script runs on the simulator's clock: wait until it has played
            while thread.is_alive() and session.simulator.truth()["leader"]["t"] < start + seconds:
                time.sleep(0.05)
            stop.set()
            thread.join(timeout=10.0)
    if out["s"].exit_code != 0:
        raise LoopFault(f"{name}: the loop ended with {out['s'].exit_code}: {out['s'].fault}")
    rows = [json.loads(line) for line in log.read_text().splitlines()]
    for row in rows:
        row["t"] -= start  # operator time
    return out["s"], source, pushes, [r for r in rows if r["t"] >= 0.0]


def transfers_case(kinds: dict, rounds: int) -> dict:
    """The felt cycle's bus work over the pty, the kinds interleaved A/B so a change in the
    machine's load falls on all: follower cycle read, the leader's part, the follower's goal
    write. ``kinds`` maps a name to ``(rig_path, leader ids, part)``; kinds of one rig path share
    its simulator; ``part(rig, ids, free)`` does the leader's part (``free``: each id's feel
    write of no current). Returns each kind's p50 and p99 (ms) and its rounds with a missed
    reply (not timed)."""
    times = {kind: [] for kind in kinds}
    failed = dict.fromkeys(kinds, 0)
    with ExitStack() as stack:
        opened, rigs = {}, {}
        for kind, (rig_path, ids, part) in kinds.items():
            if rig_path not in opened:
                leader = {"ids": list(ids), "model": "xm430-w350"}
                session = stack.enter_context(
                    open_rig(rig_path=rig_path, extra_ids=ids, sim_options={"leader": leader})
                )
                rig = session.rig
                configure_servos(rig.bus, {**rig.tick_limits(), **dict.fromkeys(ids, (0, 4095))})
                opened[rig_path] = (rig, rig.read_pose())
            rig, pose = opened[rig_path]
            rigs[kind] = (rig, ids, pose, {i: encode_feel(0, 2048) for i in ids}, part)
        for _ in range(rounds):
            for kind, (rig, ids, pose, free, part) in rigs.items():
                start = time.perf_counter()
                try:
                    rig.read_cycle(attempts=2)
                    part(rig, ids, free)
                    rig.write_pose(*pose)
                except BusError:
                    failed[kind] += 1  # a starved simulator missed a reply: not timed
                    continue
                times[kind].append(time.perf_counter() - start)
    return {
        kind: (float(np.percentile(v, 50)) * 1e3, float(np.percentile(v, 99)) * 1e3, failed[kind])
        for kind, v in times.items()
    }


def felt_part(rig, ids, free) -> None:
    """A felt leader's part of a cycle: its cycle read and its feel write."""
    rig.bus.read_cycle(ids=ids, attempts=2)
    rig.bus.sync_write_block(FEEL_DATA, free)


#: A closed excursion 10 deg past the edge and back: pan 20 -> 40 -> 20.
EXCURSION = [[0.0, 20.0, 0.0], [1.0, 20.0, 0.0], [2.0, 40.0, 0.0], [2.5, 40.0, 0.0]]
EXCURSION += [[3.5, 20.0, 0.0], [4.5, 20.0, 0.0]]


def round4_push(law, motor, present, q, corrected, previous=None, period_s=0.0, engaged=True):
    """Round 4's push, the peer in the same run: today's law without the rule on the read
    motor torque (a wall whose servo brakes the leader outward lets go), decisions/haptic.md."""
    return push_for(law, motor, present, q, corrected, previous, period_s, engaged)


def exact_rate_case(
    stiffness: float,
    script: list,
    seconds: float,
    let_go_s=None,
    cycles=None,
    push_fn=push_for,
    cut_s=None,
    release_s=0.0,
    model="xm430-w350",
    law=None,
    motor=None,
    snap_watch=True,
    brake=BrakeLaw(),
) -> dict:
    """The two-servo law at exactly 200 Hz, without the bus: the simulator in this process on a
    stepped clock, and every 5 ms the controller's part done on the leader servos' registers
    (read Present Position, :func:`push_for`, write the same ten bytes to Indirect Data
    READ_TO_WRITE_MS later; ``run_stepped``). It measures the law, not the machine's load.

    ``cycles`` maps a cycle's index to what happens instead: "late" (nothing is written: a
    stalled loop; the servos keep their last command) or "held" (what ``LeaderSource.feel``
    writes when the gate held or the follower's read failed: Goal Current 0 at the leader).
    ``push_fn``: the law (:func:`push_for`, given the read motor torque, or :func:`round4_push`
    for the peer).
    ``cut_s``: at this time (s) the controller writes Goal Current 0 (no torque, whatever the
    goal) and nothing after: an oracle that cuts the wall a chosen time after the let go
    (benchmarks/bench_let_go.py). ``release_s``: how long the hand's let go takes. ``model``:
    the leader servos' simulator model (a 330 named with firmware 53 or later: its Indirect
    Data at 224); ``law``: the law's constants (None: today's); ``motor``: the controller's
    idea of the model's motor (None: :data:`FELT_MODELS`'s). ``snap_watch``: the snap watch
    (limbctl/teleop/snap.py) between the cycles and at each read, as ``LeaderSource`` runs it
    (``tests.teleop.stepped_leader.SteppedWatch``); False: the law alone (round 6).
    Returns ``{"rows": the leader's 1 ms truth rows}``."""
    law = law or FeelLaw()
    motor = motor or felt_motor(model)
    hand = {**HAND, "stiffness_nm_deg": stiffness, "script": script, "let_go_s": let_go_s}
    hand["release_s"] = release_s
    limit = motor.units_for(motor.cap_nm(law.cap_nm))
    sim, clock, servos = stepped_leader({"ids": (1, 2)}, LEADER_IDS, model, limit, hand)
    rig = Rig(default_sim_profile())
    cone = Cone(half_angle_deg=EDGE_DEG)
    on = snap_watch and push_fn is push_for and cut_s is None
    watch = SteppedWatch(servos, rig.joints, lambda: sim.time_s, on, motor, law, brake)
    previous = None

    def decide(k, ticks, velocity, torque, pushed, read_s):
        nonlocal previous
        pose = rig.ticks_to_angles(*ticks)
        q = command_from_pan_tilt(*np.degrees(pose)).q
        past = (previous, 0.005, pushed)
        if push_fn is not round4_push:  # today's law reads the motors' torque
            past = (*past, torque)
        if on and brake is not None:  # and, with the brake rules, the speed: the walking lead
            past = (*past, velocity)
        push = push_fn(law, motor, pose, q, cone.correct(q), *past)
        if on and push.goal_current:
            if not watch.snap.allows(pose, push.goal, velocity, pushed, read_s, torque):
                push = held(pose, push.distance_deg)
        previous = pose
        if (cycles or {}).get(k) == "held":
            push = held(pose)
        return pose, push

    return {"rows": run_stepped(sim, clock, servos, rig, watch, seconds, decide, cycles, cut_s)}


def exact_cases() -> dict:
    push_script = [[0.0, 0.0, 0.0], [2.0, EDGE_DEG + 20.0, 0.0], [5.0, EDGE_DEG + 20.0, 0.0]]
    rows = exact_rate_case(HAND["stiffness_nm_deg"], push_script, 7.0, let_go_s=5.0)["rows"]
    t = np.array([r["t"] for r in rows])
    pan, velocity = pan_of(rows), pan_of(rows, "velocity_deg_s")
    after = t >= 5.0
    window = np.convolve(velocity[after], np.ones(20) / 20.0, mode="valid")
    out = {
        "stop": float(np.mean(pan[(t >= 3.0) & (t < 5.0)]) - EDGE_DEG),
        "return_peak": float(np.max(-velocity[after], initial=0.0)),
        "return_window": float(np.max(-window, initial=0.0)),
        "final": float(np.mean(pan[after][-200:]) - EDGE_DEG),
        "deepest": float(EDGE_DEG - np.min(pan[after])),
        "ripples": [],
        "passes": [],
    }
    out["let_go"] = [
        let_go_case(k, beyond, law)
        for k in (0.02, 0.05, 0.2)
        for beyond in (5.0, 20.0)
        for law in ("round 6", "round 7", "round 9")
    ]
    for k in (0.02, 0.05, 0.1, 0.2):
        script = [[0.0, 0.0, 0.0], [1.5, EDGE_DEG + 5.0, 0.0], [5.0, EDGE_DEG + 5.0, 0.0]]
        rows = exact_rate_case(k, script, 4.5)["rows"]
        t, pan = np.array([r["t"] for r in rows]), pan_of(rows)
        steady = (t >= 3.0) & (t < 4.5)
        out["ripples"].append(
            {
                "stiffness": k,
                "beyond": float(np.mean(pan[steady]) - EDGE_DEG),
                "ripple": float(np.ptp(pan[steady])),
            }
        )
    for k in (0.02, 0.05, 0.2):
        rows = exact_rate_case(k, EXCURSION, 4.5)["rows"]
        out["passes"].append({"stiffness": k, **contact_energy(rows)})
    # pressed 20 deg beyond, then the hand heads back inside (pan 50 -> 0 in 0.2 s at 4 s): the
    # torque while the leader is outside, its sign, and where the outward samples fall
    pull = [[0.0, 0.0, 0.0], [2.0, EDGE_DEG + 20.0, 0.0], [4.0, EDGE_DEG + 20.0, 0.0]]
    out["pulls"] = []
    for k in (0.05, 0.2):
        rows = exact_rate_case(k, [*pull, [4.2, 0.0, 0.0]], 5.0)["rows"]
        t, pan, motor = np.array([r["t"] for r in rows]), pan_of(rows), pan_of(rows, "motor_nm")
        outward = (pan > EDGE_DEG) & (motor > 0.0)
        peer = exact_rate_case(k, [*pull, [4.2, 0.0, 0.0]], 5.0, snap_watch=False)["rows"]
        snap = exact_rate_case(k, [*pull, [4.2, 0.0, 0.0]], 5.0, brake=None)["rows"]
        out["pulls"].append(
            {
                "stiffness": k,
                "snap": int(np.sum((pan_of(snap) > EDGE_DEG) & (pan_of(snap, "motor_nm") > 0.0))),
                "peer": int(np.sum((pan_of(peer) > EDGE_DEG) & (pan_of(peer, "motor_nm") > 0.0))),
                "peer_peak": float(
                    np.max(pan_of(peer, "motor_nm")[pan_of(peer) > EDGE_DEG], initial=0.0)
                ),
                "outside": int(np.sum((pan > EDGE_DEG) & (motor != 0.0))),
                "outward": int(np.sum(outward)),
                "span_ms": float(np.ptp(t[outward]) * 1e3) if outward.any() else 0.0,
                "peak": float(np.max(motor[outward], initial=0.0)),
                "inside": int(np.sum((pan < EDGE_DEG) & (motor != 0.0))),
            }
        )
    # the same press, interrupted at 3.2 s (cycle 640): what a loaded machine does to the loop
    press = [[0.0, 0.0, 0.0], [1.5, EDGE_DEG + 5.0, 0.0], [5.0, EDGE_DEG + 5.0, 0.0]]
    out["interrupted"] = []
    for label, schedule in INTERRUPTIONS:
        for k in (0.05, 0.2):
            rows = exact_rate_case(k, press, 4.5, cycles=schedule)["rows"]
            t, pan = np.array([r["t"] for r in rows]), pan_of(rows)
            steady = (t >= 3.0) & (t < 4.5)
            out["interrupted"].append(
                {
                    "what": label,
                    "stiffness": k,
                    "ripple": float(np.ptp(pan[steady])),
                    "peak": float(np.max(pan[steady]) - EDGE_DEG),
                }
            )
    # the closed excursion with a 50 ms held gate at 1.9 s (cycle 380), on the way out
    out["passes_held"] = []
    for k in (0.05, 0.2):
        held = {i: "held" for i in range(380, 390)}
        rows = exact_rate_case(k, EXCURSION, 4.5, cycles=held)["rows"]
        out["passes_held"].append({"stiffness": k, **contact_energy(rows)})
    return out


def let_go_case(stiffness: float, beyond: float, law: str) -> dict:
    """A hand of ``stiffness`` pressing ``beyond`` deg past the edge, let go at 5 s, under round
    6's law (the law alone), round 7's (with the snap watch) or today's (round 9: the snap watch
    with its brake rules, the walking lead, two still reads to re-arm): after the let go, the
    1 ms samples outside with the motor pulling outward (count, the last one's time from the
    let go, the largest), the 1 ms and 20 ms peak return speeds, the rest and the deepest
    point."""
    script = [[0.0, 0.0, 0.0], [2.0, EDGE_DEG + beyond, 0.0], [5.0, EDGE_DEG + beyond, 0.0]]
    watch, brake = law != "round 6", BrakeLaw() if law == "round 9" else None
    rows = exact_rate_case(stiffness, script, 7.0, 5.0, snap_watch=watch, brake=brake)["rows"]
    t = np.array([r["t"] for r in rows])
    pan, velocity, motor = pan_of(rows), pan_of(rows, "velocity_deg_s"), pan_of(rows, "motor_nm")
    after = t >= 5.0
    outward = after & (pan > EDGE_DEG) & (motor > 0.0)
    window = np.convolve(-velocity[after], np.ones(20) / 20.0, mode="valid")
    return {
        "stiffness": stiffness,
        "beyond": beyond,
        "law": law,
        "outward": int(np.sum(outward)),
        "last_ms": float((t[outward].max() - 5.0) * 1e3) if outward.any() else 0.0,
        "outward_peak": float(np.max(motor[outward], initial=0.0)),
        "peak": float(np.max(-velocity[after])),
        "window": float(window.max()),
        "rest": float(np.mean(pan[after][-200:]) - EDGE_DEG),
        "deepest": float(max(EDGE_DEG - np.min(pan[after]), 0.0)),
    }


#: Interruptions of the exact-rate press (cycle 640 = 3.2 s): a stalled loop writes nothing for
#: 4 and 8 cycles (20, 40 ms); a held gate (or a follower silent past the grace) releases the
#: leader each cycle for 50 ms (10 cycles), as does one held
#: cycle alone.
INTERRUPTIONS = [
    (
        "loop stalled 20 ms, then 40 ms (late cycles)",
        {k: "late" for k in (*range(640, 644), *range(760, 768))},
    ),
    ("one held cycle (leader released 5 ms)", {640: "held"}),
    ("gate held 50 ms (10 cycles released)", {k: "held" for k in range(640, 650)}),
]
