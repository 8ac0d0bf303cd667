"""The whole flow on the embedded simulator, for a newcomer: teach, train, teleop, look.

1. teach: a scripted hand moves the simulated limb (torque off) through an irregular region
   while ``record`` samples it;
2. train: an interpolated Rigid Map learns the region from those samples alone;
3. teleop: a command stream that sweeps far outside the region (with a few NaN and malformed
   lines mixed in) is replayed through the gate at 200 Hz;
4. check: the simulator's own goal log (what reached the servos) is compared with the model's
   region, and pictures are drawn;
5. leader: a simulated operator pushes a felt leader gimbal past the learned edge; the
   follower mirrors it through the gate, the leader pushes back (leader.png). On the
   three-servo rig (``--rig sim3``) the leader has three servos and is pushed past the edge
   in swing, then in twist.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from limbctl.errors import ConfigError
from limbctl.file_jobs import TrainOptions, run_train
from limbctl.jobs import Connection, RecordOptions, TeleopOptions, run_record, run_teleop, say
from limbctl.live import LiveView, ViewOptions, leader_status, open_view
from limbctl.teleop.gate import REGION_TOLERANCE_DEG, written_tolerance_deg

#: Loop rate of the demo's teleop (Hz): the controller's default rate.
DEMO_RATE_HZ = 200.0
#: Sampling rate of the demo's recording (samples/s): the recorder's default, above its 100 Hz
#: minimum.
DEMO_RECORD_HZ = 125.0
#: Nobody is at the demo to move a limb that rests outside the learned region by hand (as it may
#: after teaching, wherever the hand let go): the servos drive it in, at a third of the fastest
#: approach allowed.
DEMO_APPROACH_DEG_S = 10.0
#: Slew limit of the demo's teleop (deg/s): the CLI's default.
DEMO_MAX_SPEED_DEG_S = 120.0
#: The simulated rigs the demo runs on: two servos, or three with a roll joint (twist).
DEMO_RIGS = ("sim", "sim3")


@dataclass(frozen=True)
class DemoOptions:
    """``limbctl demo``: everything goes to folder ``out``; ``duration`` s of teaching;
    ``seed`` for the simulator and the model."""

    out: Path = Path("limbctl-demo")
    duration: float = 60.0  # ample: tests/test_demo.py keeps every goal inside after 20 s
    seed: int = 0
    view: ViewOptions = field(default_factory=ViewOptions)
    rig: str = "sim"


def run_demo_job(options: DemoOptions) -> int:
    """The ``demo`` job: :func:`run_demo` with the command line's options."""
    return run_demo(options.out, options.duration, options.seed, options.view, options.rig)


def write_command_stream(path: Path, seconds: float = 12.0, rate_hz: float = 50.0) -> int:
    """A replay file: a wide Lissajous sweep (pan +-110, tilt -55..75 deg) with bad lines mixed in.

    12 s at 50 lines/s: one full figure, slow enough (a quarter of the loop's rate) that the
    gate's slew limit, not the stream, shapes the motion. Returns the number of valid lines.
    """
    n = int(seconds * rate_hz)
    t = np.arange(n) / rate_hz
    # a Lissajous figure that crosses the taught region and leaves it on every side (the taught
    # region spans about pan -70..80, tilt -35..60 deg)
    pan = 110.0 * np.sin(2 * math.pi * t / seconds)
    tilt = 10.0 + 65.0 * np.sin(4 * math.pi * t / seconds + 0.6)
    bad = ['{"pan": NaN, "tilt": 0}', '{"pan": 10, "tilt": "up"}', "not json at all", "{}"]
    with open(path, "w", encoding="utf-8") as fh:
        for i in range(n):
            fh.write(json.dumps({"t": round(float(t[i]), 4), "pan": pan[i], "tilt": tilt[i]}))
            fh.write("\n")
            if i % (n // len(bad)) == n // (2 * len(bad)):
                fh.write(bad[(i * len(bad)) // n] + "\n")
    return n


def goal_log_excursions(goal_log: Path, model: object) -> np.ndarray:
    """Angle (deg) by which each logged goal's limb direction lies outside the model's region.

    0 for goals inside. Uses the simulator's ``limb_dir`` (its true geometry), not the
    controller's own idea of where it sent the limb. A sync write carries both goals in one
    packet; the simulator logs one line per servo with the same ``t``, so the pose a packet
    commands is the last line of each ``t`` (earlier lines mix the new goal of one servo with
    the old goal of the other, a state that lasts no longer than the packet).
    """
    from limbctl.geometry.quat import direction_angle, limb_direction, swing_from_direction

    by_time: dict[float, list[float]] = {}
    with open(goal_log, encoding="utf-8") as fh:
        for line in fh:
            if line.strip():
                row = json.loads(line)
                by_time[row["t"]] = row["limb_dir"]
    if not by_time:
        return np.zeros(0)
    d = np.asarray(list(by_time.values()), dtype=np.float64)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    q = swing_from_direction(d)
    nearest = limb_direction(model.correct(q))
    outside = ~np.asarray(model.contains(q), dtype=bool)
    return np.where(outside, np.degrees(direction_angle(d, nearest)), 0.0)


def run_demo(
    out: Path,
    teach_seconds: float = 45.0,
    seed: int = 0,
    view: ViewOptions | None = None,
    rig: str = "sim",
) -> int:
    """Run the whole flow into folder ``out``; returns the exit status. ``view``: whether and
    where to serve the live view (one page for the teaching and the teleop); ``rig`` one of
    :data:`DEMO_RIGS` (``sim3``: three servos, the region with its twist band)."""
    if rig not in DEMO_RIGS:
        raise ConfigError(f"unknown demo rig {rig!r}; choose one of {', '.join(DEMO_RIGS)}")
    with open_view(view or ViewOptions(), say) as live:
        if rig == "sim3":
            return _run_demo_twist(Path(out), teach_seconds, seed, live)
        return _run_demo(Path(out), teach_seconds, seed, live)


def _run_demo(out: Path, teach_seconds: float, seed: int, live: LiveView) -> int:
    from limbctl.envelope import load_model
    from limbctl.session import demo_region_path

    out.mkdir(parents=True, exist_ok=True)
    data, model_path = out / "teach.limb", out / "model.npz"
    commands, goals, telemetry = (
        out / "commands.jsonl",
        out / "goals.jsonl",
        out / "telemetry.jsonl",
    )
    for stale in (data, goals):
        if stale.exists():
            raise ConfigError(f"{stale} exists from an earlier run; use another --out or remove it")

    say(f"== 1/5 teach: the simulator's hand moves the limb for {teach_seconds:.0f} s")
    simulator = Connection(seed=seed)
    run_record(
        RecordOptions(
            out=data,
            duration=teach_seconds,
            rate=DEMO_RECORD_HZ,
            hand=demo_region_path(),
            connection=simulator,
        ),
        view=live,
    )

    say("== 2/5 train: an interpolated Rigid Map learns the region from the samples alone")
    run_train(
        TrainOptions(data=data, out=model_path, kind="rigidmap", seed=seed, plot=out / "model.png")
    )

    say("== 3/5 teleop: a sweep far outside the region, replayed through the gate at 200 Hz")
    valid = write_command_stream(commands)
    say(f"   {valid} commands (+ a few NaN/malformed lines) in {commands}")
    status = run_teleop(
        TeleopOptions(
            model=model_path,
            source=f"replay:{commands}",
            rate=DEMO_RATE_HZ,
            max_speed=DEMO_MAX_SPEED_DEG_S,
            telemetry=telemetry,
            goal_log=goals,
            quiet=True,
            approach=DEMO_APPROACH_DEG_S,
            connection=simulator,
        ),
        view=live,
    )

    say("== 4/5 check: every goal the simulator received, against the model's region")
    model = load_model(model_path)
    excursion = goal_log_excursions(goals, model)
    worst = float(excursion.max()) if len(excursion) else 0.0
    bound = written_tolerance_deg()
    beyond = int((excursion > bound).sum())
    say(f"   goals received by the servos: {len(excursion)}")
    say(
        f"   largest excursion outside the learned region: {worst:.3f} deg "
        f"(bound {bound:.3f} deg: the gate's {REGION_TOLERANCE_DEG} deg + rounding to ticks)"
    )
    say(f"   goals beyond the bound: {beyond}")
    _plot_teleop(out / "teleop.png", model, data, telemetry, demo_region_path())
    say(f"   pictures: {out / 'model.png'}, {out / 'teleop.png'}")
    if beyond:
        say(f"FAILED: {beyond} goals reached the servos beyond the gate's bound; see {goals}")
        return 1
    say("== 5/5 leader: an operator pushes a felt leader past the learned edge and lets go")
    status = max(status, _leader_run(out, model_path, seed, live))
    say(f"done: everything is in {out}/")
    return status


#: The demo's leader runs are the packaged operators (limbctl/operators.py): "push" takes a
#: two-servo leader (ids 3, 4) 20 deg past the learned edge, holds it and lets go at 6 s;
#: "push3" takes a three-servo leader (ids 4-6; the follower's roll is id 3) past the swing edge,
#: back, past the twist band, and lets go at 9 s. Each run lasts 2 s (1.5 s for three) past the
#: let go, time enough to see the leader walk back to the edge.
LEADER_RUNS = {"sim": ("push", (3, 4), 8.0), "sim3": ("push3", (4, 5, 6), 10.5)}


def _leader_run(
    out: Path, model_path: Path, seed: int, live: LiveView | None = None, rig: str = "sim"
) -> int:
    """Step 5: the felt leader on the simulator (three servos on ``rig`` ``sim3``, pushed past
    the edge in swing and in twist); leader.png shows leader vs follower (pan, tilt; the twist
    too for three) and the push, and the live page (when served) draws the leader beside the
    follower with its push. A machine too busy to keep the rate with the leader's extra write
    is said so."""
    from limbctl.geometry.gimbal import pose_quat_scalar
    from limbctl.geometry.twist import decompose_one
    from limbctl.jobs import gate_for
    from limbctl.operators import load_operator
    from limbctl.plot import plot_leader
    from limbctl.servo.control_table import MAX_TICK
    from limbctl.servo.profiles import load_rig_profile
    from limbctl.servo.setup import configure_servos
    from limbctl.session import open_rig
    from limbctl.teleop.loop import LoopConfig, run
    from limbctl.teleop.sources import LeaderSource

    three = rig == "sim3"
    name, ids, seconds = LEADER_RUNS["sim3" if three else "sim"]
    operator = load_operator(name, len(ids))
    rig_path = Path(rig) if three else None
    profile = load_rig_profile(rig_path)
    gate = gate_for(model_path, profile, DEMO_RATE_HZ, DEMO_MAX_SPEED_DEG_S)
    leader = operator.leader_spec(ids)
    rows: list[tuple[float, ...]] = []

    def twist_deg(pose: tuple[float, ...]) -> float:  # about the rest axis, as the band is
        return math.degrees(decompose_one(pose_quat_scalar(*pose))[1])

    with open_rig(
        rig_path=rig_path, seed=seed, extra_ids=ids, sim_options={"leader": leader}
    ) as session:
        sim_rig = session.rig
        limits = {**sim_rig.tick_limits(), **dict.fromkeys(ids, (0, MAX_TICK))}
        configure_servos(sim_rig.bus, limits)
        source = LeaderSource(sim_rig, ids, rate_hz=DEMO_RATE_HZ)
        try:
            source.start()
        except ConfigError as exc:
            say(f"   skipped: {exc}")
            return 0
        try:
            say(f"   {source.notice}")
            sim_rig.set_torque(True)
            observe = None if live is None else live.teleop_observer
            feed = observe and observe(gate.envelope, profile, "demo: leader")
            if feed is not None:
                feed.leader = leader_status(source)

            def record(cycle) -> None:
                if feed is not None:
                    feed(cycle)
                push, result = source.last_push, cycle.result
                if cycle.complete and cycle.command_deg is not None and result is not None:
                    torque = push.torque_nm if push is not None else 0.0
                    if three and source.last_pose is not None:
                        held = source.last_pose
                        gated3 = result.pose
                        commanded = (*map(math.degrees, held[:2]), twist_deg(held))
                        gated = (*map(math.degrees, gated3[:2]), twist_deg(gated3))
                        rows.append((cycle.t, *commanded, *gated, torque))
                    elif not three:
                        gated = tuple(map(math.degrees, result.pose))
                        rows.append((cycle.t, *cycle.command_deg, *gated, torque))

            config = LoopConfig(rate_hz=DEMO_RATE_HZ, duration_s=seconds, on_cycle=record)
            session.simulator.set_operator(operator.grip)
            summary = run(sim_rig, gate, source, config)
        finally:
            source.close()
        for line in source.report_lines()[1:]:
            say(f"   {line}")
    k = len(ids)
    table = np.asarray(rows, dtype=np.float64).reshape(-1, 2 + 2 * k)
    leader_deg, follower_deg = table[:, 1 : 1 + k], table[:, 1 + k : 1 + 2 * k]
    plot_leader(out / "leader.png", table[:, 0], leader_deg, follower_deg, table[:, -1])
    say(f"   picture: {out / 'leader.png'}")
    if summary.fault:
        say(f"   the leader run ended by a fault: {summary.fault}")
    return summary.exit_code


#: Points along the hand's true outline in the teleop picture: one per half degree of a
#: region's perimeter of a few hundred degrees, finer than the picture's pixels.
TRUE_OUTLINE_POINTS = 720


def true_outline(region_yaml: Path) -> np.ndarray:
    """The region a REGION.yaml's hand teaches, as a closed outline (M, 2) in pan/tilt degrees."""
    from firmware_sim.hand import Hand

    region = Hand.from_yaml(region_yaml).region  # a twist band, if any, leaves the outline
    fractions = np.linspace(0.0, 1.0, TRUE_OUTLINE_POINTS, endpoint=False)
    return np.array([region.boundary_point(u, 0.0) for u in fractions])


def _plot_teleop(path: Path, model: object, data: Path, telemetry: Path, region_yaml: Path) -> None:
    from limbctl.geometry.gimbal import pan_tilt_to_direction
    from limbctl.plot import plot
    from limbctl.teach.dataset import load_dataset

    commanded, written = [], []
    with open(telemetry, encoding="utf-8") as fh:
        for line in fh:
            row = json.loads(line)
            if row["cmd"] is not None:
                commanded.append(row["cmd"])
            if row["written"]:
                written.append(row["out"])

    def directions(rows: list) -> np.ndarray:
        a = np.radians(np.asarray(rows, dtype=np.float64).reshape(-1, 2))
        return pan_tilt_to_direction(a[:, 0], a[:, 1])

    plot(
        path,
        samples=load_dataset(data).quaternions,
        model=model,
        title="teleop: commanded sweep vs. what the gate wrote; the hand's true region dashed",
        extra={"commanded": directions(commanded), "written (gated)": directions(written)},
        outlines={"taught by the hand (true region)": true_outline(region_yaml)},
    )


def _run_demo_twist(out: Path, teach_seconds: float, seed: int, live: LiveView) -> int:
    """The whole flow on the three-servo rig (``calib/rigs/sim3.yaml``): the hand teaches a swing
    outline with a twist band over it (``limbctl/data/demo_region3.yaml``), a Rigid Map learns
    both (``RigidMap(twist=True)``), a stream sweeping far outside in swing and twist is gated,
    and the simulator's goal log (its full orientation ``limb_q``) is judged against the learned
    region; the learned region's hold of the true region is reported."""
    from limbctl.envelope import load_model
    from limbctl.eval.twist_demo import (
        coverage,
        logged_orientations,
        twist_excursions,
        twist_picture,
        write_twist_stream,
        written_orientations,
    )
    from limbctl.session import demo_region_path
    from limbctl.teach.dataset import load_dataset

    out.mkdir(parents=True, exist_ok=True)
    data, model_path = out / "teach.limb", out / "model.npz"
    commands, goals, telemetry = (
        out / "commands.jsonl",
        out / "goals.jsonl",
        out / "telemetry.jsonl",
    )
    for stale in (data, goals):
        if stale.exists():
            raise ConfigError(f"{stale} exists from an earlier run; use another --out or remove it")
    region_yaml = demo_region_path().with_name("demo_region3.yaml")
    simulator = Connection(seed=seed, rig=Path("sim3"))

    say(f"== 1/5 teach (three servos): the hand teaches swing and twist for {teach_seconds:.0f} s")
    run_record(
        RecordOptions(
            out=data,
            duration=teach_seconds,
            rate=DEMO_RECORD_HZ,
            hand=region_yaml,
            connection=simulator,
        ),  # fmt: skip
        view=live,
    )
    say("== 2/5 train: a Rigid Map learns the swing outline and the twist band over it")
    run_train(TrainOptions(data=data, out=model_path, kind="rigidmap", seed=seed))
    say("== 3/5 teleop: a sweep far outside in swing and twist, through the gate at 200 Hz")
    valid = write_twist_stream(commands)
    say(f"   {valid} commands (+ a few malformed lines) in {commands}")
    status = run_teleop(
        TeleopOptions(
            model=model_path,
            source=f"replay:{commands}",
            rate=DEMO_RATE_HZ,
            max_speed=DEMO_MAX_SPEED_DEG_S,
            telemetry=telemetry,
            goal_log=goals,
            quiet=True,
            connection=simulator,
        ),  # fmt: skip
        view=live,
    )
    say("== 4/5 check: every goal the simulator received, against the learned region")
    model = load_model(model_path)
    excursion = twist_excursions(goals, model, written_orientations(telemetry))
    worst = float(excursion.max()) if len(excursion) else 0.0
    bound = written_tolerance_deg(joints=3)
    beyond = int((excursion > bound).sum())
    say(f"   goals received by the servos: {len(excursion)}")
    say(
        f"   largest excursion outside the learned region: {worst:.3f} deg of rotation "
        f"(bound {bound:.3f} deg: the gate's {REGION_TOLERANCE_DEG} deg + three joints' rounding)"
    )
    probes = true_twist_probes(region_yaml)
    held = coverage(model, probes)
    say(
        f"   the learned region holds {100 * held:.2f} % of {len(probes)} orientations of the "
        f"true region lying {PROBE_DEPTH_DEG:g} deg or more inside (swing and twist)"
    )
    pan, tilt, band = true_band_lines(region_yaml)
    samples, goals_q = load_dataset(data).quaternions, logged_orientations(goals)
    twist_picture(out / "twist.png", samples, goals_q, tilt, band, model=model, band_pan_deg=pan)
    say(f"   picture: {out / 'twist.png'}")
    if beyond:
        say(f"FAILED: {beyond} goals reached the servos beyond the gate's bound; see {goals}")
        return 1
    say("== 5/5 leader: an operator pushes a felt three-servo leader past the edge in swing, then")
    say("   in twist, and lets go")
    status = max(status, _leader_run(out, model_path, seed, live, rig="sim3"))
    say(f"done: everything is in {out}/")
    return status


#: How deep inside the true region (deg, in swing and in twist) the probes of the learned
#: region's hold lie: the issue's measure, 2 deg, about twice the hand's 1 deg inset at the edge.
PROBE_DEPTH_DEG = 2.0
#: Spacing (deg) of the probes over the swing plane and along each band.
PROBE_STEP_DEG = 2.0


def true_twist_probes(region_yaml: Path) -> np.ndarray:
    """Orientations (N, 4) of a REGION.yaml's true region (swing outline and twist band) lying
    PROBE_DEPTH_DEG or more inside it: swing poses on a PROBE_STEP_DEG grid whose direction is
    that far from every point of the outline (angles on the sphere), each with twists from the
    band shrunk by that much at its pose."""
    from firmware_sim.hand import Hand
    from limbctl.geometry.gimbal import pan_tilt_to_direction
    from limbctl.geometry.quat import direction_angle
    from limbctl.geometry.twist import compose

    hand = Hand.from_yaml(region_yaml)
    region, band = hand.region, hand.band
    grid = _grid_inside(region, PROBE_STEP_DEG)
    outline = np.radians(true_outline(region_yaml))
    edge = pan_tilt_to_direction(outline[:, 0], outline[:, 1])
    d = pan_tilt_to_direction(np.radians(grid[:, 0]), np.radians(grid[:, 1]))
    depth = np.degrees(direction_angle(d[:, None, :], edge[None, :, :]).min(axis=1))
    probes = []
    for (pan, tilt), direction, deep in zip(grid, d, depth, strict=True):
        if deep < PROBE_DEPTH_DEG:
            continue
        low, high = band.limits_deg(pan, tilt)
        twists = np.arange(low + PROBE_DEPTH_DEG, high - PROBE_DEPTH_DEG + 1e-9, PROBE_STEP_DEG)
        probes.append(compose(np.broadcast_to(direction, (len(twists), 3)), np.radians(twists)))
    return np.concatenate(probes) if probes else np.zeros((0, 4))


def _grid_inside(region: object, step_deg: float) -> np.ndarray:
    from firmware_sim.regions import grid_inside

    return grid_inside(region, step_deg, 0.0)


def true_band_lines(region_yaml: Path) -> tuple[float, np.ndarray, tuple[np.ndarray, np.ndarray]]:
    """The pan (deg) of the outline's centre, and the true band's limits (deg) against tilt
    there."""
    from firmware_sim.hand import Hand

    hand = Hand.from_yaml(region_yaml)
    pan = hand.region.center_deg[0]
    lo_tilt, hi_tilt = hand.region.bbox_deg[2:]
    tilt = np.linspace(lo_tilt, hi_tilt, 50)
    limits = np.array([hand.band.limits_deg(pan, t) for t in tilt])
    return pan, tilt, (limits[:, 0], limits[:, 1])
