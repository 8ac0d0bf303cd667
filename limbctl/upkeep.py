"""Jobs that look after the servos: ``limbctl reboot`` and ``limbctl motors scan`` / ``setup``."""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from limbctl.errors import ConfigError
from limbctl.jobs import Connection, open_connection, say

if TYPE_CHECKING:
    from limbctl.servo.motors import Claims


@dataclass(frozen=True)
class RebootOptions:
    """``limbctl reboot``: the command line's options."""

    connection: Connection = field(default_factory=Connection)


def run_reboot(options: RebootOptions) -> int:
    """Reboot every servo in alarm and read their alarms again; 0 when clear, 3 when one is not."""
    from limbctl.servo.alarms import reboot_servos_in_alarm

    with open_connection(options.connection) as session:
        bus = session.rig.bus
        rebooted = reboot_servos_in_alarm(bus)
        ids = ", ".join(str(i) for i in bus.ids)
        again = {i: bits for i, bits in bus.read_hardware_errors().items() if bits}
    if not rebooted:
        say(f"no servo is in alarm (servos {ids} report no hardware error): nothing rebooted")
        return 0
    for servo in rebooted:
        say(servo.describe())
    for servo_id, bits in again.items():
        say(
            f"servo {servo_id} is in alarm again right after its reboot ({', '.join(bits)}): "
            f"its cause is still there; fix it (supply voltage, temperature, load), then "
            f"`limbctl reboot` again"
        )
    say(
        "torque is off and RAM settings are back at their defaults: the next record, teleop or "
        "calibrate sets them again"
    )
    return 3 if again else 0


MOTORS_HELP = "find the servos at any baud; set up servos out of the box (ID, baud)"
MOTORS_DESCRIPTION = (
    "Servos leave the factory as ID 1 at 57600 baud. `motors scan` finds every servo at every "
    "baud and names shared IDs; `motors setup` gives each joint's servo, connected alone, the "
    "profile's ID and baud (or --baud), reading them back (--renumber: see its help)."
)
SCAN_HELP = "ping every servo at every baud rate (the factory's 57600 first)"
SCAN_BAUD_HELP = "scan only this baud rate (repeatable; default: every rate the X series has)"
SETUP_HELP = "one servo at a time: ID, baud, Return Delay Time 0, Status Return Level 2"
RENUMBER_HELP = (
    "make the connected servo the --joint's even if it answers as another joint's ID (a spare "
    "servo of one joint made another's, on purpose); without it such a servo is refused"
)


def add_setup_options(parser: Any) -> None:
    """The ``motors setup`` options beside the connection's."""
    parser.add_argument(
        "--joint", action="append", help="only this joint (repeatable: pan, tilt, roll)"
    )
    parser.add_argument("--yes", action="store_true", help="do not ask before each servo")
    parser.add_argument("--renumber", action="store_true", help=RENUMBER_HELP)
    parser.add_argument("--scan-baud", type=int, action="append", help=SCAN_BAUD_HELP)


def motor_scan_job(connection: Callable[[Any], Connection]) -> Callable[[Any], int]:
    """The ``motors scan`` job for parsed arguments (``connection`` reads their options)."""
    return lambda a: run_motor_scan(MotorScanOptions(connection(a), tuple(a.scan_baud or ())))


def motor_setup_job(connection: Callable[[Any], Connection]) -> Callable[[Any], int]:
    """The ``motors setup`` job for parsed arguments."""
    return lambda a: run_motor_setup(
        MotorSetupOptions(
            connection(a),
            tuple(a.joint or ()),
            bool(a.yes),
            bool(a.renumber),
            tuple(a.scan_baud or ()),
        )
    )


@dataclass(frozen=True)
class MotorScanOptions:
    """``limbctl motors scan``: the command line's options (no ``bauds``: all)."""

    connection: Connection = field(default_factory=Connection)
    bauds: tuple[int, ...] = ()


def _progress(index: int, count: int, baud: int) -> None:
    """One line (rewritten in place on a tty) of the scan's progress."""
    bar = "#" * (index + 1) + "-" * (count - index - 1)
    end = "\r" if sys.stderr.isatty() else "\n"
    print(f"scanning [{bar}] {index + 1}/{count}: {baud} baud", end=end, file=sys.stderr)


def run_motor_scan(options: MotorScanOptions) -> int:
    """Scan and print what answered; 0, 1 when nothing answered, 3 when servos share an ID."""
    from limbctl.servo.scan import SCAN_BAUDS, scan

    conn = options.connection
    with _bus_port(conn) as (port, latency_ms):
        result = scan(port, options.bauds or SCAN_BAUDS, latency_ms, on_baud=_progress)
    print(file=sys.stderr)
    print(result.report())
    if result.collisions or result.unreadable:
        return 3
    return 1 if result.empty else 0


@dataclass(frozen=True)
class MotorSetupOptions:
    """``limbctl motors setup``: the command line's options (no ``joints``: all; no ``bauds``:
    every rate the X series has is scanned for the connected servo)."""

    connection: Connection = field(default_factory=Connection)
    joints: tuple[str, ...] = ()
    yes: bool = False
    renumber: bool = False
    bauds: tuple[int, ...] = ()


def run_motor_setup(options: MotorSetupOptions) -> int:
    """Set up each joint's servo; 0 when every one succeeded, 1 when one failed or was skipped."""
    from limbctl.servo.motors import Claims, JointTarget, check_target, setup_joint
    from limbctl.servo.profiles import load_rig_profile
    from limbctl.servo.scan import SCAN_BAUDS

    conn = options.connection
    profile = load_rig_profile(conn.rig)
    baud = conn.baud or profile.baud
    joints = dict(profile.joints)
    chosen = options.joints or tuple(joints)
    unknown = [j for j in chosen if j not in joints]
    if unknown:
        raise ConfigError(f"unknown joint {unknown[0]!r}: the profile has {', '.join(joints)}")
    if options.renumber and len(chosen) != 1:
        raise ConfigError(
            f"--renumber makes the connected servo one joint's on purpose: name that joint with "
            f"--joint (e.g. --joint {tuple(joints)[1]})"
        )
    targets = [JointTarget(j, joints[j].id, profile.model, baud) for j in chosen]
    for target in targets:
        check_target(target)  # a bad baud or model is refused before anything is asked
    ids = {name: joint.id for name, joint in joints.items()}
    bauds = options.bauds or SCAN_BAUDS
    unknown_rates = sorted(set(bauds) - set(SCAN_BAUDS))
    if unknown_rates:
        rates = ", ".join(str(baud) for baud in sorted(SCAN_BAUDS))
        raise ConfigError(f"--scan-baud {unknown_rates[0]}: no X-series servo runs at it ({rates})")
    done: list[str] = []
    failed: list[str] = []
    skipped: list[str] = []
    with _bus_port(conn, setup=True) as (port, latency_ms):
        for target in targets:
            if not options.yes:
                input(
                    f"Connect only the {target.joint} servo (it becomes ID {target.servo_id}), "
                    f"power it, then press Enter (Ctrl-C stops): "
                )
            claims = Claims(ids, tuple(done), options.renumber)
            outcome = setup_joint(port, target, latency_ms, bauds, claims)
            while outcome.other_joint is not None and not options.yes:
                if not _look_again(target.joint, outcome.other_joint, claims, ids):
                    break
                outcome = setup_joint(port, target, latency_ms, bauds, claims)
            if outcome.ok:
                done.append(target.joint)
                say(outcome.message)
            elif outcome.other_joint is not None and not options.yes:
                skipped.append(target.joint)
                say(f"{target.joint}: skipped: {outcome.message}")
            else:
                failed.append(target.joint)
                say(f"{target.joint}: FAILED: {outcome.message}")
    left = f"; skipped: {', '.join(skipped)}" if skipped else ""
    say(f"set up: {', '.join(done) or 'none'}{left}; failed: {', '.join(failed) or 'none'}")
    return 1 if failed or skipped else 0


def _look_again(joint: str, owner: str, claims: Claims, ids: dict[str, int]) -> bool:
    """Ask whether to look for ``joint``'s servo again (Enter) or to skip it (skip, or EOF)."""
    when = "set up a moment ago" if owner in claims.set_up_now else "set up before"
    try:
        answer = input(
            f"The connected servo answers as ID {ids[owner]}, the {owner} joint's ({when}): "
            f"connect only the {joint} servo and press Enter to look again, or type skip to "
            f"leave {joint} for now: "
        )
    except EOFError:
        return False
    return answer.strip().lower() != "skip"


@contextmanager
def _bus_port(conn: Connection, setup: bool = False) -> Iterator[tuple[str, float]]:
    """(port, latency timer ms) of the bus: --port, the profile's, or (scan) the simulator's."""
    from limbctl.servo.profiles import load_rig_profile

    profile = load_rig_profile(conn.rig)
    device = conn.port if conn.port is not None else (None if profile.is_sim else profile.port)
    if device is not None:
        yield device, conn.latency_timer_ms or 16.0
        return
    if setup:
        raise ConfigError(
            "motors setup needs --port: the serial device of the servos (or a `firmware-sim "
            "--factory 2 --link PATH` to try it)"
        )
    from firmware_sim import SimulatedBus

    with SimulatedBus(ids=profile.ids, model=profile.model, baud=conn.baud or profile.baud) as sim:
        yield sim.port, conn.latency_timer_ms or 2.0
