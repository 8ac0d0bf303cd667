"""The servo bus: the dynamixel-sdk (Protocol 2.0) with bounded retries, typed errors and alarms."""

from __future__ import annotations

import errno
import os
import threading
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from contextlib import AbstractContextManager
from dataclasses import dataclass
from typing import Any

import serial
from dynamixel_sdk import COMM_RX_CORRUPT, COMM_RX_TIMEOUT, COMM_SUCCESS, PacketHandler, PortHandler

from limbctl.errors import (
    BusError,
    BusTimeout,
    ConfigError,
    CorruptReply,
    InvalidInputError,
    PortError,
    PortInUse,
    ServoAlarm,
)
from limbctl.servo import transfers
from limbctl.servo.alarms import alarm_message
from limbctl.servo.control_table import (
    ALERT_BIT,
    FAST_SYNC_READ_MIN_FIRMWARE,
    MAX_TICK,
    MODEL_BY_NAME,
    ModelNumber,
    Register,
    StatusError,
    decode_hardware_error,
    describe_status_error,
    model_name,
)
from limbctl.servo.cycle import CycleReads
from limbctl.servo.port_lock import describe_holders
from limbctl.servo.transfers import SDK_LATENCY_TIMER_MS, Attempt, TunedPortHandler

try:  # POSIX serial ports report a vanished device through termios as well
    from termios import error as _TermiosError
except ImportError:  # pragma: no cover - not POSIX
    _TermiosError = OSError

#: What the serial layer raises when the port fails or disappears.
_PORT_FAILURES = (serial.SerialException, OSError, _TermiosError)


@dataclass
class BusStats:
    """Counters for telemetry: transactions attempted and how they went."""

    transactions: int = 0
    retries: int = 0
    timeouts: int = 0
    corrupt: int = 0


class ServoBus(CycleReads):
    """Servos on one serial port; a context manager (``close()`` is safe to call twice).

    Parameters
    ----------
    port, baud : str, int
        Serial device path (``/dev/ttyUSB0``, the simulator's pty link); bit rate (bit/s).
    ids : sequence of int
        Servo ids, e.g. ``(1, 2)`` for (pan, tilt).
    model : str or None
        Expected model name (``"xl430-w250"``); None accepts any supported.
    retry_budget_s, max_attempts : float, int
        Time (s) within which a failing transaction is retried; most tries (at least 1).
    fast_sync_read : bool or None
        Force Fast Sync Read on/off; None decides from firmware version and a probe.
    latency_timer_ms : float
        The USB adapter's latency timer (ms): 16 is the FTDI default; 1 once lowered (README).
    """

    def __init__(
        self,
        port: str,
        baud: int,
        ids: Sequence[int],
        model: str | None = None,
        retry_budget_s: float = 0.25,
        max_attempts: int = 3,
        fast_sync_read: bool | None = None,
        latency_timer_ms: float = SDK_LATENCY_TIMER_MS,
    ) -> None:
        if not ids or len(set(ids)) != len(ids):
            raise ConfigError(f"ids must be distinct servo ids, got {list(ids)}")
        if model is not None and model not in MODEL_BY_NAME:
            raise ConfigError(f"model must be one of {', '.join(MODEL_BY_NAME)}, got {model!r}")
        self.port_name = str(port)
        self.baud = int(baud)
        self.ids = tuple(int(i) for i in ids)
        self.expected_model = MODEL_BY_NAME[model] if model else None
        self.retry_budget_s = float(retry_budget_s)
        self.max_attempts = max(1, int(max_attempts))
        self.fast_sync_read = fast_sync_read
        if not 0.0 <= latency_timer_ms <= 255.0:
            raise ConfigError(f"latency_timer_ms must be 0..255, got {latency_timer_ms}")
        self.latency_timer_ms = float(latency_timer_ms)
        self.models: dict[int, ModelNumber] = {}
        self.firmware: dict[int, int] = {}
        self.stats = BusStats()
        self._port: PortHandler | None = None
        self._packets = PacketHandler(2.0)
        self._lock = threading.RLock()
        self._alerted: set[int] = set()

    @classmethod
    def from_profile(cls, profile: Any, port: str | None = None, **options: Any) -> ServoBus:
        """A bus for a :class:`calib.profile.RigProfile` (``port`` overrides the profile's)."""
        return cls(port or profile.port, profile.baud, profile.ids, profile.model, **options)

    # ---- lifecycle ----
    def open(self) -> ServoBus:
        """Open the port, ping every servo, check models, pick the sync-read flavour."""
        with self._lock:
            if self._port is not None:
                return self
            self._port = port = self._open_port()
            try:
                # not time-critical: wait as the SDK would, lest a busy machine seem silent
                port.latency_timer_ms = max(self.latency_timer_ms, SDK_LATENCY_TIMER_MS)
                for servo_id in self.ids:
                    self._identify(servo_id)
                if self.fast_sync_read is None:
                    self.fast_sync_read = self._probe_fast_sync_read()
                port.latency_timer_ms = self.latency_timer_ms
            except BaseException:
                self.close()
                raise
            return self

    def close(self) -> None:
        """Close the port (torque is left as it is). Safe to call twice."""
        with self._lock:
            port, self._port = self._port, None
            if port is not None and port.is_open:
                port.closePort()

    def __enter__(self) -> ServoBus:
        return self.open()

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def is_open(self) -> bool:
        """True between :meth:`open` and :meth:`close`."""
        return self._port is not None

    def _open_port(self) -> PortHandler:
        hint = "check the cable / permissions (dialout group) / --port"
        if not os.path.exists(self.port_name):
            raise PortError(f"serial port {self.port_name} does not exist: {hint}")
        port = TunedPortHandler(self.port_name, self.latency_timer_ms)
        try:
            opened = port.setBaudRate(self.baud)
        except _PORT_FAILURES as exc:
            if getattr(exc, "errno", None) in (errno.EAGAIN, errno.EWOULDBLOCK):
                raise PortInUse(
                    f"serial port {self.port_name} is in use by "
                    f"{describe_holders(self.port_name)}: only one controller may drive a bus; "
                    f"stop that one first (nothing was sent to the servos)"
                ) from None
            raise PortError(f"cannot open serial port {self.port_name} ({exc}): {hint}") from exc
        if not opened:
            raise ConfigError(f"baud {self.baud} is not supported by the serial port driver")
        return port

    def _identify(self, servo_id: int) -> None:
        first = servo_id == self.ids[0]  # patient: a servo just powered on may answer late
        ping = lambda: transfers.ping(self._packets, self._port, servo_id)  # noqa: E731
        number = self._transact(f"ping servo {servo_id}", ping, check_alert=False, patient=first)
        try:
            model = ModelNumber(number)
        except ValueError:
            raise ConfigError(
                f"servo {servo_id} is {model_name(number)}, which limbctl does not support "
                f"(supported: {', '.join(MODEL_BY_NAME)})"
            ) from None
        if self.expected_model is not None and model != self.expected_model:
            raise ConfigError(
                f"servo {servo_id} is {model_name(model)} but the rig profile says "
                f"{model_name(self.expected_model)}: fix `model:` in the profile or connect the "
                f"right servo"
            )
        self.models[servo_id] = model
        self.firmware[servo_id] = self.read(Register.FIRMWARE_VERSION, servo_id, check_alert=False)

    def _probe_fast_sync_read(self) -> bool:
        if min(self.firmware.values()) < FAST_SYNC_READ_MIN_FIRMWARE:
            return False
        with self._lock:
            port = self._require_port()
            outcome = transfers.fast_sync_read(
                self._packets, port, Register.PRESENT_POSITION, self.ids
            )
        return outcome.result == COMM_SUCCESS

    # ---- the retry engine ----
    def _require_port(self) -> PortHandler:
        if self._port is None:
            raise PortError(f"the bus on {self.port_name} is not open; use it as a context manager")
        return self._port

    def _transact(
        self,
        what: str,
        attempt: Callable[[], Attempt],
        check_alert: bool = True,
        attempts: int | None = None,
        patient: bool = False,
    ) -> Any:
        """Run ``attempt`` until it succeeds, or its tries or budget (``patient``: longer) end."""
        with self._lock:
            port = self._require_port()
            self.stats.transactions += 1
            deadline = time.monotonic() + (
                transfers.PATIENT_BUDGET_S if patient else self.retry_budget_s
            )
            outcome: Attempt | None = None
            for number in range(
                attempts or (transfers.PATIENT_MAX_ATTEMPTS if patient else self.max_attempts)
            ):
                try:
                    if number:
                        self.stats.retries += 1
                        port.clearPort()
                    outcome = attempt()
                except _PORT_FAILURES as exc:
                    raise PortError(
                        f"{what}: serial port {self.port_name} failed ({exc}); was the adapter "
                        f"unplugged? check the cable and reconnect",
                    ) from exc
                if outcome.result == COMM_SUCCESS:
                    refused = {
                        i: e & ~ALERT_BIT for i, e in outcome.errors.items() if e & ~ALERT_BIT
                    }
                    if not refused:
                        break
                    servo_id, code = next(iter(refused.items()))
                    if code != StatusError.CRC:
                        raise BusError(
                            f"{what}: servo {servo_id} refused it ({describe_status_error(code)})",
                            servo_id,
                        )
                    outcome.result = COMM_RX_CORRUPT  # our packet was garbled: retry
                    outcome.culprit = servo_id
                if time.monotonic() >= deadline:
                    break
            assert outcome is not None
            if outcome.result != COMM_SUCCESS:
                self.stats.timeouts += outcome.result == COMM_RX_TIMEOUT
                self.stats.corrupt += outcome.result == COMM_RX_CORRUPT
                raise transfers.failure(what, outcome, number + 1, self.baud, self.port_name)
            alerted = {i for i, e in outcome.errors.items() if e & ALERT_BIT}
            self._alerted |= alerted
            if check_alert and self._alerted:
                self._raise_alarms()
            return outcome.value

    # ---- alarms ----
    def _raise_alarms(self) -> None:
        alerted = sorted(self._alerted)
        errors = self._hardware_errors(alerted)
        # the reads above carry the alert bit again: they answered it, so forget them
        self._alerted.difference_update(alerted)
        found = {i: bits for i, bits in errors.items() if bits}
        if not found:
            return
        torque: dict[int, bool] = {}
        for i in found:
            try:
                torque[i] = bool(self.read(Register.TORQUE_ENABLE, i, check_alert=False))
            except BusError:
                pass  # unknown: the message says so
        servo_id, bits = next(iter(found.items()))
        raise ServoAlarm(alarm_message(found, torque), servo_id, bits)

    def _hardware_errors(self, ids: Iterable[int]) -> dict[int, tuple[str, ...]]:
        return {
            i: decode_hardware_error(self.read(Register.HARDWARE_ERROR_STATUS, i, False))
            for i in ids
        }

    def read_hardware_errors(self) -> dict[int, tuple[str, ...]]:
        """Decoded Hardware Error Status of every servo (empty tuple = healthy)."""
        with self._lock:
            return self._hardware_errors(self.ids)

    def check_alarms(self) -> None:
        """Raise :class:`ServoAlarm` if any servo has a hardware error set."""
        with self._lock:
            self._alerted |= set(self.ids)
            self._raise_alarms()

    # ---- single registers ----
    def read(
        self, register: Register, servo_id: int, check_alert: bool = True, patient: bool = False
    ) -> int:
        """Value of ``register`` on one servo (``patient`` for set-up: see :meth:`_transact`)."""
        return self._transact(
            f"read {register.name} of servo {servo_id}",
            lambda: transfers.read(self._packets, self._port, register, servo_id),
            check_alert,
            patient=patient,
        )

    def write(
        self, register: Register, servo_id: int, value: int, check_alert: bool = True
    ) -> None:
        """Write ``value`` to ``register`` of one servo and await its status (``check_alert``)."""
        data = register.encode(value)
        self._transact(
            f"write {register.name}={value} to servo {servo_id}",
            lambda: transfers.write(self._packets, self._port, register, servo_id, data),
            check_alert,
            patient=True,
        )

    # ---- group transfers ----
    def sync_read(
        self, register: Register, ids: Sequence[int] | None = None, check_alert: bool = True
    ) -> dict[int, int]:
        """``register`` of every servo in ``ids`` (default all) in ONE sync read."""
        ids = self._known(ids)
        flavour = "fast sync read" if self.fast_sync_read else "sync read"
        read = transfers.fast_sync_read if self.fast_sync_read else transfers.sync_read
        with self._lock:
            try:
                return self._transact(
                    f"{flavour} {register.name}",
                    lambda: read(self._packets, self._port, register, ids),
                    check_alert,
                )
            except (BusTimeout, CorruptReply) as exc:
                # one silent servo cuts a combined reply short, which looks like corruption:
                # ask each servo once so the message names the one that is gone
                silent = [i for i in ids if self._silent(i)]
                if not silent or len(silent) == len(ids):
                    raise
                names = ", ".join(str(i) for i in silent)
                raise BusTimeout(
                    f"{flavour} {register.name}: servo {names} did not answer (not even a "
                    f"ping): check its power supply and cable; the others answer",
                    silent[0],
                ) from exc

    def _silent(self, servo_id: int) -> bool:
        """True if ``servo_id`` does not answer one ping (a diagnostic; no retries)."""
        port = self._require_port()
        try:
            outcome = transfers.ping(self._packets, port, servo_id)
        except _PORT_FAILURES:
            return False  # the port itself failed: that is not this servo's fault
        return outcome.result == COMM_RX_TIMEOUT

    def sync_write(self, register: Register, values: Mapping[int, int]) -> None:
        """Write one value per servo to ``register`` in ONE sync write (no reply)."""
        self._known(values)
        params = {servo_id: register.encode(value) for servo_id, value in values.items()}
        self._transact(
            f"sync write {register.name}",
            lambda: transfers.sync_write(self._packets, self._port, register, params),
        )

    def _known(self, ids: Iterable[int] | None) -> tuple[int, ...]:
        if ids is None:
            return self.ids
        ids = tuple(ids)
        unknown = [i for i in ids if i not in self.ids]
        if unknown or not ids:
            raise ConfigError(f"servo ids {unknown or '[]'} are not on this bus {list(self.ids)}")
        return ids

    # ---- what the controller uses ----
    def read_positions(self) -> dict[int, int]:
        """Present Position (ticks) of every servo, read in one sync read."""
        return self.sync_read(Register.PRESENT_POSITION)

    def write_goals(self, goals: Mapping[int, int]) -> None:
        """Goal Position (ticks, 0..4095) for each servo in ``goals``, in one sync write."""
        for servo_id, tick in goals.items():
            if isinstance(tick, bool) or int(tick) != tick or not 0 <= tick <= MAX_TICK:
                raise InvalidInputError(
                    f"goal for servo {servo_id} must be an integer tick in 0..{MAX_TICK}, "
                    f"got {tick!r}"
                )
        self.sync_write(Register.GOAL_POSITION, {i: int(t) for i, t in goals.items()})

    def set_torque(self, enabled: bool, ids: Sequence[int] | None = None) -> None:
        """Torque on or off, servo by servo; off ignores alarms and tries every servo first."""
        if enabled:
            for servo_id in self._known(ids):
                self.write(Register.TORQUE_ENABLE, servo_id, 1)
            return
        failures: list[BusError] = []
        for servo_id in self._known(ids):
            try:
                self.write(Register.TORQUE_ENABLE, servo_id, 0, check_alert=False)
            except BusError as exc:
                failures.append(exc)
        if failures:
            raise failures[0]

    def torque_enabled(self) -> dict[int, bool]:
        """Torque Enable of every servo."""
        return {i: bool(v) for i, v in self.sync_read(Register.TORQUE_ENABLE).items()}

    def exclusive(self) -> AbstractContextManager[object]:
        """``with bus.exclusive():`` holds the bus (re-entrant) against other threads."""
        return self._lock

    def reboot(self, servo_id: int, timeout_s: float = 3.0) -> None:
        """Reboot one servo (clears an alarm; torque off, RAM reset) and wait for its answer."""
        self._known([servo_id])
        with self._lock:
            self._transact(
                f"reboot servo {servo_id}",
                lambda: transfers.reboot(self._packets, self._port, servo_id),
                check_alert=False,
            )
            self._alerted.discard(servo_id)
            deadline = time.monotonic() + timeout_s
            while True:
                # each ping blocks until its own reply timeout: this waits on the servo
                _, result, _ = self._packets.ping(self._port, servo_id)
                if result == COMM_SUCCESS:
                    return
                if time.monotonic() >= deadline:
                    raise BusTimeout(
                        f"servo {servo_id} did not come back within {timeout_s} s of a reboot: "
                        f"power-cycle it",
                        servo_id,
                    )
