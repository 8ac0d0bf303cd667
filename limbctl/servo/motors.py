"""Set up out-of-the-box servos for a rig profile's joints, one servo at a time (README)."""

from __future__ import annotations

from collections.abc import Collection, Mapping
from dataclasses import dataclass

from limbctl.errors import BusError, ConfigError, LimbctlError
from limbctl.servo.bus import ServoBus
from limbctl.servo.control_table import (
    BAUD_RATE_VALUES,
    MODEL_BY_NAME,
    SDK_BAUDS,
    Register,
    model_name,
)
from limbctl.servo.families import family_of
from limbctl.servo.scan import NOTHING_ANSWERS, SCAN_BAUDS, ScanResult, scan
from limbctl.servo.setup import STATUS_RETURN_ALL
from limbctl.servo.transfers import SDK_LATENCY_TIMER_MS

#: Return Delay Time set-up writes (2 us units): reply at once.
RETURN_DELAY = 0
#: A servo out of the box (e-Manual defaults): one at ID 1 with delay 250 was never set up.
FACTORY_ID, FACTORY_BAUD, FACTORY_RETURN_DELAY = 1, 57_600, 250


@dataclass(frozen=True)
class JointTarget:
    """What one joint's servo must become: ``joint`` name, ``servo_id``, ``model``, ``baud``."""

    joint: str
    servo_id: int
    model: str
    baud: int


@dataclass(frozen=True)
class SetupOutcome:
    """One joint's set-up: done or why refused, the registers written, the joint it belongs to."""

    joint: str
    ok: bool
    message: str
    written: tuple[str, ...] = ()
    other_joint: str | None = None


@dataclass(frozen=True)
class Claims:
    """The profile's joint ``ids``, those ``set_up_now``, and whether to ``renumber`` on purpose."""

    ids: Mapping[str, int]
    set_up_now: Collection[str] = ()
    renumber: bool = False


def _the_one_servo(result: ScanResult, target: JointTarget) -> tuple[int, int, int]:
    """(ID, baud, model number) of the only servo connected, or ConfigError saying why not."""
    joint = target.joint
    if result.collisions:
        first = result.collisions[0]
        raise ConfigError(
            f"two or more servos answer as ID {first.servo_id} at {first.baud} baud: connect "
            f"only the {joint} servo and run again"
        )
    if result.unreadable:
        raise ConfigError(
            f"garbled replies at {result.unreadable[0]} baud (servos sharing an ID): connect "
            f"only the {joint} servo and run again"
        )
    asked = set(result.seconds) | set(result.skipped)  # scanned, or not open to the driver
    if not result.found and asked and not asked >= set(SCAN_BAUDS):
        rates = ", ".join(str(baud) for baud in sorted(result.seconds)) or "none"
        skipped = "".join(f"; {baud} baud not tried: {why}" for baud, why in result.skipped.items())
        raise ConfigError(
            f"no servo answers for the {joint} joint; baud rates scanned (--scan-baud): {rates}"
            f"{skipped}: connect its servo, or scan every rate (leave --scan-baud out)"
        )
    if not result.found:
        raise ConfigError(f"no servo answers for the {joint} joint: {NOTHING_ANSWERS}")
    if len(result.found) > 1:
        seen = ", ".join(f"ID {f.servo_id} at {f.baud} baud" for f in result.found)
        raise ConfigError(
            f"more than one servo answers ({seen}): connect only the {joint} servo and run again"
        )
    servo = result.found[0]
    expected = MODEL_BY_NAME[target.model]
    if servo.model_number != expected:
        raise ConfigError(
            f"the connected servo is {model_name(servo.model_number)} but the profile's {joint} "
            f"is {model_name(expected)}: connect the {joint} servo, or fix `model:` in the "
            f"profile"
        )
    return servo.servo_id, servo.baud, servo.model_number


def check_target(target: JointTarget) -> None:
    """Refuse a target the servo's family cannot take (ConfigError naming it)."""
    family = family_of(target.model)
    if target.baud in family.bauds and target.baud not in SDK_BAUDS:
        usable = ", ".join(str(b) for b in family.bauds if b in SDK_BAUDS)
        raise ConfigError(
            f"baud {target.baud} is one the servos know, but the serial driver (dynamixel-sdk) "
            f"cannot open it; choose one of {usable}"
        )
    if target.baud not in BAUD_RATE_VALUES or target.baud not in family.bauds:
        rates = ", ".join(str(b) for b in family.bauds)
        raise ConfigError(
            f"{target.model.upper()} servos do not run at {target.baud} baud; they run at {rates}"
        )
    if not 0 <= target.servo_id <= 252:
        raise ConfigError(f"servo IDs are 0..252, got {target.servo_id} for {target.joint}")


def setup_joint(
    port: str,
    target: JointTarget,
    latency_timer_ms: float = 16.0,
    scan_bauds=SCAN_BAUDS,
    claims: Claims | None = None,
) -> SetupOutcome:
    """Find the one connected servo and make it ``target`` (replies awaited as the SDK would)."""
    latency_timer_ms = max(latency_timer_ms, SDK_LATENCY_TIMER_MS)
    claims = claims or Claims({})
    try:
        check_target(target)
        servo_id, baud, number = _the_one_servo(scan(port, scan_bauds, latency_timer_ms), target)
        owner = _owner(port, target, servo_id, baud, claims, latency_timer_ms)
        if owner is not None and not claims.renumber:
            return SetupOutcome(
                target.joint, False, _refusal(target, servo_id, owner, claims), other_joint=owner
            )
        written = _configure(port, target, servo_id, baud, latency_timer_ms)
        _verify(port, target, latency_timer_ms)
    except LimbctlError as exc:
        return SetupOutcome(target.joint, False, str(exc))
    done = (
        f"{target.joint}: {model_name(number)} now ID {target.servo_id} at {target.baud} baud, "
        f"Return Delay Time {RETURN_DELAY}, Status Return Level {STATUS_RETURN_ALL} (RAM: set "
        f"again at every start)"
    )
    if not written:
        done += "; it was set up already: nothing written"
    else:
        taken = (
            ""
            if owner is None
            else f", the {owner} joint's ID: renumbered on purpose (--renumber), so no servo "
            f"answers as {owner} until one is set up as it"
        )
        done += f" (found as ID {servo_id} at {baud} baud{taken}; wrote {', '.join(written)})"
    return SetupOutcome(target.joint, True, done, tuple(written))


def _owner(
    port: str, target: JointTarget, servo_id: int, baud: int, claims: Claims, latency_ms: float
) -> str | None:
    """The other joint whose servo the one found (``servo_id`` at ``baud``) recognisably is."""
    owner = next((j for j, i in claims.ids.items() if i == servo_id and j != target.joint), None)
    if owner is None:
        return None
    if servo_id != FACTORY_ID or baud != FACTORY_BAUD:
        return owner  # a factory-fresh servo answers only as ID 1 at 57600 baud
    # the owner may have been set up in this run and still a new servo be at the factory ID
    with _open(port, baud, servo_id, target.model, latency_ms) as bus:
        delay = bus.read(Register.RETURN_DELAY_TIME, servo_id, patient=True)
    return None if delay == FACTORY_RETURN_DELAY else owner


def _refusal(target: JointTarget, servo_id: int, owner: str, claims: Claims) -> str:
    joint = target.joint
    return (
        f"the connected servo answers as ID {servo_id}, the {owner} joint's, and is the {owner} "
        f"servo {_set_up_when(owner, claims)}: connect only the {joint} servo and run `limbctl "
        f"motors setup --joint {joint}` again (or, to make this servo the {joint} servo on "
        f"purpose, add --renumber)"
    )


def _set_up_when(owner: str, claims: Claims) -> str:
    """When ``owner``'s servo was set up, as the person saw it: in this run or before."""
    if owner in claims.set_up_now:
        return "set up a moment ago"
    return (
        f"set up before (a factory-fresh servo answers as ID {FACTORY_ID} at {FACTORY_BAUD} "
        f"baud with Return Delay Time {FACTORY_RETURN_DELAY})"
    )


def _open(port: str, baud: int, servo_id: int, model: str | None, latency_ms: float) -> ServoBus:
    """A bus on one servo (``model`` None: unchecked, as just after an ID change)."""
    return ServoBus(port, baud, (servo_id,), model, latency_timer_ms=latency_ms).open()


def _configure(port: str, target: JointTarget, servo_id: int, baud: int, latency_ms: float):
    """Torque off, then ID, baud, Return Delay Time, Status Return Level; the names written."""
    written: list[str] = []
    family = family_of(target.model)
    bus = _open(port, baud, servo_id, target.model, latency_ms)
    try:
        volts = bus.read(Register.PRESENT_INPUT_VOLTAGE, servo_id, check_alert=False)
        problem = family.voltage_problem(MODEL_BY_NAME[target.model], volts)
        if problem:
            raise ConfigError(f"{target.joint}: {problem}")
        bus.write(Register.TORQUE_ENABLE, servo_id, 0, check_alert=False)
        if servo_id != target.servo_id:
            bus.write(Register.ID, servo_id, target.servo_id, check_alert=False)
            written.append(f"ID {servo_id} -> {target.servo_id}")
        value = BAUD_RATE_VALUES[target.baud]
        if baud != target.baud:
            # the servo answers at the old rate, then listens at the new one
            bus.close()
            bus = _open(port, baud, target.servo_id, None, latency_ms)
            bus.write(Register.BAUD_RATE, target.servo_id, value, check_alert=False)
            written.append(f"baud {baud} -> {target.baud}")
    finally:
        bus.close()
    with _open(port, target.baud, target.servo_id, target.model, latency_ms) as bus:
        if bus.read(Register.RETURN_DELAY_TIME, target.servo_id, patient=True) != RETURN_DELAY:
            bus.write(Register.RETURN_DELAY_TIME, target.servo_id, RETURN_DELAY)
            written.append(f"Return Delay Time {RETURN_DELAY}")
        bus.write(Register.STATUS_RETURN_LEVEL, target.servo_id, STATUS_RETURN_ALL)
    return written


def _verify(port: str, target: JointTarget, latency_ms: float) -> None:
    """Ping at the new ID and baud and read back every value set-up writes."""
    expected = {
        Register.ID: target.servo_id,
        Register.BAUD_RATE: BAUD_RATE_VALUES[target.baud],
        Register.RETURN_DELAY_TIME: RETURN_DELAY,
        Register.STATUS_RETURN_LEVEL: STATUS_RETURN_ALL,
    }
    with _open(port, target.baud, target.servo_id, target.model, latency_ms) as bus:
        for register, value in expected.items():
            got = bus.read(register, target.servo_id, patient=True)
            if got != value:
                raise BusError(
                    f"{target.joint}: servo {target.servo_id} reads back {register.name}={got} "
                    f"after set-up wrote {value}",
                    target.servo_id,
                )
