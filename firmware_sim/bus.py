"""The simulator on a pseudo-terminal (:func:`serve`), and :class:`SimulatedBus`, which runs it in
its own process so that a controller's busy polling cannot starve it (README.md shows its use)."""

from __future__ import annotations

import contextlib
import errno
import json
import os
import select
import signal
import socket
import subprocess
import sys
import time
import tty
from collections.abc import Callable, Mapping
from functools import partial
from multiprocessing.connection import Connection
from pathlib import Path
from typing import Any

from firmware_sim.events import EventSchedule
from firmware_sim.faults import FaultPlan
from firmware_sim.hand import Hand
from firmware_sim.simulator import Simulator
from firmware_sim.wire import host_baud, wire_s

# The physics keeps moving (hand, profiles) at least this often without traffic.
TICK_S = 0.005
# Bytes read at once: above any SDK packet (a 253-servo sync write is ~1.3 kB).
READ_CHUNK = 4096
# Waits shorter than this are spun rather than slept (a sleep can overshoot by ~1 ms).
SPIN_BELOW_S = 0.0015
# How long (s) SimulatedBus waits for its process to come up, and for a reply or an exit.
START_TIMEOUT_S = 60.0
REPLY_TIMEOUT_S = 10.0


class PtyEndpoint:
    """A pty whose slave side a controller opens like a U2D2's serial device; ``link``, if given,
    becomes a symlink to it (replacing a symlink, refusing any other file)."""

    def __init__(self, link: str | os.PathLike | None = None) -> None:
        self.master, self._slave = os.openpty()
        tty.setraw(self._slave)
        os.set_blocking(self.master, False)
        self.device = os.ttyname(self._slave)
        self.link = None if link is None else Path(link)
        if self.link is not None:
            if self.link.is_symlink():
                self.link.unlink()
            elif self.link.exists():
                self.close()
                raise FileExistsError(
                    f"{self.link} exists and is not a symlink; choose another --link path"
                )
            self.link.symlink_to(self.device)

    @property
    def port(self) -> str:
        """What a controller opens: the link if there is one, else the device."""
        return str(self.link) if self.link is not None else self.device

    def write_all(self, data: bytes) -> None:
        """Write every byte of ``data`` to the controller (waits while the pty is full)."""
        view = memoryview(data)
        while view:
            try:
                written = os.write(self.master, view)
            except BlockingIOError:
                select.select([], [self.master], [], 0.1)
                continue
            view = view[written:]

    def read_available(self) -> bytes:
        """Whatever the controller has sent (b"" if nothing)."""
        try:
            return os.read(self.master, READ_CHUNK)
        except BlockingIOError:
            return b""
        except OSError as error:
            if error.errno == errno.EIO:  # no reader/writer at the moment
                return b""
            raise

    def close(self) -> None:
        """Remove the link (if still ours) and close the pty; safe to call twice."""
        if self.link is not None and self.link.is_symlink():
            if os.readlink(self.link) == self.device:
                self.link.unlink()
        for fd in (self.master, self._slave):
            if fd >= 0:
                os.close(fd)
        self.master = self._slave = -1

    def __enter__(self) -> PtyEndpoint:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _wait_until(deadline: float) -> None:
    remaining = deadline - time.monotonic()
    if remaining > SPIN_BELOW_S:
        time.sleep(remaining - SPIN_BELOW_S)
    while time.monotonic() < deadline:
        pass


def serve(
    sim: Simulator,
    endpoint: PtyEndpoint,
    should_stop: Callable[[], bool],
    control: Any | None = None,
    on_control: Callable[[Any], bool] | None = None,
    schedule: EventSchedule | None = None,
) -> None:
    """Run the firmware until ``should_stop()``, or ``on_control(control)``, called whenever
    ``control`` is readable, returns False; ``schedule``'s faults are applied once due."""
    sources = [endpoint.master] + ([control] if control is not None else [])
    free_at = 0.0  # when the wire is quiet again (a write without reply still occupies it)
    while not should_stop():
        if schedule is not None:
            schedule.apply_due(sim)
        ready, _, _ = select.select(sources, [], [], TICK_S)
        if endpoint.master in ready:
            data = endpoint.read_available()
            if data:
                baud = host_baud(endpoint.master)
                # the pty delivers at once; on the wire the last byte lands this much later
                quiet = max(time.monotonic(), free_at) + wire_s(len(data), baud)
                replies = sim.receive(data, sim.now(), baud)
                for packet, delay in replies:
                    # Return Delay Time after the bus goes quiet, then the reply's wire time
                    quiet += delay + wire_s(len(packet), baud)
                    _wait_until(quiet)
                    endpoint.write_all(packet)
                    quiet = max(quiet, time.monotonic())
                free_at = quiet
                sim.persist()
        if control is not None and control in ready and on_control is not None:
            if not on_control(control):
                return
        sim.advance()


#: Plain options passed to :class:`FaultPlan` and, as they are, to :class:`Simulator`.
_FAULT_KEYS = ("drop", "corrupt", "latency_ms", "latency_p")
_SIM_KEYS = "ids model goal_log baud factory connect eeprom_dir leader roll_id".split()


def build_simulator(config: Mapping[str, Any]) -> Simulator:
    """A :class:`Simulator` from plain options (the CLI's and :class:`SimulatedBus`'s)."""
    seed = int(config.get("seed", 0))
    hand = _make_hand(config.get("hand"), seed)
    plan = FaultPlan(**{k: config[k] for k in _FAULT_KEYS if k in config}, seed=seed)
    options = {k: config[k] for k in _SIM_KEYS if config.get(k) is not None}
    return Simulator(**options, hand=hand, seed=seed, faults=plan)


def _make_hand(spec: Any, seed: int) -> Hand | None:
    if spec is None:
        return None
    if isinstance(spec, Mapping):
        return Hand.from_mapping(dict(spec), seed=seed)
    return Hand.from_yaml(spec, seed=seed)


_REQUESTS: dict[str, Callable[..., Any]] = {
    "truth": Simulator.truth,
    "set_hand": lambda sim, spec: sim.world.set_hand(_make_hand(spec, sim.seed)),
    "set_operator": Simulator.set_operator,
    "push": Simulator.push,
    "vanish": Simulator.vanish,
    "restart": Simulator.restart,
    "set_environment": Simulator.set_environment,
    "set_faults": lambda sim, options: sim.faults.replan(FaultPlan(**options)),
}


def _control(sim: Simulator, conn: Any) -> bool:
    """Execute one :class:`SimulatedBus` request inside the simulator process."""
    try:
        name, args = conn.recv()
    except (EOFError, OSError):
        return False  # the parent went away: stop serving
    if name == "stop":
        return False
    try:
        result = _REQUESTS[name](sim, *args)
    except Exception as error:  # reported to the caller, who re-raises it
        conn.send(("error", type(error).__name__, str(error)))
    else:
        conn.send(("ok", result))
    return True


def child_main(conn: Any, config: dict) -> None:
    """Body of the simulator process started by :class:`SimulatedBus`."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent decides when we stop
    try:
        sim = build_simulator(config)
        endpoint = PtyEndpoint(config.get("link"))
    except Exception as error:
        conn.send(("error", type(error).__name__, str(error)))
        conn.close()
        return
    try:
        conn.send(("ready", endpoint.device, endpoint.port))
        serve(sim, endpoint, lambda: False, control=conn, on_control=partial(_control, sim))
    finally:
        endpoint.close()
        sim.close()
        with contextlib.suppress(BrokenPipeError, OSError):
            conn.send(("stopped",))
        conn.close()


def _hand_spec(hand: Mapping | str | os.PathLike | None) -> dict | str | None:
    """A hand option as plain data for the simulator process."""
    if hand is None:
        return None
    return dict(hand) if isinstance(hand, Mapping) else os.fspath(hand)


_ERRORS = {"ValueError": ValueError, "FileExistsError": FileExistsError, "KeyError": KeyError}


class SimulatedBus:
    """Servos on a pty, served by a separate process; a context manager. The other options are
    :class:`firmware_sim.simulator.Simulator`'s as plain data (``hand`` a REGION.yaml mapping or
    path), the :class:`firmware_sim.faults.FaultPlan`'s and ``link`` (also make this path a symlink
    to the pty)."""

    def __init__(
        self,
        ids=(1, 2),
        model: str = "xl430-w250",
        hand: Mapping | str | os.PathLike | None = None,
        goal_log: str | os.PathLike | None = None,
        seed: int = 0,
        drop: float = 0.0,
        corrupt: float = 0.0,
        latency_ms: float = 0.0,
        latency_p: float = 1.0,
        link: str | os.PathLike | None = None,
        baud: int | None = None,
        factory: int = 0,
        connect=None,
        eeprom_dir: str | os.PathLike | None = None,
        leader: Mapping | None = None,
        roll_id: int | None = None,
    ) -> None:
        FaultPlan(drop=drop, corrupt=corrupt, latency_ms=latency_ms, latency_p=latency_p)
        given = {"goal_log": (goal_log, str), "link": (link, str), "baud": (baud, int)}
        given |= {"connect": (connect, list), "eeprom_dir": (eeprom_dir, str)}
        given |= {"leader": (leader, dict), "roll_id": (roll_id, int)}
        self.config = {key: None if v is None else kind(v) for key, (v, kind) in given.items()}
        self.config |= {"ids": tuple(ids), "model": model, "hand": _hand_spec(hand)}
        self.config |= {"seed": int(seed), "factory": int(factory), "drop": drop}
        self.config |= {"corrupt": corrupt, "latency_ms": latency_ms, "latency_p": latency_p}
        self._process: subprocess.Popen | None = None
        self._conn: Connection | None = None
        self.exitcode: int | None = None
        self.device: str | None = None
        self.port: str | None = None

    def start(self) -> SimulatedBus:
        """Start the simulator process and wait until its pty is ready."""
        parent, child = socket.socketpair()
        command = [sys.executable, "-m", "firmware_sim._child", str(child.fileno())]
        command.append(json.dumps(self.config))
        self._process = subprocess.Popen(command, pass_fds=(child.fileno(),))
        child.close()
        self._conn = Connection(parent.detach())
        if not self._conn.poll(START_TIMEOUT_S):
            self.close()
            raise TimeoutError(f"the simulator did not start within {START_TIMEOUT_S} s")
        try:
            message = self._conn.recv()
        except EOFError:
            self.close()
            raise RuntimeError(
                f"the simulator process died on start (exit {self.exitcode})"
            ) from None
        if message[0] == "error":
            self.close()
            raise _ERRORS.get(message[1], RuntimeError)(message[2])
        _, self.device, self.port = message
        return self

    def close(self) -> None:
        """Stop the process, remove the link, close the pipe; safe to call twice."""
        if self._conn is not None:
            with contextlib.suppress(BrokenPipeError, EOFError, OSError):
                self._conn.send(("stop", ()))
                if self._conn.poll(REPLY_TIMEOUT_S):
                    self._conn.recv()
            self._conn.close()
            self._conn = None
        if self._process is not None:
            try:
                self._process.wait(REPLY_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                self._process.terminate()
                self._process.wait(REPLY_TIMEOUT_S)
            self.exitcode = self._process.returncode
            self._process = None

    def __enter__(self) -> SimulatedBus:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def running(self) -> bool:
        return self._process is not None and self._process.poll() is None

    def _call(self, name: str, *args: Any) -> Any:
        if self._conn is None:
            raise RuntimeError("the simulator is not running: use `with SimulatedBus(...)`")
        self._conn.send((name, args))
        if not self._conn.poll(REPLY_TIMEOUT_S):
            raise TimeoutError(f"the simulator did not answer {name!r} within {REPLY_TIMEOUT_S} s")
        reply = self._conn.recv()
        if reply[0] == "error":
            raise _ERRORS.get(reply[1], RuntimeError)(reply[2])
        return reply[1]

    def truth(self) -> dict[str, Any]:
        """Ground truth: ``joints_deg``, ``servos[id]`` (raw_tick, setpoint, load_percent,
        torque_on, goal_position, hardware_error_status, present), fault counters."""
        return self._call("truth")

    def set_hand(self, hand: Mapping | str | os.PathLike | None) -> None:
        """Give the limb to a hand (REGION mapping or YAML path), or take it away (None)."""
        self._call("set_hand", _hand_spec(hand))

    def set_operator(self, operator: Mapping | None) -> None:
        """Give the leader gimbal to an operator (``firmware_sim.leader.Operator`` as data)."""
        self._call("set_operator", None if operator is None else dict(operator))

    def push(self, servo_id: int, torque_percent: float) -> None:
        """Push a joint with a steady torque (% of stall, shaft frame); 0 clears it."""
        self._call("push", servo_id, float(torque_percent))

    def vanish(self, servo_id: int, duration_s: float) -> None:
        """Make a servo unreachable for ``duration_s`` seconds (it keeps its state)."""
        self._call("vanish", servo_id, float(duration_s))

    def restart(self, servo_id: int, off_s: float = 0.0) -> None:
        """Brown-out: off the bus for ``off_s`` s, then back with RAM at its defaults."""
        self._call("restart", servo_id, float(off_s))

    def set_voltage(self, servo_id: int, volts: float) -> None:
        """Supply voltage the servo measures (V)."""
        self._call("set_environment", servo_id, float(volts), None)

    def set_temperature(self, servo_id: int, celsius: float) -> None:
        """Motor temperature the servo measures (deg C)."""
        self._call("set_environment", servo_id, None, float(celsius))

    def set_faults(
        self,
        drop: float = 0.0,
        corrupt: float = 0.0,
        latency_ms: float = 0.0,
        latency_p: float = 1.0,
        seed: int = 0,
    ) -> None:
        """Replace the fault options while running."""
        options = dict(
            drop=drop, corrupt=corrupt, latency_ms=latency_ms, latency_p=latency_p, seed=seed
        )
        FaultPlan(**options)
        self._call("set_faults", options)
