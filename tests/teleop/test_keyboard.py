"""The keyboard source: on a pseudo-terminal, in a tmux pane, against an edge on both rigs."""

from __future__ import annotations

import contextlib
import io
import math
import os
import pty
import re
import sys
import time
from collections.abc import Callable, Iterator

import numpy as np
import pytest

from limbctl.demo import goal_log_excursions
from limbctl.envelope import Cone, load_model
from limbctl.errors import ConfigError
from limbctl.geometry.gimbal import pan_tilt_roll_to_quat, pan_tilt_to_direction, pan_tilt_to_quat
from limbctl.jobs import gate_for
from limbctl.teleop.cycle import Cycle
from limbctl.teleop.gate import Gate, GateLimits, Outcome, written_tolerance_deg
from limbctl.teleop.keys import KEY_RATE_HZ
from limbctl.teleop.loop import LoopConfig
from limbctl.teleop.sources import KeyboardSource
from limbctl.teleop.sources.keyboard import MAX_LEAD_DEG, region_centre
from tests.safety.support import Gathered, LoopThread
from tests.teleop.chains import live_chain
from tests.teleop.tmux import ROOT, tmux_pane

#: A terminal's key repeat (common desktop settings): the delay before the first, the rate after.
REPEAT_DELAY_S = 0.5
REPEAT_HZ = 30.0
POSE = re.compile(r"(commanded|written) pan +(-?[\d.]+) tilt +(-?[\d.]+)")


def poses(status: str) -> dict[str, tuple[float, float]]:
    """The commanded and written poses the status line shows."""
    return {m[1]: (float(m[2]), float(m[3])) for m in POSE.finditer(status)}


def lead(shown: dict[str, tuple[float, float]]) -> float:
    """The largest joint gap (deg) between commanded and written pose; inf if one is missing."""
    if len(shown) != 2:
        return math.inf
    return max(abs(a - b) for a, b in zip(shown["commanded"], shown["written"]))


def hold_key(pane, key: str, seconds: float, watch=None) -> float:
    """Hold ``key`` ``seconds`` as a terminal repeats it, ``watch()`` after each repeat: the
    time (s) from the press to the last repeat."""
    pane.keys(key)
    first = time.monotonic()  # each key timed once tmux has passed it on, as the source reads it
    time.sleep(REPEAT_DELAY_S)  # the terminal's repeat delay: the key is down, nothing is sent
    last = time.monotonic()
    while last - first < seconds:
        pane.keys(key)
        last = time.monotonic()
        if watch is not None:
            watch()
        time.sleep(1.0 / REPEAT_HZ)  # the terminal's repeat rate
    return last - first


def settled(pane) -> dict[str, tuple[float, float]]:
    """The poses once written = commanded, inside, on two successive status refreshes."""
    seen: list[str] = []

    def still(_text: str) -> bool:
        status = pane.status()
        if "inside: following the command" not in status or not lead(poses(status)) < 0.15:
            seen.clear()
            return False
        if not seen or seen[-1].split(" s ")[0] != status.split(" s ")[0]:  # a new refresh
            seen.append(status)
        return len(seen) >= 2 and poses(seen[-1]) == poses(seen[-2])

    pane.wait_for(still, "the limb never settled at the command")
    return poses(seen[-1])


def test_keyboard_session_explains_itself_in_a_terminal(tmp_path, hand_model_path):
    goal_log = tmp_path / "goals.jsonl"
    command = (
        f"{sys.executable} -m limbctl teleop --model {hand_model_path} --source keyboard --no-view "
        f"--goal-log {goal_log}"
    )
    with tmux_pane(command, env={"PYTHONPATH": str(ROOT)}) as pane:
        # the guide at the start: every key, how far a press moves, how fast a held key
        text = pane.wait_for(lambda t: "q          quit" in t, "no key guide at the start")
        assert "one press moves 2 deg; a key held moves 20 deg/s" in text
        for words in ("tilt up", "pan left", "a larger step", "hold here", "region's centre"):
            assert words in text
        pane.wait_for(lambda t: "written pan" in pane.status(), "no status line")
        assert "step 2 deg" in pane.status() and "Hz" in pane.status()

        # a smaller step (1 deg: 10 deg/s held), back to the region's centre
        pane.keys("-", "c")
        pane.wait_for(lambda t: "step 1 deg" in pane.status(), "the step did not change")
        before = settled(pane)

        # hold "left" for 2 s: the limb moves 10 deg/s for as long as the key is down
        held_s = hold_key(pane, "Left", 2.0)
        after = settled(pane)
        moved = after["written"][0] - before["written"][0]
        predicted = 1.0 * KEY_RATE_HZ * held_s
        print(f"held {held_s:.2f} s: moved {moved:.2f} deg, the step predicts {predicted:.2f} deg")
        assert moved == pytest.approx(predicted, rel=0.10), (moved, predicted, held_s)
        assert after["written"][1] == pytest.approx(before["written"][1], abs=0.15)

        # up until the edge holds it: only up is named blocked, the point never a step past
        # the limb; let go, the point is the limb's pose again
        pane.keys("+", "+")  # 5 deg steps: 50 deg/s held, more than the region is high
        seen: list[str] = []
        hold_key(pane, "Up", 2.0, watch=lambda: seen.append(pane.status()))
        blocked = [line for line in seen if re.search(r"at the edge: .* blocked", line)]
        assert blocked, seen[-3:]
        for line in blocked:
            assert re.search(r"at the edge: up is blocked, (sliding \w+ along it|holding)", line)
            shown = poses(line)
            assert shown["commanded"][1] - shown["written"][1] <= 5.0 + 0.15, line

        pane.wait_for(
            lambda t: lead(poses(pane.status())) <= 0.15,
            "the point stayed past the limb after the key was let go",
        )
        assert "blocked" not in pane.status()

        # the guide again on ?, then q quits and parks
        pane.keys("?")
        pane.wait_for(
            lambda t: pane.text(history=True).count("q          quit") >= 2,
            "? did not repeat the guide",
        )
        pane.keys("q")
        pane.wait_for(lambda t: "EXIT " in t, "the session did not end")
        text = pane.text(history=True)
        assert "EXIT 0" in text and "ended by           end of input" in text

    excursions = goal_log_excursions(goal_log, load_model(hand_model_path))
    print(f"{len(excursions)} goal packets, at most {excursions.max():.4f} deg outside")
    assert len(excursions) > 100 and excursions.max() <= written_tolerance_deg()


@contextlib.contextmanager
def keyboard_on_pty(**options) -> Iterator[tuple[KeyboardSource, Callable[[bytes], int]]]:
    """A :class:`KeyboardSource` on a new pseudo-terminal: yields it and a function that types."""
    master, slave = pty.openpty()
    try:
        with KeyboardSource(tty_path=os.ttyname(slave), **options) as source:
            yield source, lambda keys: os.write(master, keys)
    finally:
        os.close(master)
        os.close(slave)


def typed(source: KeyboardSource, type_, keys: bytes, count: int) -> list:
    """Type ``keys``, poll until ``count`` commands came, then quit: the commands."""
    type_(keys)
    got = []
    while len(got) < count:
        batch = source.poll(timeout=5.0)
        assert batch, "no key arrived"
        got += batch
    type_(b"q")
    assert source.wait_finished(5.0)
    return got


def test_keyboard_source_on_a_pseudo_terminal_and_only_on_one(tmp_path):
    """Each key of a burst a press; roll keys turn a three-servo limb and are refused on two."""
    with keyboard_on_pty(step_deg=5.0) as (src, type_):
        # up, left, a stray key, up (w), left (a) in one burst: each a press of its own key
        typed(src, type_, b"\x1b[A\x1b[Dx" + b"wa", 4)
    assert src.stats.accepted == 4
    assert (src.pan_deg, src.tilt_deg) == (10.0, 10.0)
    with pytest.raises(ConfigError, match="needs a terminal"):
        KeyboardSource(tty_path=str(tmp_path / "no-such-tty"))
    plain = tmp_path / "plain-file"
    plain.write_text("")
    with pytest.raises(ConfigError, match="not a terminal"):
        KeyboardSource(tty_path=str(plain))
    for twist in (True, False):
        with keyboard_on_pty(step_deg=5.0) as (src, type_):
            src.twist = twist
            got = typed(src, type_, b"]]\x1b[A[", 4 if twist else 1)  # roll +2, up, roll -1
        if twist:
            assert (src.pan_deg, src.tilt_deg, src.roll_deg) == (0.0, 5.0, 5.0)
            np.testing.assert_allclose(
                got[-1].q, pan_tilt_roll_to_quat(0.0, math.radians(5), math.radians(5))
            )
        else:
            assert src.stats.rejected == 3
            assert "roll keys need a three-servo rig" in src.stats.refusals.lines()[0]


def test_keys_start_from_the_gates_pose_hold_release_and_show_the_guide():
    gate = Gate(Cone(math.radians(40)), GateLimits((-1.7, -0.5), (1.7, 1.4), 0.01, 0.02))
    gate.start(math.radians(10.0), math.radians(5.0))
    guide = io.StringIO()
    with keyboard_on_pty(gate=gate, guide=guide) as (source, type_):
        # up from the gate's pose; space holds (up ignored), releases; +; up; ?; quit
        type_(b"w w +\x1b[A?q")
        assert source.wait_finished(10.0)
    assert source.stats.accepted == 4  # up, the hold's own pose, the release's, up
    assert (source.pan_deg, source.tilt_deg) == pytest.approx((10.0, 10.0))
    assert not source.holding and source.step_deg == 5.0
    assert guide.getvalue().count("q          quit") == 2
    # a burst of held-down ups runs no further ahead of the limb than MAX_LEAD_DEG
    with keyboard_on_pty(step_deg=10.0, gate=gate) as (ahead, type_):
        type_(b"wawawawawawaq")  # alternating: each one a press
        assert ahead.wait_finished(10.0)
    assert ahead.tilt_deg == pytest.approx(5.0 + MAX_LEAD_DEG)
    assert ahead.pan_deg == pytest.approx(10.0 + MAX_LEAD_DEG)


def test_the_centre_is_the_point_deepest_inside_the_region(hand_model_path):
    model = load_model(hand_model_path)
    pan, tilt = region_centre(model)
    assert bool(model.contains(pan_tilt_to_quat(math.radians(pan), math.radians(tilt))))
    edge = model.mesh.vertices

    def clearance(p: float, t: float) -> float:
        d = pan_tilt_to_direction(math.radians(p), math.radians(t))
        return float(np.degrees(np.arccos(np.clip((edge @ d).max(), -1.0, 1.0))))

    # deeper than the edge's mean direction, and than any point a step away
    mean = edge.mean(axis=0)
    mean_pan = math.degrees(math.atan2(mean[1], mean[0]))
    mean_tilt = math.degrees(math.asin(mean[2] / np.linalg.norm(mean)))
    assert clearance(pan, tilt) > clearance(mean_pan, mean_tilt) + 5.0
    for dp, dt in ((2, 0), (-2, 0), (0, 2), (0, -2)):
        assert clearance(pan, tilt) >= clearance(pan + dp, tilt + dt) - 1e-9
    assert region_centre(Cone(math.radians(30))) is None  # no mesh: the centre key does nothing


# -- keys against an edge (the real loop over the simulator's pty): the point never runs on ----

RATE = 200.0
MAX_SPEED = 120.0
STEP_DEG = 5.0  # the up and down presses' step (deg): a point run on is plain to see
WAIT_S = 30.0  # the longest wait (s) for the loop to take a press and settle
UP_PRESSES = 60  # repeats of a held Up: at 30 Hz they carry it far beyond the cone


class Cycles(Gathered):
    """The loop's cycles as they come (its ``on_cycle``, ``items``), and waits on them."""

    def settled_after(self, start: int) -> Cycle:
        """The first cycle from ``start`` on written and not slewed."""

        def found() -> Cycle | None:
            for cycle in self.items[start:]:
                result = cycle.result
                if result is not None and result.outcome is not Outcome.HELD:
                    if not result.slewed and cycle.written:
                        return cycle
            return None

        with self.changed:
            settled = self.changed.wait_for(found, WAIT_S)
            last = self.items[-1] if self.items else None
            assert settled, f"never gated and settled: cycles {start}-{len(self.items)}: {last}"
            return found()


def written_deg(cycle: Cycle) -> tuple[float, float]:
    return math.degrees(cycle.result.pose[0]), math.degrees(cycle.result.pose[1])


def press(type_, cycles: Cycles, source: KeyboardSource, key: bytes) -> Cycle:
    """Press ``key`` once; the cycle where the limb has settled after it."""
    accepted = source.stats.accepted
    type_(key)
    with cycles.changed:
        assert cycles.changed.wait_for(lambda: source.stats.accepted > accepted, WAIT_S)
        start = len(cycles.items) + 1  # the next cycle polls what was queued before it began
    return cycles.settled_after(start)


@pytest.mark.parametrize("rig", ["sim", "sim3"])
def test_up_against_a_slanted_edge_slides_without_running_on_and_down_answers_at_once(
    tmp_path, rig, cone_file
):
    cycles = Cycles()
    with live_chain(rig, tmp_path / "goals.jsonl") as session:
        profile = session.profile
        gate = gate_for(cone_file(40.0, rig), profile, RATE, MAX_SPEED)
        with keyboard_on_pty(step_deg=10.0, gate=gate) as (source, type_):
            source.twist = profile.twists  # as the session sets it: roll kept
            config = LoopConfig(rate_hz=RATE, on_cycle=cycles)
            with LoopThread(session.rig, gate, source, config):
                assert cycles.waits(lambda: cycles.items, WAIT_S), "no cycle"
                # left one 10 deg step: +pan, where the cone's edge slants; then 5 deg steps
                start = press(type_, cycles, source, b"a")
                type_(b"-")
                first = len(cycles.items)
                at_edge = []
                for _ in range(UP_PRESSES):  # Up held: the terminal repeats it
                    at_edge.append(press(type_, cycles, source, b"w"))
                    time.sleep(1.0 / REPEAT_HZ)  # the terminal's repeat rate, the input
                pressed = cycles.items[first:]
                down = press(type_, cycles, source, b"s")

    assert written_deg(start) == pytest.approx((10.0, 0.0), abs=0.5)  # the start was read
    stopped = [c for c in at_edge if c.result.corrected]
    assert len(stopped) >= 4, "the presses never reached the edge"
    # how far the command ran ahead of the written pose once the limb had settled (a cycle whose
    # read failed holds and writes nothing: its pose says nothing of the command's lead)
    leads = [
        max(abs(a - b) for a, b in zip(c.command_deg, written_deg(c), strict=True))
        for c in pressed
        if c.written and not c.result.slewed and c.command_deg is not None
    ]
    top = written_deg(at_edge[-1])
    lowered = top[1] - written_deg(down)[1]
    print(
        f"at the edge: written {top}, slid {written_deg(start)[0] - top[0]:.2f} deg in pan; the "
        f"command led by at most {max(leads):.2f} deg; one Down lowered it {lowered:.2f} deg"
    )
    assert top[0] < written_deg(start)[0] - 1.0  # it slid along the slanted edge (toward pan 0)
    assert max(leads) <= STEP_DEG + 0.2  # never more than the step just pressed
    assert lowered == pytest.approx(STEP_DEG, abs=0.2)  # a full step at once
