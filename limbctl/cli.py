"""The ``limbctl`` command line: one small parser per subcommand, each calling a typed job.
Errors print one message and exit with status 2; a fault during teleop exits with 3."""

from __future__ import annotations

import argparse
import math
import os
import sys
from collections.abc import Callable
from dataclasses import fields
from pathlib import Path
from typing import TypeVar

from calib.yaml_guard import shown
from limbctl import file_jobs, jobs, upkeep
from limbctl.demo import DEMO_RIGS, run_demo
from limbctl.envelope import MODEL_KINDS
from limbctl.errors import ConfigError, LimbctlError
from limbctl.live import DEFAULT_PORT as DEFAULT_VIEW_PORT
from limbctl.live import ViewOptions
from limbctl.operators import OPERATORS
from limbctl.teach import warm
from limbctl.teleop.loop import SafeState
from limbctl.teleop.start import DEFAULT_WAIT_S, MAX_APPROACH_SPEED_DEG_S

EPILOG_HARDWARE = (
    "On real hardware: give --port (e.g. /dev/ttyUSB0 for a U2D2) and --rig (a profile written "
    "by `limbctl calibrate`). Without --port the embedded simulator is started."
)

Subparsers = argparse._SubParsersAction
Job = Callable[[argparse.Namespace], int]
Options = TypeVar("Options")


def _positive(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {shown(text)}") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected a positive number, got {shown(text)}")
    return value


def _add_connection(p: argparse.ArgumentParser, hand: bool = False) -> None:
    g = p.add_argument_group("connection")
    g.add_argument(
        "--port",
        help="serial device of the servo bus, e.g. /dev/ttyUSB0 (default: start the embedded "
        "simulator)",
    )
    g.add_argument(
        "--rig",
        type=Path,
        help="rig profile YAML (default: the simulated rig, calib/rigs/sim.yaml; sim3 names the "
        "simulated three-servo rig, calib/rigs/sim3.yaml)",
    )
    g.add_argument("--baud", type=int, help="baud rate (default: the rig profile's)")
    g.add_argument(
        "--latency-timer",
        type=float,
        metavar="MS",
        help="the USB adapter's latency timer in ms, which sets how long a reply is waited for "
        "(default: 16, the FTDI default; 1 after lowering it as the README shows)",
    )
    if hand:
        g.add_argument(
            "--hand",
            type=Path,
            help="simulator only: REGION.yaml the scripted hand moves the limb through "
            "(default: the packaged irregular region)",
        )
    g.add_argument("--seed", type=int, default=0, help="simulator seed (default: 0)")


def _connection(args: argparse.Namespace) -> jobs.Connection:
    return jobs.Connection(
        port=args.port,
        rig=args.rig,
        baud=args.baud,
        latency_timer_ms=args.latency_timer,
        seed=args.seed,
    )


def _add_view(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("live view")
    g.add_argument(
        "--view",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="serve a page that shows the limb, the samples and the region live (default: on "
        "when this runs in a terminal)",
    )
    g.add_argument(
        "--view-port",
        type=int,
        help=f"port of the live view (default: {DEFAULT_VIEW_PORT}, or any free port if taken; "
        "0: any free port)",
    )
    g.add_argument(
        "--view-host", default="127.0.0.1", help="address of the live view (default: 127.0.0.1)"
    )


def _view(args: argparse.Namespace) -> ViewOptions:
    return ViewOptions(enabled=args.view, host=args.view_host, port=args.view_port)


def _limits(text: str | None, option: str) -> tuple[float, float] | None:
    """``MIN,MAX`` in degrees, or None when the option was not given."""
    if text is None:
        return None
    try:
        lo, hi = (float(v) for v in text.split(","))
    except ValueError:
        raise ConfigError(
            f"{option} expects MIN,MAX in degrees like -90,90; got {shown(text)}"
        ) from None
    if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
        raise ConfigError(f"{option}: need finite MIN < MAX, got {shown(text)}")
    return lo, hi


def _joint_ids(text: str | None, option: str) -> tuple[int, ...] | None:
    """Servo ids of pan, tilt and (a three-servo rig) roll, from ``1,2`` or ``1,2,3``."""
    if text is None:
        return None
    try:
        ids = tuple(int(v) for v in text.split(","))
    except ValueError:
        ids = ()
    if len(ids) not in (2, 3):
        raise ConfigError(
            f"{option} expects two or three integers like 1,2 (pan, tilt) or 1,2,3 (pan, tilt, "
            f"roll); got {shown(text)}"
        )
    return ids


def _options(kind: type[Options], args: argparse.Namespace, **given: object) -> Options:
    """Options dataclass ``kind`` with the fields not ``given`` taken from the parsed ``args``."""
    taken = {f.name: getattr(args, f.name) for f in fields(kind) if f.name not in given}
    return kind(**taken, **given)


def _job(run: Callable[[Options], int], kind: type[Options], **derived: Callable) -> Job:
    """A job running ``run`` on ``kind`` from the parsed arguments (``derived`` fields computed)."""
    return lambda a: run(_options(kind, a, **{name: f(a) for name, f in derived.items()}))


def _command(
    sub: Subparsers, name: str, job: Job, **parser_options: str
) -> argparse.ArgumentParser:
    """A subcommand's parser whose parsed arguments are handed to ``job``."""
    p = sub.add_parser(name, **parser_options)
    p.set_defaults(job=job)
    return p


def _add_demo(sub: Subparsers) -> None:
    p = _command(
        sub,
        "demo",
        lambda a: run_demo(a.out, a.duration, a.seed, _view(a), a.rig),
        help="the whole flow on the simulator: teach, train, teleop, plot",
        description="Run teach-by-hand, training, a teleop session that tries to leave the "
        "region, and plots, all on the embedded simulator, writing everything to --out.",
    )
    p.add_argument("--out", type=Path, default=Path("limbctl-demo"), help="output folder")
    p.add_argument(
        "--duration", type=_positive, default=60.0, help="seconds of teaching (default: 60)"
    )
    p.add_argument("--seed", type=int, default=0, help="simulator and model seed")
    p.add_argument(
        "--rig",
        choices=DEMO_RIGS,
        default=DEMO_RIGS[0],
        help="simulated rig: sim (pan, tilt; default) or sim3 (pan, tilt, roll: the region "
        "has a twist band, taught, learned and enforced too)",
    )
    _add_view(p)


def _calibrate(a: argparse.Namespace) -> int:
    ids = _joint_ids(a.ids, "--ids")
    ranges = {
        f"{joint}_{kind}": _limits(getattr(a, f"{joint}_{kind}"), f"--{joint}-{kind}")
        for kind in ("limits", "stops")
        for joint in ("pan", "tilt", "roll")
    }
    options = _options(jobs.CalibrateOptions, a, ids=ids, connection=_connection(a), **ranges)
    return jobs.run_calibrate(options)


def _add_calibrate(sub: Subparsers) -> None:
    p = _command(
        sub,
        "calibrate",
        _calibrate,
        help="find each joint's zero and direction by hand and write a rig profile",
        description="Guided, hand-held: with torque off, hold the limb at rest along +x, then "
        "turn the pan joint toward +y (left), then raise the limb (tilt up), following the "
        "prompts. Writes a rig profile YAML.",
        epilog=EPILOG_HARDWARE,
    )
    _add_connection(p)
    p.add_argument("--out", type=Path, required=True, help="rig profile YAML to write")
    p.add_argument("--name", default="my-rig", help="name stored in the profile")
    p.add_argument(
        "--ids",
        help="servo ids, comma separated: PAN,TILT, or PAN,TILT,ROLL for a limb that also turns "
        "about its own axis (default: the --rig profile's, else 1,2)",
    )
    examples = {"pan": ("-90,90", "-120,120"), "tilt": ("-40,60", "-60,75"), "roll": (None, None)}
    for k, (kind, what, tail) in enumerate(
        (
            ("limits", "hard {} limits", " (default: the base rig profile's, narrowed to 1 deg "
             "inside the end stops)"),
            ("stops", "where the {} joint's travel ends mechanically", "; the hard limits must lie "
             "1 deg inside (default: the --rig profile's, else +-90)"),
        )
    ):  # fmt: skip
        for joint, example in examples.items():
            flag = f"--{joint}-{kind}"
            given = f"e.g. {flag}={example[k]}" if example[k] else "three --ids only"
            p.add_argument(flag, help=f"{what.format(joint)}, MIN,MAX in degrees, {given}{tail}")


def _add_record(sub: Subparsers) -> None:
    p = _command(
        sub,
        "record",
        _job(jobs.run_record, jobs.RecordOptions, connection=_connection, view=_view),
        help="teach by hand: torque off, sample the limb and write a dataset",
        description="Torque off; move the limb by hand through every pose it may take. "
        "Samples every joint (pan, tilt; and roll on three servos) at --rate Hz and appends to "
        "the dataset as it goes. Stops on Enter, Ctrl-C or after --duration; nothing is lost.",
        epilog=EPILOG_HARDWARE,
    )
    _add_connection(p, hand=True)
    p.add_argument("--out", type=Path, required=True, help="dataset file to write")
    p.add_argument("--duration", type=_positive, help="stop after this many seconds")
    p.add_argument(
        "--rate", type=_positive, default=125.0, help="samples per second (>= 100; default 125)"
    )
    _add_view(p)


def _add_train(sub: Subparsers) -> None:
    p = _command(
        sub,
        "train",
        _job(file_jobs.run_train, file_jobs.TrainOptions),
        help="learn the valid region from a dataset and write a model file",
        description="Fit an envelope model (default: a Rigid Map) to a dataset (and its twist).",
    )
    p.add_argument("data", type=Path, help="dataset written by `limbctl record`")
    p.add_argument("--out", type=Path, required=True, help="model file to write (.npz)")
    p.add_argument("--kind", default=MODEL_KINDS[0], choices=MODEL_KINDS, help="model type")
    p.add_argument("--nodes", type=int, help="number of nodes (Rigid Map)")
    p.add_argument("--layout", help="node layout (Rigid Map), e.g. uniform, 720, super-fibonacci")
    p.add_argument("--seed", type=int, default=0, help="random seed")
    p.add_argument("--plot", type=Path, help="also draw the model and data to this PNG")


def _add_teleop(sub: Subparsers) -> None:
    p = _command(
        sub,
        "teleop",
        _job(
            jobs.run_teleop,
            jobs.TeleopOptions,
            on_fault=lambda a: SafeState(a.on_fault),
            connection=_connection,
            view=_view,
        ),
        help="drive the limb from a command source, every command through the gate",
        description="Read commands from --source at --rate Hz; each is corrected by the model, "
        "slew-limited (--max-speed), clamped to the hard limits and a joint step, checked again, "
        "then written. A silent source holds the last safe pose; end of input exits 0, every "
        "line refused 2. A limb resting outside the region: see --wait and --approach.",
        epilog="Sources: stdin (JSON lines {'pan': deg, 'tilt': deg}, {'dir': [x, y, z]}, {'q': "
        "[w, x, y, z]}; three servos also {'pan', 'tilt', 'roll': deg}, {'dir', 'twist': deg}, "
        "a q keeping its twist, no roll or twist meaning twist 0), udp://127.0.0.1:PORT (the "
        "same lines), keyboard (arrows, [ ] roll; ? shows the keys), page (the view's page: "
        "drag or arrows; open the address printed with the key), leader:ID,ID or leader:ID,ID,"
        f"ID (a second limb; --operator moves a simulated one), replay:FILE. {EPILOG_HARDWARE}",
    )
    _add_connection(p)
    p.add_argument("--model", type=Path, required=True, help="model file from `limbctl train`")
    p.add_argument("--source", default="stdin", help="command source (default: stdin)")
    p.add_argument(
        "--operator",
        metavar="NAME|FILE",
        help="simulator only, with --source leader: a simulated hand moves a felt leader at those "
        f"ids: {' or '.join(OPERATORS)} (past the edge, held, let go) or an operator YAML",
    )
    p.add_argument("--rate", type=_positive, default=200.0, help="loop rate in Hz")
    p.add_argument(
        "--max-speed", type=_positive, default=120.0, help="slew limit of the limb, deg/s"
    )
    p.add_argument(
        "--on-fault",
        choices=[state.value for state in SafeState],
        default=SafeState.HOLD.value,
        help="safe state after a bus fault or servo alarm (default: hold)",
    )
    p.add_argument("--duration", type=_positive, help="stop after this many seconds")
    p.add_argument("--telemetry", type=Path, help="JSON-lines log of every cycle")
    p.add_argument("--goal-log", type=Path, help="simulator only: the simulator's goal log")
    p.add_argument("--quiet", action="store_true", help="no status line")
    p.add_argument(
        "--wait",
        type=_positive,
        default=DEFAULT_WAIT_S,
        metavar="S",
        help="a limb outside the taught region or the hard limits keeps torque off and is "
        "waited for this long while you move it inside by hand (the way is shown live); then "
        f"exit 2 (default: {DEFAULT_WAIT_S:.0f})",
    )
    p.add_argument(
        "--approach",
        type=_positive,
        metavar="DEG_S",
        help="instead of waiting for the hand, let the servos drive a limb outside to the "
        f"nearest pose inside, slowly (at most {MAX_APPROACH_SPEED_DEG_S:.0f} deg/s), every "
        "goal checked",
    )
    _add_view(p)


def _add_reboot(sub: Subparsers) -> None:
    p = _command(
        sub,
        "reboot",
        lambda a: upkeep.run_reboot(upkeep.RebootOptions(connection=_connection(a))),
        help="reboot the servos in alarm (a hardware error) and say what each alarm was",
        description="Reads each servo's Hardware Error Status; reboots the ones that report an "
        "error (overload, overheating, input voltage, ...), which clears it and leaves torque "
        "off. Fix the cause first. Healthy servos are left alone.",
        epilog=EPILOG_HARDWARE,
    )
    _add_connection(p)


def _add_plot(sub: Subparsers) -> None:
    p = _command(
        sub,
        "plot",
        lambda a: file_jobs.run_plot(file_jobs.PlotOptions(inputs=tuple(a.inputs), out=a.out)),
        help="draw a model or a dataset (region, samples, node weights) to a PNG",
    )
    p.add_argument("inputs", type=Path, nargs="+", help="a model file and/or a dataset")
    p.add_argument("--out", type=Path, required=True, help="PNG file to write")


def _add_eval(sub: Subparsers) -> None:
    p = _command(
        sub,
        "eval",
        _job(file_jobs.run_evaluation, file_jobs.EvalOptions),
        help="reproduce the papers' experiments beside the gate; tables and plots",
    )
    p.add_argument("--quick", action="store_true", help="a reduced grid (under two minutes)")
    p.add_argument("--out", type=Path, default=Path("eval-results"), help="output folder")
    p.add_argument("--jobs", type=int, default=0, help="worker processes (0: all cores)")


def _add_prepare(sub: Subparsers) -> None:
    p = _command(sub, "prepare", warm.prepare_job, help=warm.HELP, description=warm.DESCRIPTION)
    p.add_argument("--rig", default="all", help=warm.RIG_HELP)


def _add_info(sub: Subparsers) -> None:
    p = _command(
        sub,
        "info",
        lambda a: file_jobs.run_info(file_jobs.InfoOptions(file=a.file, connection=_connection(a))),
        help="what is on the bus, or what a model/dataset file holds",
    )
    _add_connection(p)
    p.add_argument("file", type=Path, nargs="?", help="a model or dataset file to describe")


def _add_motors(sub: Subparsers) -> None:
    p = sub.add_parser("motors", help=upkeep.MOTORS_HELP, description=upkeep.MOTORS_DESCRIPTION)
    motors = p.add_subparsers(dest="motors_command", metavar="ACTION", required=True)
    scan = _command(motors, "scan", upkeep.motor_scan_job(_connection), help=upkeep.SCAN_HELP)
    _add_connection(scan)
    scan.add_argument("--scan-baud", type=int, action="append", help=upkeep.SCAN_BAUD_HELP)
    setup = _command(motors, "setup", upkeep.motor_setup_job(_connection), help=upkeep.SETUP_HELP)
    _add_connection(setup)
    upkeep.add_setup_options(setup)


#: The subcommands in the order ``--help`` lists them.
SUBCOMMANDS = (
    _add_demo,
    _add_prepare,
    _add_calibrate,
    _add_record,
    _add_train,
    _add_teleop,
    _add_reboot,
    _add_motors,
    _add_plot,
    _add_eval,
    _add_info,
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="limbctl",
        description="Teach a Dynamixel limb of two servos (pan, tilt) or three (and roll) its "
        "allowed orientations by hand, learn them as a Rigid Map, and gate every command by it.",
        epilog=EPILOG_HARDWARE,
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for add in SUBCOMMANDS:
        add(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``limbctl`` console script; returns the exit status."""
    args = build_parser().parse_args(argv)
    try:
        status = int(args.job(args) or 0)
        # flushed here, so a reader that went away is noticed below and not at interpreter exit
        sys.stdout.flush()
        return status
    except BrokenPipeError:
        # the reader of stdout went away (`limbctl info | head`): as the Python docs' note on
        # SIGPIPE does, point stdout at devnull so the last flush cannot raise again
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 1
    except LimbctlError as exc:
        print(f"limbctl {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"limbctl {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
