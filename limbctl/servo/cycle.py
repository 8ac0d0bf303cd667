"""What each servo reports in the control cycle's ONE sync read, through indirect addresses.

Present Position, Goal Position, Torque Enable and Hardware Error Status live far apart in the
control table (132, 116, 64, 70). The X series' Indirect Address n (168 + 2 (n - 1)) names the
RAM address that Indirect Data n (224 + (n - 1)) stands for, so mapping those registers' bytes
onto Indirect Data 1..10 lets one (Fast) Sync Read of 10 bytes per servo carry all four. Set-up
(:func:`limbctl.servo.setup.configure_servos`) writes the map; a servo that restarts (brown-out,
reboot) loses it with the rest of its RAM: its Indirect Data then read 0, so Torque Enable reads
0 and the restart is noticed as torque loss.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass

from limbctl.errors import BusTimeout, ConfigError, CorruptReply
from limbctl.servo import transfers
from limbctl.servo.control_table import (
    INDIRECT_SLOTS,
    Block,
    Register,
    decode_hardware_error,
)

#: The registers in the cycle's read, in Indirect Data order.
CYCLE_REGISTERS = (
    Register.PRESENT_POSITION,
    Register.GOAL_POSITION,
    Register.TORQUE_ENABLE,
    Register.HARDWARE_ERROR_STATUS,
)
#: Bytes each servo returns per cycle (4 + 4 + 1 + 1).
CYCLE_BYTES = sum(register.size for register in CYCLE_REGISTERS)
#: What the cycle reads: Indirect Data 1 .. CYCLE_BYTES.
CYCLE_BLOCK = Block(Register.INDIRECT_DATA_1, CYCLE_BYTES)
#: What set-up writes: Indirect Address 1 .. CYCLE_BYTES, two bytes each.
INDIRECT_MAP_BLOCK = Block(Register.INDIRECT_ADDRESS_1, 2 * CYCLE_BYTES)

assert CYCLE_BYTES <= INDIRECT_SLOTS


def indirect_map() -> bytes:
    """The bytes of Indirect Address 1..N: each mapped register's addresses, little-endian."""
    addresses = [
        register.address + offset for register in CYCLE_REGISTERS for offset in range(register.size)
    ]
    return b"".join(address.to_bytes(2, "little") for address in addresses)


@dataclass(frozen=True)
class ServoReport:
    """One servo's part of a cycle read.

    Attributes
    ----------
    present, goal : int
        Present and Goal Position (ticks).
    torque_on : bool
        Torque Enable.
    hardware_error : tuple of str
        Decoded Hardware Error Status (empty = healthy).
    """

    present: int
    goal: int
    torque_on: bool
    hardware_error: tuple[str, ...]

    @classmethod
    def decode(cls, data: bytes) -> ServoReport:
        """A report from the CYCLE_BYTES bytes of Indirect Data 1..N."""
        values = []
        offset = 0
        for register in CYCLE_REGISTERS:
            values.append(register.decode(data[offset : offset + register.size]))
            offset += register.size
        present, goal, torque, error = values
        return cls(present, goal, bool(torque), decode_hardware_error(error))


@dataclass(frozen=True)
class CycleRead:
    """The outcome of one cycle read, as a value.

    Attributes
    ----------
    reports : dict
        Servo id -> :class:`ServoReport` (every servo when the read succeeded, else empty).
    silent : tuple of int
        Servos that did not answer (the first one the reply names; more may be silent).
    problem : str
        Why the read failed ('' when it succeeded).
    duration_s : float
        How long the read took (s).
    """

    reports: dict[int, ServoReport]
    silent: tuple[int, ...] = ()
    problem: str = ""
    duration_s: float = 0.0

    @property
    def ok(self) -> bool:
        """True when every servo answered."""
        return not self.problem


class CycleReads:
    """The block transfers and the cycle read of :class:`limbctl.servo.bus.ServoBus`.

    A mixin kept beside the layout it reads; it uses the bus's retry engine (``_transact``),
    lock and port, and nothing else of it.
    """

    def read_block(self, block: Block, servo_id: int) -> bytes:
        """The raw bytes of ``block`` on one servo (e.g. its indirect address map)."""
        return self._transact(
            f"read {block.name} of servo {servo_id}",
            lambda: transfers.read(self._packets, self._port, block, servo_id),
        )

    def write_block(self, block: Block, servo_id: int, data: bytes) -> None:
        """Write ``block.size`` raw bytes ``data`` from ``block``'s address of one servo."""
        if len(data) != block.size:
            raise ConfigError(f"{block.name} takes {block.size} bytes, got {len(data)}")
        self._transact(
            f"write {block.name} to servo {servo_id}",
            lambda: transfers.write(self._packets, self._port, block, servo_id, list(data)),
        )

    def read_cycle(self, ids: Sequence[int] | None = None, attempts: int = 1) -> CycleRead:
        """Each servo's (``ids``, default all) :class:`ServoReport` in ONE (fast) sync read,
        tried at most ``attempts`` times.

        For the control loop: no diagnostic ping, and a silent servo costs ``attempts`` reply
        timeouts, not seconds. A failed read is a value (``silent`` names the servo the
        reply stopped at); only a failing port raises (:class:`PortError`). The indirect map
        must have been written (:func:`limbctl.servo.setup.configure_servos`).
        """
        ids = self._known(ids)
        fast = bool(self.fast_sync_read)
        read = transfers.fast_sync_read if fast else transfers.sync_read
        start = time.monotonic()
        with self._lock:
            try:
                raw = self._transact(
                    f"{'fast ' if fast else ''}sync read of the cycle's registers",
                    lambda: read(self._packets, self._port, CYCLE_BLOCK, ids),
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
        reports = {i: ServoReport.decode(data) for i, data in raw.items()}
        return CycleRead(reports, (), "", time.monotonic() - start)
