"""The jobs behind each ``limbctl`` subcommand (argument parsing lives in :mod:`limbctl.cli`)."""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import replace
from pathlib import Path

from limbctl.errors import ConfigError
from limbctl.session import demo_region_path, load_rig_profile, open_rig, stop_on_signals


def _say(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


# ---- record ---------------------------------------------------------------------------------
def cmd_record(args: argparse.Namespace) -> int:
    from limbctl.teach.dataset import DatasetWriter
    from limbctl.teach.record import record, stop_on_enter

    profile = load_rig_profile(args.rig)
    hand = args.hand if args.hand is not None else demo_region_path()
    meta = {"rate_hz": args.rate, "simulated": args.port is None and profile.is_sim}
    # the writer checks the path and free space before any servo is touched
    with DatasetWriter(args.out, rig=profile.name, meta=meta) as writer:
        with open_rig(
            args.port,
            args.rig,
            args.baud,
            hand=hand,
            seed=args.seed,
            latency_timer_ms=args.latency_timer,
        ) as session:
            with stop_on_signals() as stop:
                if session.simulated:
                    _say(f"simulator: a scripted hand teaches the region in {hand}")
                stop_on_enter(stop)
                summary = record(
                    session.rig, writer, args.rate, args.duration, stop, progress=sys.stderr
                )
    for line in summary.lines():
        _say(line)
    _say(f"wrote {writer.count} samples to {args.out}")
    return 0


# ---- train ----------------------------------------------------------------------------------
def cmd_train(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from limbctl.teach.train import STAGES, train

    options: dict[str, object] = {}
    if args.kind == "rigidmap":
        options["seed"] = args.seed
        if args.nodes is not None:
            options["nodes"] = args.nodes
        if args.layout is not None:
            options["layout"] = args.layout
    elif args.kind == "som":
        options["seed"] = args.seed
    elif args.nodes is not None or args.layout is not None:
        raise ConfigError("--nodes and --layout apply to --kind rigidmap only")
    with tqdm(
        total=len(STAGES), desc=f"training {args.kind}", unit="stage", file=sys.stderr
    ) as bar:

        def advance(finished: str) -> None:
            following = STAGES.index(finished) + 1
            bar.set_postfix_str(STAGES[following] if following < len(STAGES) else "done")
            bar.update(1)

        summary = train(args.data, args.out, args.kind, options, progress=advance)
    for line in summary.lines():
        _say(line)
    _say(f"wrote {args.out}")
    if args.plot is not None:
        _plot_files([args.data, args.out], args.plot)
        _say(f"wrote {args.plot}")
    return 0


# ---- plot / info ----------------------------------------------------------------------------
def _plot_files(paths: list[Path], out: Path, extra: dict | None = None) -> Path:
    from limbctl.envelope import load_model
    from limbctl.errors import FileFormatError
    from limbctl.plot import plot
    from limbctl.teach.dataset import load_dataset

    samples, model, names = None, None, []
    for path in paths:
        try:
            model = load_model(path)
            names.append(f"model {path.name}")
            continue
        except FileFormatError as model_error:
            try:
                samples = load_dataset(path).quaternions
                names.append(f"data {path.name}")
            except FileFormatError as data_error:
                raise ConfigError(
                    f"{path} is neither a model ({model_error.problem}) nor a dataset "
                    f"({data_error.problem})"
                ) from None
    return plot(out, samples=samples, model=model, title=", ".join(names), extra=extra)


def cmd_plot(args: argparse.Namespace) -> int:
    _say(f"wrote {_plot_files(args.inputs, args.out)}")
    return 0


def cmd_info(args: argparse.Namespace) -> int:
    if args.file is not None:
        return _info_file(args.file)
    from limbctl.servo.control_table import Register, model_name

    with open_rig(
        args.port, args.rig, args.baud, seed=args.seed, latency_timer_ms=args.latency_timer
    ) as session:
        bus = session.rig.bus
        where = "embedded simulator" if session.simulated else bus.port_name
        print(f"bus: {where} at {bus.baud} bps, fast sync read: {bus.fast_sync_read}")
        errors = bus.read_hardware_errors()
        torque = bus.torque_enabled()
        for servo_id in bus.ids:
            print(
                f"servo {servo_id}: {model_name(bus.models[servo_id])}, firmware "
                f"{bus.firmware[servo_id]}, torque {'on' if torque[servo_id] else 'off'}"
                f", position {bus.read(Register.PRESENT_POSITION, servo_id)}, "
                f"hardware errors: {', '.join(errors[servo_id]) or 'none'}"
            )
        pan, tilt = session.rig.read_pose()
        print(f"pose: pan {math.degrees(pan):+.1f} deg, tilt {math.degrees(tilt):+.1f} deg")
    return 0


def _info_file(path: Path) -> int:
    from limbctl.envelope import load_header
    from limbctl.errors import FileFormatError
    from limbctl.teach.dataset import load_dataset

    try:
        header = load_header(path)
        print(f"{path}: {header['kind']} model, format {header['format_version']}")
        for key, value in {**header["params"], **header["metadata"]}.items():
            print(f"  {key}: {value}")
        return 0
    except FileFormatError as model_error:
        try:
            data = load_dataset(path)
        except FileFormatError:
            raise model_error from None
    print(f"{path}: dataset of {len(data)} samples from rig {data.header.rig!r}")
    print(f"  created {data.header.created}, {data.t[-1] if len(data) else 0:.1f} s recorded")
    if data.dropped_tail:
        print(f"  note: {data.dropped_tail}")
    return 0


# ---- teleop ---------------------------------------------------------------------------------
def gate_for(model_path: Path, profile, rate_hz: float, max_speed_deg_s: float):
    """Load a model (refusing one trained for another rig) and build the gate around it."""
    from limbctl.envelope import load_header, load_model
    from limbctl.teleop.gate import Gate, GateLimits

    trained_for = load_header(model_path).get("metadata", {}).get("rig")
    if trained_for and trained_for != profile.name:
        raise ConfigError(
            f"{model_path} was trained for rig {trained_for!r}, not {profile.name!r}; "
            "train a model on a recording from this rig"
        )
    step = math.radians(max_speed_deg_s) / rate_hz
    limits = GateLimits(
        pan_min=profile.pan.min_rad,
        pan_max=profile.pan.max_rad,
        tilt_min=profile.tilt.min_rad,
        tilt_max=profile.tilt.max_rad,
        max_step=step,
        max_joint_step=max(3.0 * step, math.radians(1.0)),
    )
    return Gate(load_model(model_path), limits)


def cmd_teleop(args: argparse.Namespace) -> int:
    from limbctl.teleop.loop import LoopConfig, SafeState, Telemetry, open_telemetry, run
    from limbctl.teleop.sources import open_source

    profile = load_rig_profile(args.rig)
    gate = gate_for(args.model, profile, args.rate, args.max_speed)
    config = LoopConfig(
        rate_hz=args.rate, safe_state=SafeState(args.on_fault), duration_s=args.duration
    )
    leader_ids = _leader_ids(args.source)
    with open_rig(
        args.port,
        args.rig,
        args.baud,
        goal_log=args.goal_log,
        seed=args.seed,
        extra_ids=leader_ids,
        latency_timer_ms=args.latency_timer,
    ) as session:
        if leader_ids:
            from limbctl.servo.setup import configure_servos
            from limbctl.teleop.leader import LeaderSource

            limits = session.rig.tick_limits()
            limits.update({servo_id: (0, 4095) for servo_id in leader_ids})
            configure_servos(session.rig.bus, limits)
            source = LeaderSource(session.rig, leader_ids)
        else:
            session.rig.configure()
            source = open_source(args.source)
        telemetry_file = open_telemetry(args.telemetry)
        try:
            with source, stop_on_signals() as stop:
                session.rig.set_torque(True)
                summary = run(
                    session.rig,
                    gate,
                    source,
                    config,
                    telemetry=Telemetry(telemetry_file) if telemetry_file else None,
                    status=None if args.quiet else sys.stderr,
                    stop=stop,
                )
        finally:
            if telemetry_file is not None:
                telemetry_file.close()
    for line in summary.lines():
        _say(line)
    if summary.fault:
        _say(f"FAULT: {summary.fault}")
    return summary.exit_code


def _leader_ids(spec: str) -> tuple[int, ...]:
    if not spec.startswith("leader:"):
        return ()
    try:
        ids = tuple(int(i) for i in spec[len("leader:") :].split(","))
    except ValueError:
        raise ConfigError(f"bad leader source {spec!r}; expected leader:ID,ID") from None
    if len(ids) != 2:
        raise ConfigError(f"bad leader source {spec!r}; expected leader:ID,ID (pan, tilt)")
    return ids


# ---- calibrate ------------------------------------------------------------------------------
def cmd_calibrate(args: argparse.Namespace) -> int:
    from importlib import resources

    from limbctl.servo.calibrate import find_zero_and_directions, profile_from_calibration
    from limbctl.servo.profiles import save_rig_profile

    base = load_rig_profile(args.rig)
    pan_id, tilt_id = _pair(args.ids, "--ids")
    base = replace(base, pan=replace(base.pan, id=pan_id), tilt=replace(base.tilt, id=tilt_id))
    script = Path(str(resources.files("limbctl").joinpath("data", "calibration_hand.yaml")))
    with open_rig(
        args.port,
        args.rig,
        args.baud,
        hand=script,
        seed=args.seed,
        latency_timer_ms=args.latency_timer,
    ) as session:
        if session.simulated:
            _say("simulator: a scripted hand follows the prompts below")
        with stop_on_signals() as stop:
            result = find_zero_and_directions(session.rig, say=_say, stop=stop)
        port = "sim" if session.simulated else session.rig.bus.port_name
    pan_limits = _limits(args.pan_limits, "--pan-limits", (base.pan.min_deg, base.pan.max_deg))
    tilt_limits = _limits(args.tilt_limits, "--tilt-limits", (base.tilt.min_deg, base.tilt.max_deg))
    profile = profile_from_calibration(base, result, args.name, port, pan_limits, tilt_limits)
    save_rig_profile(profile, args.out)
    _say(
        f"pan: zero tick {result.pan_zero}, direction {result.pan_direction:+d}; "
        f"tilt: zero tick {result.tilt_zero}, direction {result.tilt_direction:+d}"
    )
    _say(f"wrote {args.out} (check the hard limits in it before teleoperating)")
    return 0


def _limits(text: str | None, option: str, default: tuple[float, float]) -> tuple[float, float]:
    if text is None:
        return default
    try:
        lo, hi = (float(v) for v in text.split(","))
    except ValueError:
        raise ConfigError(
            f"{option} expects MIN,MAX in degrees like -90,90; got {text!r}"
        ) from None
    if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
        raise ConfigError(f"{option}: need finite MIN < MAX, got {text!r}")
    return lo, hi


def _pair(text: str, option: str) -> tuple[int, int]:
    try:
        a, b = (int(v) for v in text.split(","))
    except ValueError:
        raise ConfigError(f"{option} expects two integers like 1,2; got {text!r}") from None
    return a, b


# ---- eval -----------------------------------------------------------------------------------
def cmd_eval(args: argparse.Namespace) -> int:
    from limbctl.eval.experiments import run_eval

    return int(run_eval(out=args.out, quick=args.quick, jobs=args.jobs))


# ---- demo -----------------------------------------------------------------------------------
def cmd_demo(args: argparse.Namespace) -> int:
    from limbctl.demo import run_demo

    return run_demo(args.out, args.duration, args.seed)
