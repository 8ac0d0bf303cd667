"""A felt leader's teleop on the live page: the simulator's leader gimbal pushed past the edge by
its operator, the real loop over the pty feeding the page, watched in headless Chromium."""

from __future__ import annotations

import threading

from calib.profile import default_sim_profile
from limbctl.envelope import Cone
from limbctl.jobs import gate_for
from limbctl.live import TeleopFeed, leader_status
from limbctl.servo.setup import configure_servos
from limbctl.session import open_rig
from limbctl.teleop.loop import LoopConfig, run
from limbctl.teleop.sources import LeaderSource
from limbctl.view import Board, ViewServer
from tests.view.browser import chromium, wait_for

IDS = (3, 4)
EDGE = 30.0
#: The operator means to go 20 deg past the edge and stays there (a relaxed 0.3 N m hand).
PRESS = {"script": [[0.0, 0.0, 0.0], [1.5, EDGE + 20.0, 0.0]], "max_torque_nm": 0.3}
#: RGB of the leader's diamond (leader.js COLORS.leader).
LEADER_RGB = (0, 137, 123)
#: What the page received last, what it shows of it, and the leader diamond's pixel, read in one
#: script (the page's thread cannot change them in between).
SHOWN = """
const live = window.limbview.state.live;
const leader = live && live.leader;
if (!leader || !leader.pose || !document.getElementById('leader-push')) return null;
const text = (id) => document.getElementById(id).textContent;
const xy = window.limbview.toCanvas(leader.pose[0], leader.pose[1]);
const rgb = Array.from(document.getElementById('plane').getContext('2d')
  .getImageData(Math.round(xy[0]), Math.round(xy[1]), 1, 1).data).slice(0, 3);
return {leader: leader, pose: text('leader-pose'), push: text('leader-push'),
        state: text('leader-state'), follower: live.pose, rgb: rgb};
"""


class Recording(TeleopFeed):
    """The page's feed, keeping every leader part it published."""

    def __init__(self, board: Board) -> None:
        super().__init__(board)
        self.published: list[dict] = []

    def __call__(self, cycle) -> None:
        super().__call__(cycle)
        live = self.board.live
        self.published.append(live.to_json())


def test_the_page_shows_the_felt_leader_beside_the_follower_and_how_hard_it_pushes(tmp_path):
    cone = tmp_path / "cone.npz"
    sim = default_sim_profile()
    metadata = {"rig": sim.name, "calibration": sim.calibration.to_dict()}
    Cone(half_angle_deg=EDGE).save(cone, metadata=metadata)
    board = Board()
    feed = Recording(board)
    leader = {"ids": list(IDS), "model": "xm430-w350"}
    with (
        open_rig(extra_ids=IDS, sim_options={"leader": leader}) as session,
        ViewServer(board, port=0) as server,
        chromium() as browser,
    ):
        rig = session.rig
        configure_servos(rig.bus, {**rig.tick_limits(), **dict.fromkeys(IDS, (0, 4095))})
        # the start's rate check and the pace watch against 50 Hz: a busy test machine must
        # not switch the feel off before the page is looked at
        source = LeaderSource(rig, IDS, rate_hz=50.0)
        stop = threading.Event()
        with source:
            feed.leader = leader_status(source)
            rig.set_torque(True)
            gate = gate_for(cone, sim, 200.0, 120.0)
            config = LoopConfig(on_cycle=feed)
            thread = threading.Thread(target=lambda: run(rig, gate, source, config, stop=stop))
            thread.start()
            try:
                browser.get(server.url)
                session.simulator.set_operator(PRESS)

                def pushing(driver):
                    shown = driver.execute_script(SHOWN)
                    return shown if shown and shown["leader"]["torque_nm"] > 0.0 else None

                shown = wait_for(browser, pushing, "the page never showed the leader pushing")
            finally:
                stop.set()
                thread.join(timeout=10.0)
    leader_part = shown["leader"]
    # what the page shows is what the feed published, in one of the loop's cycles
    published = [live["leader"] for live in feed.published]
    matching = [live for live in feed.published if live["leader"] == leader_part]
    assert matching, f"the page's {leader_part} was never published"
    assert shown["follower"] == matching[-1]["pose"]  # the follower's pose of the same cycle
    assert shown["pose"] == f"{leader_part['pose'][0]:.1f}, {leader_part['pose'][1]:.1f}"
    assert shown["push"] == (
        f"{leader_part['torque_nm']:.2f} N m (cap {leader_part['cap_nm']:.2f} N m)"
    )
    assert shown["state"] == "pushing back"
    assert tuple(shown["rgb"]) == LEADER_RGB  # the leader's diamond where it is
    # the leader is past the edge and the follower is not; the push is within the cap
    assert leader_part["pose"][0] > EDGE and leader_part["beyond_deg"] > 0.4
    assert 0.0 < leader_part["torque_nm"] <= leader_part["cap_nm"] <= 0.4
    assert leader_part["toward"][0] < leader_part["pose"][0]  # pushed back toward the region
    assert all(part["cap_nm"] == leader_part["cap_nm"] for part in published)
