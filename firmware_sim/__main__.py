"""``firmware-sim`` / ``python -m firmware_sim``: serve simulated Dynamixel servos on a pty."""

from __future__ import annotations

import argparse
import math
import signal
import sys
from collections.abc import Sequence

from firmware_sim.bus import PtyEndpoint, build_simulator, serve
from firmware_sim.control_table import MODELS, Register
from firmware_sim.events import EventSchedule, ScheduledEvent, parse_event
from firmware_sim.operator_file import DEFAULT_MODEL, leader_spec, read_operator_file
from firmware_sim.simulator import parse_ids
from firmware_sim.wire import BAUD_BY_VALUE, RIG_BAUD
from firmware_sim.world import ROLL_JOINT

#: The servo the CLI makes the roll joint when it is listed (calib/rigs/sim3.yaml).
ROLL_ID = ROLL_JOINT.servo_id

DESCRIPTION = """\
Simulated Dynamixel X-series servos (Protocol 2.0) on a pseudo-terminal, byte for byte like real
servos behind a U2D2 adapter: open PATH with the dynamixel-sdk at the servos' baud rate; servos
sharing an ID garble each other's replies. Servos 1 and 2 are the pan and tilt joints of a
simulated gimbal (calib/rigs/sim.yaml); servo 3, when listed, its roll joint
(calib/rigs/sim3.yaml); other IDs drive free shafts. Runs until SIGINT or SIGTERM, then removes
PATH."""

EPILOG = """\
--hand REGION.yaml: a scripted hand moves the limb while torque is off (a region, polygon or
cone, optionally with a twist band; or a script). --leader IDS --operator OPERATOR.yaml: a
leader gimbal and the hand that holds it. --goal-log: one line per Goal Position write (limb_dir,
limb_q). --event T:KIND:ID:VALUE, KIND one of vanish, voltage, temperature, restart, push.
Every form in full: docs/simulator.md.

Example: firmware-sim --ids 1,2 --link /tmp/ttyDXL &
"""


def _number(what: str, example: str, low: float, high: float):
    """An argparse type: a float within ``low..high``, else an error naming ``what``."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"expected {what} like {example}, got {text!r}"
            ) from None
        if not low <= value <= high:
            bound = f"within {low:g}..{high:g}" if high < math.inf else f">= {low:g}"
            raise argparse.ArgumentTypeError(f"{what} must be {bound}, got {value}")
        return value

    return parse


_probability = _number("a probability", "0.05", 0.0, 1.0)
_milliseconds = _number("milliseconds", "20", 0.0, math.inf)


def _ids(text: str) -> tuple[int, ...]:
    try:
        return parse_ids(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="firmware-sim",
        description=DESCRIPTION,
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    models = ", ".join(sorted(MODELS))
    model_help = f"servo model, or one per servo comma-separated (default xl430-w250): {models}"
    baud_help = (
        f"the servos' baud rate: they then answer only a host at that rate (limbctl's simulated "
        f"rig: {RIG_BAUD}); without it they answer at any rate until their Baud Rate register is "
        f"written. Not with --factory"
    )
    factory_help = "serve N factory-fresh servos (ID 1, 57600 baud, Return Delay Time 250)"
    eeprom_help = "keep each servo's EEPROM in DIR/servo-SLOT.eeprom across runs"
    leader_help = "a leader gimbal on the same bus at these IDs (pan, tilt[, roll]; see below)"
    latency_p_help = "probability that a reply gets the latency spike (default 1)"
    # (option, metavar, type, default, help); a None field is left to argparse
    options = (
        ("--ids", None, _ids, (1, 2), "servo IDs, e.g. 1,2 (default)"),
        ("--link", "PATH", None, None, "symlink to create to the pty device"),
        ("--model", None, _models, "xl430-w250", model_help),
        ("--baud", "BPS", int, None, baud_help),
        ("--factory", "N", int, 0, factory_help),
        ("--connect", "SLOTS", _ids, None, "only these slots are plugged in, e.g. 2"),
        ("--eeprom", "DIR", None, None, eeprom_help),
        ("--hand", "REGION.yaml", None, None, "scripted hand (see below)"),
        ("--leader", "IDS", _ids, None, leader_help),
        ("--operator", "OPERATOR.yaml", None, None, "the hand that holds the leader (see below)"),
        ("--leader-log", "FILE.jsonl", None, None, "the leader's ground truth every 1 ms"),
        ("--goal-log", "FILE.jsonl", None, None, "log every goal position write"),
        ("--seed", None, int, 0, "seed of world and faults (0)"),
        ("--drop", "P", _probability, 0.0, "reply loss probability"),
        ("--corrupt", "P", _probability, 0.0, "reply corruption prob."),
        ("--latency-ms", "X", _milliseconds, 0.0, "latency spike (ms)"),
        ("--latency-p", "P", _probability, 1.0, latency_p_help),
    )
    for flag, metavar, kind, default, text in options:
        given = {"metavar": metavar, "type": kind, "default": default}
        extra = {"choices": sorted(BAUD_BY_VALUE.values())} if flag == "--baud" else {}
        extra |= {"required": True} if flag == "--link" else {}
        parser.add_argument(
            flag, help=text, **{k: v for k, v in given.items() if v is not None}, **extra
        )
    parser.add_argument(
        "--event",
        type=_event,
        action="append",
        default=[],
        metavar="T:KIND:ID:VALUE",
        help="scheduled fault, repeatable (see below)",
    )
    return parser


def _models(text: str) -> str:
    keys = [part.strip().lower() for part in text.split(",")]
    for key in keys:
        if key.partition("@")[0] not in MODELS:
            raise argparse.ArgumentTypeError(
                f"invalid choice: {key!r} (choose from {', '.join(sorted(MODELS))})"
            )
    return ",".join(keys)


def _event(text: str) -> ScheduledEvent:
    try:
        return parse_event(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


def _leader(args: argparse.Namespace) -> dict | None:
    """The simulator's ``leader`` option from --leader, --operator and --leader-log; ValueError
    naming what is wrong."""
    if args.leader is None:
        if args.operator or args.leader_log:
            raise ValueError("--operator and --leader-log need a leader: give --leader IDS")
        return None
    if len(args.leader) not in (2, 3):
        raise ValueError(f"--leader takes two or three IDs (pan, tilt[, roll]), got {args.leader}")
    if not args.operator:  # nobody holds it: only its motors move it
        spec = {"ids": list(args.leader), "model": DEFAULT_MODEL}
        return spec if args.leader_log is None else {**spec, "log": args.leader_log}
    data = read_operator_file(args.operator)  # its errors name the file
    try:
        return leader_spec(data, args.leader, args.leader_log)
    except ValueError as error:
        raise ValueError(f"{args.operator}: {error}") from None


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``firmware-sim``; returns the exit status."""
    args = build_parser().parse_args(argv)
    keys = ("ids", "model", "hand", "goal_log", "seed", "drop", "corrupt", "latency_ms")
    keys += ("latency_p", "baud", "factory", "connect")
    config = {key: getattr(args, key) for key in keys}
    config |= {"roll_id": ROLL_ID if ROLL_ID in args.ids else None, "eeprom_dir": args.eeprom}
    stop = {"requested": False}

    def request_stop(signum, frame) -> None:
        stop["requested"] = True

    schedule = EventSchedule(args.event)
    sim = None
    try:
        config["leader"] = _leader(args)
        sim = build_simulator(config)
        schedule.check(sim)
        endpoint = PtyEndpoint(args.link)
    except (ValueError, OSError) as error:
        if sim is not None:  # its goal and leader logs are open: close them before leaving
            sim.close()
        print(f"firmware-sim: error: {error}", file=sys.stderr)
        return 2
    signal.signal(signal.SIGINT, request_stop)
    signal.signal(signal.SIGTERM, request_stop)
    try:
        servos = ", ".join(
            f"{s.model.title} ID {s.servo_id} at {BAUD_BY_VALUE[s.value(Register.BAUD_RATE)]}"
            for s in sim.servos
        )
        print(
            f"firmware-sim ready: {servos} on {endpoint.device} linked at {endpoint.port}",
            flush=True,
        )
        serve(sim, endpoint, lambda: stop["requested"], schedule=schedule)
    finally:
        endpoint.close()
        sim.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
