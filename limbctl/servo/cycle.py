"""The control cycle's ONE sync read of :data:`CYCLE_REGISTERS`, mapped onto Indirect Data."""

from __future__ import annotations

import time
from collections import defaultdict
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from types import MappingProxyType

from limbctl.errors import BusTimeout, ConfigError, CorruptReply
from limbctl.servo import transfers
from limbctl.servo.control_table import INDIRECT_SLOTS, Block, Register, decode_hardware_error

#: The registers in the cycle's read, in Indirect Data order.
CYCLE_REGISTERS = (
    Register.PRESENT_POSITION,
    Register.GOAL_POSITION,
    Register.TORQUE_ENABLE,
    Register.HARDWARE_ERROR_STATUS,
    Register.PRESENT_PWM,
)
#: Bytes each servo returns per cycle (4 + 4 + 1 + 1 + 2).
CYCLE_BYTES = sum(register.size for register in CYCLE_REGISTERS)
#: What the cycle reads: Indirect Data 1 .. CYCLE_BYTES.
CYCLE_BLOCK = Block(Register.INDIRECT_DATA_1, CYCLE_BYTES)
#: What set-up writes: Indirect Address 1 .. CYCLE_BYTES, two bytes each.
INDIRECT_MAP_BLOCK = Block(Register.INDIRECT_ADDRESS_1, 2 * CYCLE_BYTES)

assert CYCLE_BYTES <= INDIRECT_SLOTS

#: PWM Limit (36) as the XL430-W250 and XM430-W350 leave the factory: Present PWM's full scale.
FACTORY_PWM_LIMIT = 885
#: Bits per byte on the wire: start, 8 data, stop.
BITS_PER_BYTE = 10
#: The baud :func:`wire_budget` advises: every family runs at it, a 200 Hz loop fits easily.
ADVISED_BAUD = 1_000_000


def cycle_wire_bytes(n_servos: int, fast: bool = True) -> int:
    """Bytes of one cycle's read and goals' sync write (Protocol 2.0 packet sizes)."""
    back = 8 + n_servos * (CYCLE_BYTES + 4) if fast else n_servos * (11 + CYCLE_BYTES)
    return (14 + n_servos) + back + (14 + 5 * n_servos)


def wire_budget(rate_hz: float, baud: int, n_servos: int, fast: bool = True) -> str:
    """What to tell a person whose loop rate (Hz) the wire cannot carry ('' when it can)."""
    count = cycle_wire_bytes(n_servos, fast)
    wire_s = count * BITS_PER_BYTE / baud
    most_hz = 1.0 / wire_s
    if most_hz >= rate_hz:
        return ""
    return (
        f"at {baud} baud one cycle's {count} bytes take {wire_s * 1e3:.1f} ms on the wire, so "
        f"the loop runs at most {most_hz:.0f} Hz, not {rate_hz:g} Hz: raise the servos' baud "
        f"to {ADVISED_BAUD} (`limbctl motors setup --baud {ADVISED_BAUD} --rig PROFILE`, then "
        f"`baud: {ADVISED_BAUD}` in the profile)"
    )


def indirect_map(registers: Sequence[Register] = CYCLE_REGISTERS) -> bytes:
    """The Indirect Address bytes (little-endian) that map each byte of ``registers``."""
    addresses = [register.address + k for register in registers for k in range(register.size)]
    return b"".join(address.to_bytes(2, "little") for address in addresses)


@dataclass(frozen=True)
class ServoReport:
    """One servo's part of a cycle read: Present and Goal Position (ticks), Torque Enable, Hardware
    Error Status (empty: healthy), Present PWM (signed) and the PWM Limit where its drive
    saturates."""

    present: int
    goal: int
    torque_on: bool
    hardware_error: tuple[str, ...]
    pwm: int = 0
    pwm_limit: int = FACTORY_PWM_LIMIT

    @classmethod
    def decode(cls, data: bytes, pwm_limit: int = FACTORY_PWM_LIMIT) -> ServoReport:
        """A report from the CYCLE_BYTES bytes of Indirect Data 1..N."""
        values = []
        offset = 0
        for register in CYCLE_REGISTERS:
            values.append(register.decode(data[offset : offset + register.size]))
            offset += register.size
        present, goal, torque, error, pwm = values
        return cls(present, goal, bool(torque), decode_hardware_error(error), pwm, pwm_limit)


@dataclass(frozen=True)
class CycleRead:
    """One cycle read as a value: a :class:`ServoReport` per id that answered, the ``silent`` ids (a
    sync read names the one its reply stops at), the ``problem`` ('' if none), its duration (s)
    and the ``unread`` silent ids not asked this cycle (until their next probe)."""

    reports: dict[int, ServoReport]
    silent: tuple[int, ...] = ()
    problem: str = ""
    duration_s: float = 0.0
    unread: tuple[int, ...] = ()

    @property
    def ok(self) -> bool:
        """True when every servo answered."""
        return not self.problem


#: A cycle read of some servos: ``read(attempts, ids)`` (``Rig.read_cycle``).
ReadCycle = Callable[[int, Sequence[int]], CycleRead]


def read_around_silent(
    read: ReadCycle, ids: Sequence[int], silent: Sequence[int], probe: Sequence[int], attempts: int
) -> CycleRead:
    """One cycle's read of the servos not ``silent``, and of each in ``probe`` alone, one try."""
    parts = []
    answering = [i for i in ids if i not in silent]
    if answering:
        parts.append(read(attempts, answering))
    probes = [read(1, [servo_id]) for servo_id in probe]
    parts += probes
    reports: dict[int, ServoReport] = {}
    for part in parts:
        reports.update(part.reports)
    named = [i for part in parts[: len(parts) - len(probes)] for i in part.silent]
    still = named + [i for i in probe if i not in reports and i not in named]
    unread = tuple(i for i in silent if i not in probe)
    problems = [part.problem for part in parts if part.problem and not part.silent]
    if still:
        problems.insert(0, f"servo {', '.join(map(str, still))} did not answer the cycle's read")
    if unread:
        problems.append(f"servo {', '.join(map(str, unread))} silent, not read until its probe")
    return CycleRead(
        reports, tuple(still), "; ".join(problems), sum(part.duration_s for part in parts), unread
    )


class CycleReads:
    """The block transfers and cycle read of :class:`limbctl.servo.bus.ServoBus` (a mixin)."""

    #: Each servo's PWM Limit as set-up read it (until then, the factory value).
    pwm_limits: Mapping[int, int] = MappingProxyType({})
    #: Where each servo keeps Indirect Data 1, as set-up's probe found it (224 until then).
    indirect_at: Mapping[int, int] = MappingProxyType({})

    def note_indirect_data(self, addresses: Mapping[int, int]) -> None:
        """Remember where each servo's Indirect Data 1 is (set-up's probe)."""
        self.indirect_at = MappingProxyType(dict(addresses))

    def note_pwm_limits(self, limits: Mapping[int, int]) -> None:
        """Remember each servo's PWM Limit (EEPROM), the full scale of its Present PWM."""
        self.pwm_limits = MappingProxyType(dict(limits))

    def read_block(self, block: Block, servo_id: int) -> bytes:
        """The raw bytes of ``block`` on one servo (e.g. its indirect address map)."""
        return self._transact(
            f"read {block.name} of servo {servo_id}",
            lambda: transfers.read(self._packets, self._port, block, servo_id),
            patient=True,  # set-up: nothing waits on it but the person
        )

    def write_block(self, block: Block, servo_id: int, data: bytes) -> None:
        """Write ``block.size`` raw bytes ``data`` from ``block``'s address of one servo."""
        if len(data) != block.size:
            raise ConfigError(f"{block.name} takes {block.size} bytes, got {len(data)}")
        self._transact(
            f"write {block.name} to servo {servo_id}",
            lambda: transfers.write(self._packets, self._port, block, servo_id, list(data)),
            patient=True,  # set-up: nothing waits on it but the person
        )

    def sync_write_block(
        self, block: Block, data: Mapping[int, bytes], check_alert: bool = True
    ) -> None:
        """Write ``block.size`` raw bytes per servo in ONE sync write."""
        for values in data.values():
            if len(values) != block.size:
                raise ConfigError(f"{block.name} takes {block.size} bytes, got {len(values)}")
        self._known(data)
        params = {servo_id: list(values) for servo_id, values in data.items()}
        self._transact(
            f"sync write {block.name}",
            lambda: transfers.sync_write(self._packets, self._port, block, params),
            check_alert,
        )

    def read_cycle(self, ids: Sequence[int] | None = None, attempts: int = 1) -> CycleRead:
        """Each servo's :class:`ServoReport` in ONE (fast) sync read; only a failing port raises."""
        groups: dict[int, list[int]] = defaultdict(list)
        for servo_id in self._known(ids):
            groups[self.indirect_at.get(servo_id, CYCLE_BLOCK.address)].append(servo_id)
        parts = [self._read_cycle_at(at, group, attempts) for at, group in groups.items()]
        if len(parts) == 1:
            return parts[0]
        return CycleRead(
            {i: r for part in parts for i, r in part.reports.items()},
            tuple(i for part in parts for i in part.silent),
            "; ".join(part.problem for part in parts if part.problem),
            sum(part.duration_s for part in parts),
        )

    def _read_cycle_at(self, at: int, ids: Sequence[int], attempts: int) -> CycleRead:
        block = (
            CYCLE_BLOCK if at == CYCLE_BLOCK.address else Block(CYCLE_BLOCK.start, CYCLE_BYTES, at)
        )
        fast = bool(self.fast_sync_read)
        read = transfers.fast_sync_read if fast else transfers.sync_read
        start = time.monotonic()
        with self._lock:
            try:
                raw = self._transact(
                    f"{'fast ' if fast else ''}sync read of the cycle's registers",
                    lambda: read(self._packets, self._port, block, ids),
                    check_alert=False,
                    attempts=max(1, int(attempts)),
                )
            except (BusTimeout, CorruptReply) as exc:
                self._require_port().clearPort()  # a late or partial reply must not linger
                # a fast reply cut short names the servo it stopped at: that one is silent
                silent = isinstance(exc, BusTimeout) or (fast and exc.servo_id is not None)
                if silent and exc.servo_id is not None:
                    problem = f"servo {exc.servo_id} did not answer the cycle's read"
                    return CycleRead({}, (exc.servo_id,), problem, time.monotonic() - start)
                return CycleRead({}, (), str(exc), time.monotonic() - start)
            # the reports carry Hardware Error Status: their alert bits are answered
            self._alerted.difference_update(raw)
        reports = {
            i: ServoReport.decode(data, self.pwm_limits.get(i, FACTORY_PWM_LIMIT))
            for i, data in raw.items()
        }
        return CycleRead(reports, (), "", time.monotonic() - start)
