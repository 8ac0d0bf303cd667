"""The keyboard session as a person has it: `limbctl teleop --source keyboard` in a tmux pane.

The pane is a real pseudo-terminal (160 x 40); keys go in as tmux sends them and everything
asserted is read from the pane's text, as the person would read it. A held key is sent the way
a terminal repeats one: a press, a repeat delay, then a steady repeat rate.
"""

from __future__ import annotations

import re
import sys
import time

import pytest

from limbctl.demo import goal_log_excursions
from limbctl.envelope import load_model
from limbctl.teleop.gate import written_tolerance_deg
from limbctl.teleop.keys import KEY_RATE_HZ
from tests.teleop.tmux import ROOT, tmux_pane

#: A terminal's key repeat: the delay before the first repeat and the rate after it (the X
#: server's 660 ms / 25 Hz default is near; these are the common desktop settings).
REPEAT_DELAY_S = 0.5
REPEAT_HZ = 30.0
POSE = re.compile(r"(commanded|written) pan +(-?[\d.]+) tilt +(-?[\d.]+)")


def poses(status: str) -> dict[str, tuple[float, float]]:
    """The commanded and written poses the status line shows."""
    return {m[1]: (float(m[2]), float(m[3])) for m in POSE.finditer(status)}


def hold_key(pane, key: str, seconds: float, watch=None) -> float:
    """Hold ``key`` for about ``seconds`` as a terminal repeats it; returns the time from the
    press to the last repeat sent (s). ``watch()`` is called after each repeat (while held)."""
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
    """The poses once the limb has reached the command and stays: written = commanded, inside,
    the same on two successive refreshes of the status line (a limb following a held key at
    10 deg/s is within a cycle of its command while it moves)."""
    seen: list[str] = []

    def still(_text: str) -> bool:
        status = pane.status()
        shown = poses(status)
        if not (
            "inside: following the command" in status
            and len(shown) == 2
            and max(abs(a - b) for a, b in zip(shown["commanded"], shown["written"])) < 0.15
        ):
            seen.clear()
            return False
        if not seen or seen[-1].split(" s ")[0] != status.split(" s ")[0]:  # a new refresh
            seen.append(status)
        return len(seen) >= 2 and poses(seen[-1]) == poses(seen[-2])

    pane.wait_for(still, "the limb never settled at the command")
    return poses(seen[-1])


@pytest.fixture(scope="module")
def model_path(tmp_path_factory):
    from calib.profile import default_sim_profile
    from limbctl.envelope import RigidMap
    from limbctl.teach.dataset import load_dataset

    path = tmp_path_factory.mktemp("model") / "model.npz"
    sim = default_sim_profile()
    metadata = {"rig": sim.name, "calibration": sim.calibration.to_dict()}
    data = load_dataset(ROOT / "tests" / "data" / "hand_irregular_seed0_20s.limb")
    RigidMap().fit(data.quaternions).save(path, metadata=metadata)
    return path


def test_keyboard_session_explains_itself_in_a_terminal(tmp_path, model_path):
    goal_log = tmp_path / "goals.jsonl"
    command = (
        f"{sys.executable} -m limbctl teleop --model {model_path} --source keyboard --no-view "
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

        # up until the edge holds it: while the key is held the status line names up as
        # blocked, and only up (nobody pressed left or right); the point never runs on more
        # than a step past the limb; let go, the point is the limb's own pose again
        pane.keys("+", "+")  # 5 deg steps: 50 deg/s held, more than the region is high
        seen: list[str] = []
        hold_key(pane, "Up", 2.0, watch=lambda: seen.append(pane.status()))
        blocked = [line for line in seen if re.search(r"at the edge: .* blocked", line)]
        assert blocked, seen[-3:]
        for line in blocked:
            assert re.search(r"at the edge: up is blocked, (sliding \w+ along it|holding)", line)
            shown = poses(line)
            assert shown["commanded"][1] - shown["written"][1] <= 5.0 + 0.15, line

        def at_the_limb(_text: str) -> bool:
            shown = poses(pane.status())
            return len(shown) == 2 and all(
                abs(a - b) <= 0.15 for a, b in zip(shown["commanded"], shown["written"])
            )

        pane.wait_for(at_the_limb, "the point stayed past the limb after the key was let go")
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

    excursions = goal_log_excursions(goal_log, load_model(model_path))
    print(f"{len(excursions)} goal packets, at most {excursions.max():.4f} deg outside")
    assert len(excursions) > 100 and excursions.max() <= written_tolerance_deg()


def test_keys_start_from_the_gates_pose_hold_release_and_show_the_guide():
    import io
    import math
    import os
    import pty

    from limbctl.envelope import Cone
    from limbctl.teleop.gate import Gate, GateLimits
    from limbctl.teleop.sources import KeyboardSource
    from limbctl.teleop.sources.keyboard import MAX_LEAD_DEG

    gate = Gate(Cone(math.radians(40)), GateLimits((-1.7, -0.5), (1.7, 1.4), 0.01, 0.02))
    gate.start(math.radians(10.0), math.radians(5.0))
    guide = io.StringIO()
    master, slave = pty.openpty()
    try:
        with KeyboardSource(tty_path=os.ttyname(slave), gate=gate, guide=guide) as source:
            # up from where the gate holds the limb (not from 0, 0); space holds: up is ignored;
            # space releases from the limb's pose; a larger step; up; the guide again; quit
            os.write(master, b"w w +\x1b[A?q")
            assert source.wait_finished(10.0)
        assert source.stats.accepted == 4  # up, the hold's own pose, the release's, up
        assert (source.pan_deg, source.tilt_deg) == pytest.approx((10.0, 10.0))
        assert not source.holding and source.step_deg == 5.0
        assert guide.getvalue().count("q          quit") == 2
        # a burst of held-down ups runs no further ahead of the limb than MAX_LEAD_DEG
        master2, slave2 = pty.openpty()
        try:
            with KeyboardSource(step_deg=10.0, tty_path=os.ttyname(slave2), gate=gate) as ahead:
                os.write(master2, b"wawawawawawaq")  # alternating: each one a press
                assert ahead.wait_finished(10.0)
            assert ahead.tilt_deg == pytest.approx(5.0 + MAX_LEAD_DEG)
            assert ahead.pan_deg == pytest.approx(10.0 + MAX_LEAD_DEG)
        finally:
            os.close(master2)
            os.close(slave2)
    finally:
        os.close(master)
        os.close(slave)


def test_the_centre_is_the_point_deepest_inside_the_region(model_path):
    import math

    import numpy as np

    from limbctl.envelope import Cone
    from limbctl.geometry.gimbal import pan_tilt_to_direction, pan_tilt_to_quat
    from limbctl.teleop.sources.keyboard import region_centre

    model = load_model(model_path)
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
