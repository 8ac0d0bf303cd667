"""The jobs that drive servos (record, teleop, calibrate): options in, an exit status out, words
to stderr, failures raised as LimbctlError."""

from __future__ import annotations

import contextlib
import math
import sys
from contextlib import AbstractContextManager
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from calib.profile import RigProfile
from limbctl.errors import ConfigError
from limbctl.live import LiveView, ViewOptions, leader_status, open_view
from limbctl.servo.profiles import load_rig_profile
from limbctl.session import Session, configure, open_rig, stop_on_signals
from limbctl.teleop.gate import Gate
from limbctl.teleop.loop import SafeState
from limbctl.teleop.start import DEFAULT_WAIT_S

if TYPE_CHECKING:
    from collections.abc import Iterator

    from limbctl.operators import SimOperator
    from limbctl.teleop.sources import CommandSource, SourceSpec


def say(text: str) -> None:
    """One line for the person at the terminal (stderr, flushed)."""
    print(text, file=sys.stderr, flush=True)


def prepare(stage: str) -> None:
    """Say why a first run waits: the kernels of ``stage`` are not all cached yet."""
    from limbctl.geometry import jit

    if jit.cache_dir() is None or jit.prepared(stage):
        return  # in memory, every run compiles (the cache's own line said so); or all is ready
    say("preparing (first run only)")


def _say_wire_budget(rate_hz: float, bus: Any) -> None:
    """Warn when the bus's baud cannot carry ``rate_hz``."""
    from limbctl.servo.cycle import wire_budget

    problem = wire_budget(rate_hz, bus.baud, len(bus.ids), bool(bus.fast_sync_read))
    if problem:
        say(f"warning: {problem}")


@dataclass(frozen=True)
class Connection:
    """Where the servos are (the CLI's connection options; see :func:`open_rig`)."""

    port: str | None = None
    rig: Path | None = None
    baud: int | None = None
    latency_timer_ms: float | None = None
    seed: int = 0


@dataclass(frozen=True)
class RecordOptions:
    """``limbctl record``: the command line's options (``rate`` samples/s, ``duration`` s)."""

    out: Path
    duration: float | None = None
    rate: float = 125.0  # above the recorder's 100 Hz minimum with room for a late sample
    hand: Path | None = None
    connection: Connection = field(default_factory=Connection)
    view: ViewOptions = field(default_factory=ViewOptions)


def _viewing(options: ViewOptions, view: LiveView | None):
    """``view`` when the caller has one open, else a view opened as ``options`` ask."""
    return contextlib.nullcontext(view) if view is not None else open_view(options, say)


def run_record(options: RecordOptions, view: LiveView | None = None) -> int:
    """Torque off, record the limb moved by hand (shown live); 0, or 3 after a bus failure."""
    from limbctl.session import demo_region_path
    from limbctl.teach.dataset import DatasetWriter
    from limbctl.teach.record import SIM_LATENCY_TIMER_MS, check_rate, record, stop_on_enter
    from limbctl.teach.warm import warming_in_background

    check_rate(options.rate)
    conn = options.connection
    profile = load_rig_profile(conn.rig)
    hand = options.hand if options.hand is not None else demo_region_path()
    if options.hand is None and profile.twists:  # the packaged region with twist
        hand = hand.with_name("demo_region3.yaml")
    meta = {"rate_hz": options.rate, "simulated": conn.port is None and profile.is_sim}
    if meta["simulated"] and conn.latency_timer_ms is None:  # late replies kept: see the constant
        conn = replace(conn, latency_timer_ms=SIM_LATENCY_TIMER_MS)
    writer = DatasetWriter(
        options.out, rig=profile.name, meta=meta, calibration=profile.calibration
    )
    with (
        _viewing(options.view, view) as live,
        open_connection(conn, hand=hand) as session,
        # the first train and teleop then find their kernels compiled (this rig's: twist or not)
        warming_in_background(twist=profile.twists),
    ):
        with writer:
            with stop_on_signals() as stop, live.teaching(session.rig, session.profile) as taught:
                if session.simulated:
                    say(f"simulator: a scripted hand teaches the region in {hand}")
                stop_on_enter(stop)
                summary = record(
                    taught.limb,
                    writer,
                    options.rate,
                    options.duration,
                    stop,
                    progress=sys.stderr,
                    on_guidance=taught.on_guidance,
                    on_twist=taught.on_twist,
                )
    for line in summary.lines():
        say(line)
    say(f"wrote {writer.count} samples to {options.out}")
    return summary.exit_code


def gate_for(model_path: Path, profile: RigProfile, rate_hz: float, max_speed_deg_s: float) -> Gate:
    """The gate around a model file, refusing a model trained for another rig or calibration."""
    from limbctl.envelope import load_header, load_model
    from limbctl.servo.profiles import check_trained_for
    from limbctl.teleop.gate import GateLimits

    check_trained_for(load_header(model_path).get("metadata", {}), profile, str(model_path))
    step = math.radians(max_speed_deg_s) / rate_hz
    # a joint may move 3 Cartesian steps per cycle (pan turns fast near the pole), never under 1 deg
    limits = GateLimits.for_profile(profile, step, max(3.0 * step, math.radians(1.0)))
    return Gate(load_model(model_path), limits)


@dataclass(frozen=True)
class TeleopOptions:
    """``limbctl teleop``: the command line's options."""

    model: Path
    source: str = "stdin"
    rate: float = 200.0  # the loop's default (see LoopConfig.rate_hz)
    max_speed: float = 120.0  # a brisk hand's speed, well under an XL430's ~340 deg/s
    on_fault: SafeState = SafeState.HOLD
    duration: float | None = None
    telemetry: Path | None = None
    goal_log: Path | None = None
    quiet: bool = False
    wait: float = DEFAULT_WAIT_S
    approach: float | None = None
    operator: str | None = None
    connection: Connection = field(default_factory=Connection)
    view: ViewOptions = field(default_factory=ViewOptions)


def run_teleop(options: TeleopOptions, view: LiveView | None = None) -> int:
    """Start (waiting or approaching when outside), run the loop, park the limb (shown live); 0, 2
    when it never started or refused every line, 3 after a fault, 130 when stopped waiting."""
    from limbctl.geometry.jit import stage as jit_stage
    from limbctl.teleop.lifecycle import run_session
    from limbctl.teleop.loop import LoopConfig
    from limbctl.teleop.sources import SourceContext, check_leader_fits, parse_source
    from limbctl.teleop.start import StartOptions

    spec = parse_source(options.source)  # a bad source is refused before anything opens
    view_options = options.view
    if spec.kind.scheme == "page":  # the page is the source: the view must be served
        if view_options.enabled is False:
            raise ConfigError("--source page steers from the live view: drop --no-view")
        view_options = replace(view_options, enabled=True)
    conn = options.connection
    profile = load_rig_profile(conn.rig)
    if spec.kind.scheme == "leader":  # before any port opens
        check_leader_fits(spec.extra_ids, profile)
    gate = gate_for(options.model, profile, options.rate, options.max_speed)
    prepare(jit_stage("gate", profile.twists))
    starting = StartOptions(options.wait, options.approach, options.rate)  # checked before opening
    operator = _sim_operator(options.operator, spec, conn, profile)
    sim_options = None if operator is None else {"leader": operator.leader_spec(spec.extra_ids)}
    with (
        _viewing(view_options, view) as live,
        open_connection(
            conn, goal_log=options.goal_log, extra_ids=spec.extra_ids, sim_options=sim_options
        ) as session,
    ):
        config = LoopConfig(
            rate_hz=options.rate,
            safe_state=options.on_fault,
            duration_s=options.duration,
            on_cycle=live.teleop_observer(gate.envelope, profile),
        )
        rig = session.rig
        # read before configuring switches it off: a limb outside is then told why it went limp
        torque_was_on = any(rig.torque_enabled())
        configure(rig, spec.extra_ids)
        _say_wire_budget(options.rate, rig.bus)
        context = SourceContext(rig=rig, rate_hz=options.rate, gate=gate, page=live.page_connect)
        reporting = {
            "telemetry_path": options.telemetry,
            "stream": sys.stderr,
            "status": None if options.quiet else sys.stderr,
        }

        opened: list[CommandSource] = []

        @contextlib.contextmanager
        def introduced(built: CommandSource) -> Iterator[CommandSource]:
            with built as source:
                opened.append(source)
                if spec.kind.scheme == "page":  # printed once: whoever has it can steer
                    say(
                        f"steer from this address (it holds this session's key): {live.control_url}"
                    )
                if source.report_lines():
                    say(source.report_lines()[0])  # what the leader will do, before it starts
                if getattr(source, "felt", False) and config.on_cycle is not None:
                    # the page says how hard a felt leader pushes back
                    config.on_cycle.push_nm = lambda: getattr(source.last_push, "torque_nm", 0.0)
                if source.name == "leader" and config.on_cycle is not None:
                    config.on_cycle.leader = leader_status(source)  # its pose and push, drawn
                if operator is not None:
                    say(operator.describe())
                    session.simulator.set_operator(operator.grip)
                yield source

        with stop_on_signals() as stop:  # the source opens once the limb is held inside
            result = run_session(
                rig, gate, lambda: introduced(spec.open(context)), config, starting, **reporting,
                stop=stop, torque_was_on=torque_was_on, publish=live.start_observer(),
            )  # fmt: skip
    from limbctl.geometry.jit import mark_prepared

    mark_prepared(jit_stage("gate", profile.twists))
    extra = opened[0].report_lines()[1:] if opened else ()
    for line in (*result.lines(), *extra):
        say(line)
    return result.exit_code


def _sim_operator(
    name: str | None, spec: SourceSpec, conn: Connection, profile: RigProfile
) -> SimOperator | None:
    """The simulated operator ``--operator`` names (refused on real servos or without a leader)."""
    if name is None:
        return None
    if conn.port is not None or not profile.is_sim:
        raise ConfigError(
            "--operator moves the embedded simulator's leader; with --port, move the leader by "
            "hand (drop --operator)"
        )
    if spec.kind.scheme != "leader":
        raise ConfigError("--operator holds a leader: use it with --source leader:ID,ID")
    from limbctl.operators import load_operator

    return load_operator(name, len(spec.extra_ids))


@dataclass(frozen=True)
class CalibrateOptions:
    """``limbctl calibrate``: the command line's options (``*_limits``, ``*_stops`` in deg)."""

    out: Path
    name: str = "my-rig"
    ids: tuple[int, ...] | None = None
    pan_limits: tuple[float, float] | None = None
    tilt_limits: tuple[float, float] | None = None
    roll_limits: tuple[float, float] | None = None
    pan_stops: tuple[float, float] | None = None
    tilt_stops: tuple[float, float] | None = None
    roll_stops: tuple[float, float] | None = None
    connection: Connection = field(default_factory=Connection)


def run_calibrate(options: CalibrateOptions) -> int:
    """Find each joint's zero tick and direction by hand and write the rig profile."""
    from importlib import resources

    from limbctl.servo.calibrate import find_zero_and_directions, profile_from_calibration
    from limbctl.servo.profiles import save_rig_profile

    conn = options.connection
    base = _calibration_base(options, load_rig_profile(conn.rig))
    # the simulator's person follows the prompts: three steps, or four with a roll joint
    name = "calibration_hand3.yaml" if base.twists else "calibration_hand.yaml"
    script = Path(str(resources.files("limbctl").joinpath("data", name)))
    # the servos the person named: the chosen profile's ids, not the base profile's
    with open_connection(conn, hand=script, profile=base) as session:
        if session.simulated:
            say("simulator: a scripted hand follows the prompts below")
        with stop_on_signals() as stop:
            result = find_zero_and_directions(session.rig, say=say, stop=stop)
        port = "sim" if session.simulated else session.rig.bus.port_name
    pan_limits = (base.pan.min_deg, base.pan.max_deg)
    tilt_limits = (base.tilt.min_deg, base.tilt.max_deg)
    profile = profile_from_calibration(base, result, options.name, port, pan_limits, tilt_limits)
    save_rig_profile(profile, options.out)
    found = [("pan", result.pan_zero, result.pan_direction)]
    found.append(("tilt", result.tilt_zero, result.tilt_direction))
    if result.roll_zero is not None:
        found.append(("roll", result.roll_zero, result.roll_direction))
    say("; ".join(f"{j}: zero tick {zero}, direction {sign:+d}" for j, zero, sign in found))
    say(f"wrote {options.out} (check the hard limits in it before teleoperating)")
    return 0


def _calibration_base(options: CalibrateOptions, base):
    """``base`` with the chosen ids, hard limits and end stops, checked before any servo moves."""
    from calib.profile import (
        DEFAULT_END_STOP_DEG,
        END_STOP_MARGIN_DEG,
        ProfileError,
        default_sim_profile,
        profile_from_dict,
    )

    conn = options.connection
    ids = options.ids or tuple(joint.id for _, joint in base.joints)
    if len(ids) == 3 and not base.twists:  # a roll joint to start from: the sim3 rig's
        base = base.with_joints(roll=default_sim_profile("sim3").roll)
    elif len(ids) == 2 and base.twists:
        raise ConfigError(
            f"the rig profile {base.name!r} has a roll joint (servo {base.roll.id}): give three "
            "ids, --ids PAN,TILT,ROLL"
        )
    # the base profile's end stops describe this gimbal if it was named, or is the simulator's
    describes_gimbal = conn.rig is not None or (conn.port is None and base.is_sim)
    unknown = (-DEFAULT_END_STOP_DEG, DEFAULT_END_STOP_DEG)
    joints = {}
    if len(ids) == 2 and (options.roll_limits or options.roll_stops):
        raise ConfigError("--roll-limits and --roll-stops need a roll joint: --ids PAN,TILT,ROLL")
    for servo_id, name in zip(ids, ("pan", "tilt", "roll"), strict=False):
        limits, stops = getattr(options, f"{name}_limits"), getattr(options, f"{name}_stops")
        joint = getattr(base, name)
        stops = stops or ((joint.stop_min_deg, joint.stop_max_deg) if describes_gimbal else unknown)
        if limits is None:  # the base profile's, narrowed inside these end stops by the margin
            low = max(joint.min_deg, stops[0] + END_STOP_MARGIN_DEG)
            high = min(joint.max_deg, stops[1] - END_STOP_MARGIN_DEG)
            if (low, high) != (joint.min_deg, joint.max_deg):
                say(
                    f"{name} hard limits {low:g}..{high:g} deg ({END_STOP_MARGIN_DEG:g} deg inside "
                    f"the end stops {stops[0]:g}..{stops[1]:g}); --{name}-limits chooses others"
                )
            limits = (low, high)
        joints[name] = replace(
            joint,
            id=servo_id,
            min_deg=float(limits[0]),
            max_deg=float(limits[1]),
            stop_min_deg=float(stops[0]),
            stop_max_deg=float(stops[1]),
        )
    chosen = replace(base.with_joints(**joints), source=None)
    try:
        profile_from_dict(chosen.to_dict(), "the chosen limits")
    except ProfileError as exc:
        raise ConfigError(
            f"{exc} (give hard limits inside the end stops: --pan-limits inside --pan-stops, "
            f"--tilt-limits inside --tilt-stops, --roll-limits inside --roll-stops)"
        ) from None
    return chosen


def open_connection(conn: Connection, **rig_options: Any) -> AbstractContextManager[Session]:
    """:func:`open_rig` for a connection; ``rig_options`` are its other keywords."""
    return open_rig(
        conn.port,
        conn.rig,
        conn.baud,
        seed=conn.seed,
        latency_timer_ms=conn.latency_timer_ms,
        **rig_options,
    )
