"""Keys against an edge: the commanded point never runs on past what the gate wrote.

The real loop, gate and keyboard source on a terminal (a pty), the real SDK over the simulator's
pty, on the two-servo and the three-servo rig; the cycles the loop returns are the judge. Up is
pressed step by step into a 40 deg cone from pan 10 deg, where its edge is slanted (presses in
quick succession, as a held key repeats): the limb slides along it; the command never leads the
written pose by more than the one step just pressed, and the first Down press lowers the limb a
full step at once.
"""

from __future__ import annotations

import math
import os
import pty
import threading
import time

import pytest

from limbctl.envelope import Cone
from limbctl.jobs import gate_for
from limbctl.session import open_rig
from limbctl.teleop.cycle import Cycle
from limbctl.teleop.gate import Outcome
from limbctl.teleop.loop import LoopConfig, run
from limbctl.teleop.sources import KeyboardSource

RATE = 200.0
MAX_SPEED = 120.0
#: The step of the up and down presses (deg): large, so a point run on past the edge is plain
#: to see (one "-" from the 10 deg step the session starts with).
STEP_DEG = 5.0
#: Longest wait (s) for the loop to take a press and settle: generous for a loaded machine.
WAIT_S = 30.0
#: A held key as a terminal repeats it (Hz), and how many repeats of Up: a held key moves
#: 10 steps a second (50 deg/s at 5 deg), so 60 repeats at 30 Hz carry it far beyond the cone.
REPEAT_HZ = 30.0
UP_PRESSES = 60


def cone_model(path, profile):
    """A 40 deg cone about the rest axis, saved for ``profile``'s rig (its gate checks that)."""
    metadata = {"rig": profile.name, "calibration": profile.calibration.to_dict()}
    Cone(half_angle_deg=40.0).save(path, metadata=metadata)
    return path


class Cycles:
    """The loop's cycles as they come (its ``on_cycle``), and waits on them."""

    def __init__(self) -> None:
        self.all: list[Cycle] = []
        self.changed = threading.Condition()

    def __call__(self, cycle: Cycle) -> None:
        with self.changed:
            self.all.append(cycle)
            self.changed.notify_all()

    def settled_after(self, start: int) -> Cycle:
        """The first cycle from index ``start`` on that has reached what the gate allows of its
        command (written, not paced by the speed limit)."""

        def found() -> Cycle | None:
            for cycle in self.all[start:]:
                result = cycle.result
                if result is not None and result.outcome is not Outcome.HELD:
                    if not result.slewed and cycle.written:
                        return cycle
            return None

        with self.changed:
            settled = self.changed.wait_for(found, WAIT_S)
            last = self.all[-1] if self.all else None
            assert settled, (
                f"the press was never gated and settled: {len(self.all)} cycles, from {start}; "
                f"the last {last}"
            )
            return found()


def written_deg(cycle: Cycle) -> tuple[float, float]:
    return math.degrees(cycle.result.pose[0]), math.degrees(cycle.result.pose[1])


def press(master: int, cycles: Cycles, source: KeyboardSource, key: bytes) -> Cycle:
    """Press ``key`` once; the cycle where the limb has settled after it: the source has read
    the key (its count grew), the loop took the command in a later cycle and reached it."""
    accepted = source.stats.accepted
    os.write(master, key)
    with cycles.changed:
        assert cycles.changed.wait_for(lambda: source.stats.accepted > accepted, WAIT_S)
        start = len(cycles.all) + 1  # the next cycle polls what was queued before it began
    return cycles.settled_after(start)


@pytest.mark.parametrize("rig", ["sim", "sim3"])
def test_up_against_a_slanted_edge_slides_without_running_on_and_down_answers_at_once(
    tmp_path, rig
):
    cycles = Cycles()
    stop = threading.Event()
    master, slave = pty.openpty()
    try:
        with open_rig(rig_path=rig, goal_log=tmp_path / "goals.jsonl") as session:
            profile = session.profile
            gate = gate_for(cone_model(tmp_path / "cone.npz", profile), profile, RATE, MAX_SPEED)
            session.rig.configure()
            session.rig.set_torque(True)
            source = KeyboardSource(step_deg=10.0, tty_path=os.ttyname(slave), gate=gate)
            source.twist = profile.twists  # as the session sets it: roll kept
            with source:
                config = LoopConfig(rate_hz=RATE, on_cycle=cycles)
                loop = threading.Thread(
                    target=run, args=(session.rig, gate, source, config), kwargs={"stop": stop}
                )
                loop.start()
                try:
                    with cycles.changed:
                        assert cycles.changed.wait_for(lambda: cycles.all, WAIT_S), "no cycle"
                    # left one 10 deg step: +pan, where the cone's edge slants; then 5 deg steps
                    start = press(master, cycles, source, b"a")
                    os.write(master, b"-")
                    first = len(cycles.all)
                    at_edge = []
                    for _ in range(UP_PRESSES):  # Up held: the terminal repeats it
                        at_edge.append(press(master, cycles, source, b"w"))
                        time.sleep(1.0 / REPEAT_HZ)  # the terminal's repeat rate, the input
                    pressed = cycles.all[first:]
                    down = press(master, cycles, source, b"s")
                finally:
                    stop.set()
                    loop.join(WAIT_S)
    finally:
        os.close(master)
        os.close(slave)

    assert written_deg(start) == pytest.approx((10.0, 0.0), abs=0.5)  # the start was read
    stopped = [c for c in at_edge if c.result.corrected]
    assert len(stopped) >= 4, "the presses never reached the edge"
    # how far the command ran ahead of the written pose once the limb had settled
    leads = [
        max(abs(a - b) for a, b in zip(c.command_deg, written_deg(c), strict=True))
        for c in pressed
        if c.result is not None and not c.result.slewed and c.command_deg is not None
    ]
    top = written_deg(at_edge[-1])
    lowered = top[1] - written_deg(down)[1]
    print(
        f"at the edge: written {top}, slid {written_deg(start)[0] - top[0]:.2f} deg in pan; the "
        "command led the "
        f"settled limb by at most {max(leads):.2f} deg; one Down press lowered it {lowered:.2f} deg"
    )
    assert top[0] < written_deg(start)[0] - 1.0  # it slid along the slanted edge (toward pan 0)
    assert max(leads) <= STEP_DEG + 0.2  # never more than the step just pressed
    assert lowered == pytest.approx(STEP_DEG, abs=0.2)  # a full step at once
