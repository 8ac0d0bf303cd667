"""A three-servo leader on the page: its twist beside its pose, a push in twist on the leader's
own twist gauge, and no arrow on the pan/tilt plane for a push that is only twist."""

from __future__ import annotations

import math

import pytest

from limbctl.view import HardLimits, PanTilt, Scene, TeleopStatus
from limbctl.view.leader import LeaderLive, LeaderStatus, with_twist
from tests.view.browser import text_of, wait_for
from tests.view.test_leader import PUSH_RGB, canvas_rgb, made, near

LIMITS = HardLimits(pan_deg=(-90.0, 90.0), tilt_deg=(-40.0, 60.0))


def rad(*deg: float) -> tuple[float, ...]:
    return tuple(math.radians(d) for d in deg)


def pushing(pose_deg, goal_deg) -> LeaderStatus:
    """What leader_status makes of a felt leader pushing from ``pose_deg`` toward ``goal_deg``."""
    status = LeaderStatus(
        PanTilt(*pose_deg[:2]), 0.3, 0.4, PanTilt(*goal_deg[:2]), 1.9, "pushing back"
    )
    return with_twist(status, rad(*pose_deg), rad(*goal_deg))


def test_a_push_in_twist_gives_the_twists_and_no_arrow_on_the_plane():
    # at pan = tilt = 0 the twist is the roll
    status = pushing((0.0, 0.0, 31.7), (0.005, 0.0, 31.4))
    out = status.to_json()
    assert (out["twist_deg"], out["toward_twist_deg"]) == (31.7, 31.4)
    assert out["toward"] is None  # a push in twist alone: no direction on the pan/tilt plane
    swing = pushing((31.9, 0.0, 0.0), (31.6, 0.0, 0.0)).to_json()
    assert swing["toward"] == [31.6, 0.0] and swing["twist_deg"] == 0.0
    # away from the rest pose the twist is not the roll (docs: chain_twist)
    free = with_twist(LeaderStatus(PanTilt(40.0, 30.0)), rad(40.0, 30.0, 10.0), None).to_json()
    assert free["toward_twist_deg"] is None and abs(free["twist_deg"] - 10.0) > 5.0
    assert "twist_deg" not in LeaderStatus(PanTilt(1.0, 2.0)).to_json()  # two servos: as before
    with pytest.raises(ValueError, match="twist_deg"):
        LeaderStatus(PanTilt(1.0, 2.0), twist_deg=math.nan)


def test_the_page_shows_a_three_servo_leaders_twist_and_its_push(browser, served):
    board, server = served
    board.publish_scene(Scene(limits=LIMITS))
    browser.get(server.url)
    teleop = TeleopStatus(PanTilt(0.0, 0.0), PanTilt(0.0, 0.0), "corrected", 200.0, 1)
    leader = pushing((0.0, 0.0, 31.7), (0.005, 0.0, 31.4))
    board.publish_live(LeaderLive("teleop", PanTilt(0.0, 0.0), teleop=teleop, leader=leader))
    wait_for(browser, lambda d: made(d, "leader-twist") and text_of(d, "leader-twist") != "-", "")
    assert text_of(browser, "leader-twist") == "31.7 deg, pushed toward 31.4 deg"
    assert browser.find_element("id", "leader-twist-row").is_displayed()
    assert browser.find_element("id", "leader-twist-toward").is_displayed()
    left = browser.execute_script(
        "return document.getElementById('leader-twist-mark').getBoundingClientRect().left -"
        " document.getElementById('leader-twist-gauge').getBoundingClientRect().left;"
    )
    width = browser.execute_script(
        "return document.getElementById('leader-twist-gauge').getBoundingClientRect().width;"
    )
    assert abs(left + 1 - width * (31.7 + 180) / 360) < 2.0  # the mark at 31.7 deg
    x, y = browser.execute_script("return window.limbview.toCanvas(0.0, 0.0);")
    for dx, dy in ((-30, 0), (30, 0), (0, -30), (0, 30)):  # no arrow drawn from the diamond
        assert not near(canvas_rgb(browser, x + dx, y + dy), PUSH_RGB)
    # released: the twist alone, the push's mark gone; a two-servo leader: no twist row
    free = with_twist(LeaderStatus(PanTilt(0.0, 0.0), 0.0, 0.4, None, 0.2, "free"),
                      rad(0.0, 0.0, 30.2), None)  # fmt: skip
    teleop = TeleopStatus(PanTilt(0.0, 0.0), PanTilt(0.0, 0.0), "corrected", 200.0, 2)
    board.publish_live(LeaderLive("teleop", PanTilt(0.0, 0.0), teleop=teleop, leader=free))
    wait_for(browser, lambda d: text_of(d, "leader-twist") == "30.2 deg", "release not shown")
    assert not browser.find_element("id", "leader-twist-toward").is_displayed()
    teleop = TeleopStatus(PanTilt(0.0, 0.0), PanTilt(0.0, 0.0), "corrected", 200.0, 3)
    two = LeaderStatus(PanTilt(5.0, 0.0), state="free")
    board.publish_live(LeaderLive("teleop", PanTilt(0.0, 0.0), teleop=teleop, leader=two))
    wait_for(browser, lambda d: text_of(d, "leader-pose") == "5.0, 0.0", "two servos not shown")
    assert not browser.find_element("id", "leader-twist-row").is_displayed()
