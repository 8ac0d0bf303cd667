"""A second process that makes a felt leader limp when its controller dies (docs/haptic.md)."""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import time
from collections.abc import Sequence
from typing import TYPE_CHECKING

from limbctl.errors import LimbctlError, PortInUse
from limbctl.servo.bus import ServoBus
from limbctl.servo.control_table import Register

if TYPE_CHECKING:
    from types import FrameType

#: What the controller writes before closing the pipe on a clean end.
DONE = b"done\n"
#: The bound (s) from the controller's death to the guard's exit, the leader limp: ten Bus
#: Watchdog times, far over the 22-45 ms measured (docs/decisions/haptic.md), for a loaded machine.
GIVE_UP_S = 1.0
#: How often (s) the guard tries the port while the dead controller's lock is still on it.
PORT_RETRY_S = 0.002
#: How long (s) a clean end waits for the guard to exit: its start takes 47 ms, quiet.
EXIT_WAIT_S = 5.0
#: The retry budget (s) of each guard transaction: a few replies, so the next servo is not kept.
RETRY_BUDGET_S = 0.05


class GuardBus(ServoBus):
    """The guard's bus: never patient (a silent servo must not hold up the next)."""

    def _transact(self, what, attempt, check_alert=True, attempts=None, patient=False):
        return super()._transact(what, attempt, check_alert, attempts, patient=False)


class GaveUp(Exception):
    """The guard's bound ran out (raised by its alarm)."""


class LeaderGuard:
    """The controller's side of a running guard: its ``process`` and the pipe's ``write_fd``."""

    def __init__(self, process: subprocess.Popen, write_fd: int) -> None:
        self.process = process
        self._write_fd: int | None = write_fd

    @classmethod
    def start(cls, bus: ServoBus, leader_ids: Sequence[int]) -> LeaderGuard:
        """Start a guard for ``leader_ids`` on ``bus``'s port (not waited for)."""
        read_fd, write_fd = os.pipe()  # both not inheritable (PEP 446): only pass_fds passes
        command = [sys.executable, "-m", "limbctl.servo.leader_guard", "--fd", str(read_fd)]
        command += ["--port", bus.port_name, "--baud", str(bus.baud)]
        command += ["--latency-timer", f"{bus.latency_timer_ms:g}"]
        command += ["--ids", ",".join(str(i) for i in leader_ids)]
        try:
            process = subprocess.Popen(
                command,
                pass_fds=(read_fd,),
                close_fds=True,
                start_new_session=True,
                stdin=subprocess.DEVNULL,
                stdout=subprocess.DEVNULL,
            )
        except BaseException:
            os.close(write_fd)
            raise
        finally:
            os.close(read_fd)
        return cls(process, write_fd)

    def done(self) -> None:
        """A clean end: tell the guard to exit touching nothing and wait; None. Safe twice."""
        fd, self._write_fd = self._write_fd, None
        if fd is None:
            return
        try:
            os.write(fd, DONE)
        except OSError:
            pass  # the guard is gone already (it exits only on EOF or a kill)
        finally:
            os.close(fd)
        try:
            self.process.wait(EXIT_WAIT_S)
        except subprocess.TimeoutExpired:
            self.process.kill()  # it never read its pipe: nothing it could still do matters
            self.process.wait()


def wait_for_controller(fd: int) -> bool:
    """Block until the pipe ``fd`` ends; True if the controller said ``done`` first."""
    said = b""
    while chunk := os.read(fd, 64):
        said += chunk
    return said == DONE


def switch_off(
    port: str, baud: int, left: list[int], latency_timer_ms: float, failures: dict
) -> None:
    """Torque Enable 0 on each servo of ``left`` (removed once done), ``failures`` by servo."""
    while left:
        for servo_id in list(left):
            bus = GuardBus(port, baud, (servo_id,), retry_budget_s=RETRY_BUDGET_S)
            bus.fast_sync_read, bus.latency_timer_ms = False, latency_timer_ms
            try:
                with bus:
                    bus.write(Register.TORQUE_ENABLE, servo_id, 0, check_alert=False)
                left.remove(servo_id)
            except PortInUse:
                time.sleep(PORT_RETRY_S)  # the dead controller's lock is still being dropped
                break
            except LimbctlError as exc:
                failures[servo_id] = str(exc)
                time.sleep(PORT_RETRY_S)


def _give_up(signum: int, frame: FrameType | None) -> None:
    raise GaveUp


def main(argv: Sequence[str] | None = None) -> int:
    """Run the guard (``--fd N --port P --baud B --ids 3,4``); 0: clean end or limp, 1: gave up."""
    parser = argparse.ArgumentParser(prog="limbctl.servo.leader_guard")
    parser.add_argument("--fd", type=int, required=True)
    parser.add_argument("--port", required=True)
    parser.add_argument("--baud", type=int, required=True)
    parser.add_argument("--latency-timer", type=float, required=True)
    parser.add_argument("--ids", required=True)
    args = parser.parse_args(argv)
    ids = tuple(int(i) for i in args.ids.split(","))
    if wait_for_controller(args.fd):
        return 0
    died_at = time.monotonic()
    signal.signal(signal.SIGALRM, _give_up)
    signal.setitimer(signal.ITIMER_REAL, GIVE_UP_S)
    left, failures = list(ids), {}
    try:
        switch_off(args.port, args.baud, left, args.latency_timer, failures)
    except GaveUp:
        pass
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0.0)
    took_ms = (time.monotonic() - died_at) * 1e3
    if not left:
        print(
            f"leader guard: the controller died; Torque Enable 0 on leader servos "
            f"{', '.join(map(str, ids))} {took_ms:.0f} ms after (the leader is limp)",
            file=sys.stderr,
        )
        return 0
    last = failures.get(left[0], "no answer")
    print(
        f"leader guard: the controller died; could not switch off leader servos "
        f"{', '.join(map(str, left))} on {args.port} within {GIVE_UP_S:g} s (gave up {took_ms:.0f} "
        f"ms after; {last}): their Bus Watchdog holds them with at most the last push until the "
        f"power goes: switch it off",
        file=sys.stderr,
    )
    return 1


if __name__ == "__main__":
    sys.exit(main())
