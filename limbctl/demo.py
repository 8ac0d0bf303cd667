"""The whole flow on the embedded simulator, for a newcomer: teach, train, teleop, check, leader;
what differs by rig is a :class:`DemoRig` in :data:`RIGS`."""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from limbctl.errors import ConfigError
from limbctl.eval.twist_demo import (
    coverage,
    logged_orientations,
    logged_packets,
    twist_excursions,
    twist_picture,
    write_stream,
    write_twist_stream,
    written_orientations,
)
from limbctl.file_jobs import TrainOptions, run_train
from limbctl.jobs import Connection, RecordOptions, TeleopOptions, run_record, run_teleop, say
from limbctl.live import LiveView, ViewOptions, leader_status, open_view
from limbctl.session import demo_region_path
from limbctl.teleop.gate import REGION_TOLERANCE_DEG, written_tolerance_deg
from limbctl.view.twist import pose_twist

#: The CLI's defaults: loop rate (Hz), recording rate (samples/s), slew limit (deg/s).
DEMO_RATE_HZ = 200.0
DEMO_RECORD_HZ = 125.0
DEMO_MAX_SPEED_DEG_S = 120.0
#: Nobody is there to move a limb resting outside by hand: the servos drive it in (deg/s).
DEMO_APPROACH_DEG_S = 10.0


@dataclass(frozen=True)
class DemoRig:
    """What the demo does differently on one simulated rig: its profile (None: two servos), the
    hand's REGION.yaml in ``limbctl/data``, the command stream, ``judge(goals, model, telemetry)
    -> (N,)`` deg outside the learned region per goal, step 4's ``report``, the ``approach``
    (deg/s; None waits), the ``leader`` (operator, ids, seconds) and its rows (deg) for
    leader.png, and the printed lines (formatted with the step's figures)."""

    profile: Path | None
    joints: int
    region_file: str
    write_stream: Callable[[Path], int]
    judge: Callable[[Path, object, Path], np.ndarray]
    report: Callable[[Path, object, Path, int], None]
    approach: float | None
    train_plot: str | None
    leader: tuple[str, tuple[int, ...], float]
    leader_row: Callable[[object, object], tuple[float, ...] | None]
    teach: str
    train: str
    teleop: str
    stream: str
    check: str
    excursion: str
    push: str


def run_demo(
    out: Path,
    teach_seconds: float = 45.0,
    seed: int = 0,
    view: ViewOptions | None = None,
    rig: str = "sim",
) -> int:
    """Run the whole flow into folder ``out`` on ``rig`` (:data:`DEMO_RIGS`); the exit status."""
    if rig not in RIGS:
        raise ConfigError(f"unknown demo rig {rig!r}; choose one of {', '.join(DEMO_RIGS)}")
    with open_view(view or ViewOptions(), say) as live:
        return _run_flow(Path(out), teach_seconds, seed, live, RIGS[rig])


def _run_flow(out: Path, teach_seconds: float, seed: int, live: LiveView, spec: DemoRig) -> int:
    from limbctl.envelope import load_model

    out.mkdir(parents=True, exist_ok=True)
    data, model_path = out / "teach.limb", out / "model.npz"
    commands, goals, telemetry = (out / f"{n}.jsonl" for n in ("commands", "goals", "telemetry"))
    for stale in (data, goals):
        if stale.exists():
            raise ConfigError(f"{stale} exists from an earlier run; use another --out or remove it")
    region_yaml = demo_region_path().with_name(spec.region_file)
    sim = Connection(seed=seed, rig=spec.profile)

    say(spec.teach.format(seconds=teach_seconds))
    teach = RecordOptions(
        out=data, duration=teach_seconds, rate=DEMO_RECORD_HZ, hand=region_yaml, connection=sim
    )
    run_record(teach, view=live)

    say(spec.train)
    plot = out / spec.train_plot if spec.train_plot else None
    run_train(TrainOptions(data=data, out=model_path, kind="rigidmap", seed=seed, plot=plot))

    say(spec.teleop)
    valid = spec.write_stream(commands)
    say(spec.stream.format(valid=valid, path=commands))
    status = run_teleop(
        TeleopOptions(
            model=model_path,
            source=f"replay:{commands}",
            rate=DEMO_RATE_HZ,
            max_speed=DEMO_MAX_SPEED_DEG_S,
            telemetry=telemetry,
            goal_log=goals,
            quiet=True,
            approach=spec.approach,
            connection=sim,
        ),
        view=live,
    )

    say(spec.check)
    model = load_model(model_path)
    excursion = spec.judge(goals, model, telemetry)
    worst = float(excursion.max()) if len(excursion) else 0.0
    bound = written_tolerance_deg(joints=spec.joints)
    beyond = int((excursion > bound).sum())
    say(f"   goals received by the servos: {len(excursion)}")
    say(spec.excursion.format(worst=worst, bound=bound, tolerance=REGION_TOLERANCE_DEG))
    spec.report(out, model, region_yaml, beyond)
    if beyond:
        say(f"FAILED: {beyond} goals reached the servos beyond the gate's bound; see {goals}")
        return 1
    say(spec.push)
    status = max(status, _leader_run(out, model_path, seed, live, spec))
    say(f"done: everything is in {out}/")
    return status


def _leader_run(out: Path, model: Path, seed: int, live: LiveView | None, spec: DemoRig) -> int:
    """Step 5: the felt leader pushed past the learned edge and let go, drawn to leader.png."""
    from limbctl.jobs import gate_for
    from limbctl.operators import load_operator
    from limbctl.plot import plot_leader
    from limbctl.servo.profiles import load_rig_profile
    from limbctl.session import configure, open_rig
    from limbctl.teleop.loop import LoopConfig, run
    from limbctl.teleop.sources import LeaderSource

    name, ids, seconds = spec.leader
    operator = load_operator(name, len(ids))
    profile = load_rig_profile(spec.profile)
    gate = gate_for(model, profile, DEMO_RATE_HZ, DEMO_MAX_SPEED_DEG_S)
    leader = operator.leader_spec(ids)
    rows: list[tuple[float, ...]] = []

    with open_rig(
        rig_path=spec.profile, seed=seed, extra_ids=ids, sim_options={"leader": leader}
    ) as session:
        sim_rig = session.rig
        configure(sim_rig, ids)
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
                push = source.last_push
                if cycle.complete and cycle.command_deg is not None and cycle.result is not None:
                    row = spec.leader_row(cycle, source)
                    if row is not None:
                        rows.append((cycle.t, *row, push.torque_nm if push is not None else 0.0))

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


def _twist_row(cycle, source) -> tuple[float, ...] | None:
    """Three servos: leader's held and gated pose (pan, tilt, twist deg); None before a hold."""

    def deg(pose: tuple[float, ...]) -> tuple[float, ...]:
        return (*map(math.degrees, pose[:2]), math.degrees(pose_twist(*pose)))

    held = source.last_pose
    return None if held is None else (*deg(held), *deg(cycle.result.pose))


def write_command_stream(path: Path, seconds: float = 12.0, rate_hz: float = 50.0) -> int:
    """A replay file: a sweep (pan +-110, tilt -55..75 deg), bad lines mixed in; the valid lines."""
    n = int(seconds * rate_hz)
    t = np.arange(n) / rate_hz
    # crosses the taught region (about pan -70..80, tilt -35..60 deg) and leaves it on every side
    pan = 110.0 * np.sin(2 * math.pi * t / seconds)
    tilt = 10.0 + 65.0 * np.sin(4 * math.pi * t / seconds + 0.6)
    bad = ['{"pan": NaN, "tilt": 0}', '{"pan": 10, "tilt": "up"}', "not json at all", "{}"]
    rows = [{"t": round(float(t[i]), 4), "pan": pan[i], "tilt": tilt[i]} for i in range(n)]
    return write_stream(path, rows, bad)


def goal_log_excursions(goal_log: Path, model: object) -> np.ndarray:
    """Angle (deg) by which each logged goal's ``limb_dir`` lies outside the model (0 inside)."""
    from limbctl.geometry.quat import direction_angle, limb_direction, swing_from_direction

    d = logged_packets(goal_log, "limb_dir", 3)
    if not len(d):
        return np.zeros(0)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    q = swing_from_direction(d)
    nearest = limb_direction(model.correct(q))
    outside = ~np.asarray(model.contains(q), dtype=bool)
    return np.where(outside, np.degrees(direction_angle(d, nearest)), 0.0)


#: Points along the hand's true outline: finer than the picture's pixels.
TRUE_OUTLINE_POINTS = 720


def true_outline(region_yaml: Path) -> np.ndarray:
    """The region a REGION.yaml's hand teaches, as a closed outline (M, 2), pan/tilt deg."""
    from firmware_sim.hand import Hand

    region = Hand.from_yaml(region_yaml).region  # a twist band, if any, leaves the outline
    fractions = np.linspace(0.0, 1.0, TRUE_OUTLINE_POINTS, endpoint=False)
    return np.array([region.boundary_point(u, 0.0) for u in fractions])


def _report_gimbal(out: Path, model: object, region_yaml: Path, beyond: int) -> None:
    """Two servos: the goals past the bound, and teleop.png (commanded vs. written)."""
    from limbctl.geometry.gimbal import pan_tilt_to_direction
    from limbctl.plot import plot
    from limbctl.teach.dataset import load_dataset

    say(f"   goals beyond the bound: {beyond}")
    with open(out / "telemetry.jsonl", encoding="utf-8") as fh:
        rows = [json.loads(line) for line in fh]
    commanded = [row["cmd"] for row in rows if row["cmd"] is not None]
    written = [row["out"] for row in rows if row["written"]]

    def directions(rows: list) -> np.ndarray:
        a = np.radians(np.asarray(rows, dtype=np.float64).reshape(-1, 2))
        return pan_tilt_to_direction(a[:, 0], a[:, 1])

    plot(
        out / "teleop.png",
        samples=load_dataset(out / "teach.limb").quaternions,
        model=model,
        title="teleop: commanded sweep vs. what the gate wrote; the hand's true region dashed",
        extra={"commanded": directions(commanded), "written (gated)": directions(written)},
        outlines={"taught by the hand (true region)": true_outline(region_yaml)},
    )
    say(f"   pictures: {out / 'model.png'}, {out / 'teleop.png'}")


def _report_twist(out: Path, model: object, region_yaml: Path, beyond: int) -> None:
    """Three servos: how much of the true region the learned one holds, and twist.png."""
    from limbctl.teach.dataset import load_dataset

    probes = true_twist_probes(region_yaml)
    held = coverage(model, probes)
    say(
        f"   the learned region holds {100 * held:.2f} % of {len(probes)} orientations of the "
        f"true region lying {PROBE_DEPTH_DEG:g} deg or more inside (swing and twist)"
    )
    pan, tilt, band = true_band_lines(region_yaml)
    samples = load_dataset(out / "teach.limb").quaternions
    goals_q = logged_orientations(out / "goals.jsonl")
    twist_picture(out / "twist.png", samples, goals_q, tilt, band, model=model, band_pan_deg=pan)
    say(f"   picture: {out / 'twist.png'}")


#: Depth (deg) of the probes inside the true region: twice the hand's 1 deg inset at the edge.
PROBE_DEPTH_DEG = 2.0
#: Spacing (deg) of the probes over the swing plane and along each band.
PROBE_STEP_DEG = 2.0


def true_twist_probes(region_yaml: Path) -> np.ndarray:
    """Orientations (N, 4) of a REGION.yaml's true region lying PROBE_DEPTH_DEG or more inside it
    (swing on a PROBE_STEP_DEG grid, twists from the band shrunk by that much)."""
    from firmware_sim.hand import Hand
    from firmware_sim.regions import grid_inside
    from limbctl.geometry.gimbal import pan_tilt_to_direction
    from limbctl.geometry.quat import direction_angle
    from limbctl.geometry.twist import compose

    hand = Hand.from_yaml(region_yaml)
    region, band = hand.region, hand.band
    grid = grid_inside(region, PROBE_STEP_DEG, 0.0)
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


def true_band_lines(region_yaml: Path) -> tuple[float, np.ndarray, tuple[np.ndarray, np.ndarray]]:
    """The outline centre's pan (deg), and the true band's limits (deg) against tilt there."""
    from firmware_sim.hand import Hand

    hand = Hand.from_yaml(region_yaml)
    pan = hand.region.center_deg[0]
    lo_tilt, hi_tilt = hand.region.bbox_deg[2:]
    tilt = np.linspace(lo_tilt, hi_tilt, 50)
    limits = np.array([hand.band.limits_deg(pan, t) for t in tilt])
    return pan, tilt, (limits[:, 0], limits[:, 1])


#: The demo's rigs by name; a leader run lasts 1.5-2 s past its operator's let go.
RIGS = {
    "sim": DemoRig(
        profile=None,
        joints=2,
        region_file="demo_region.yaml",
        write_stream=write_command_stream,
        judge=lambda goals, model, telemetry: goal_log_excursions(goals, model),
        report=_report_gimbal,
        approach=DEMO_APPROACH_DEG_S,
        train_plot="model.png",
        leader=("push", (3, 4), 8.0),
        leader_row=lambda cycle, source: (
            *cycle.command_deg,
            *map(math.degrees, cycle.result.pose),
        ),
        teach="== 1/5 teach: the simulator's hand moves the limb for {seconds:.0f} s",
        train="== 2/5 train: an interpolated Rigid Map learns the region from the samples alone",
        teleop="== 3/5 teleop: a sweep far outside the region, replayed through the gate at 200 Hz",
        stream="   {valid} commands (+ a few NaN/malformed lines) in {path}",
        check="== 4/5 check: every goal the simulator received, against the model's region",
        excursion="   largest excursion outside the learned region: {worst:.3f} deg "
        "(bound {bound:.3f} deg: the gate's {tolerance} deg + rounding to ticks)",
        push="== 5/5 leader: an operator pushes a felt leader past the learned edge and lets go",
    ),
    "sim3": DemoRig(
        profile=Path("sim3"),
        joints=3,
        region_file="demo_region3.yaml",
        write_stream=write_twist_stream,
        judge=lambda goals, model, tel: twist_excursions(goals, model, written_orientations(tel)),
        report=_report_twist,
        approach=None,
        train_plot=None,
        leader=("push3", (4, 5, 6), 10.5),
        leader_row=_twist_row,
        teach="== 1/5 teach (three servos): the hand teaches swing and twist for {seconds:.0f} s",
        train="== 2/5 train: a Rigid Map learns the swing outline and the twist band over it",
        teleop="== 3/5 teleop: a sweep far outside in swing and twist, through the gate at 200 Hz",
        stream="   {valid} commands (+ a few malformed lines) in {path}",
        check="== 4/5 check: every goal the simulator received, against the learned region",
        excursion="   largest excursion outside the learned region: {worst:.3f} deg of rotation "
        "(bound {bound:.3f} deg: the gate's {tolerance} deg + three joints' rounding)",
        push="== 5/5 leader: an operator pushes a felt three-servo leader past the edge in swing, "
        "then\n   in twist, and lets go",
    ),
}
#: The simulated rigs the demo runs on.
DEMO_RIGS = tuple(RIGS)
