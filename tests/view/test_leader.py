"""The leader on the page, in headless Chromium: its marker, its push against the cap, a
three-servo leader's twist on its own gauge; a page without a leader is as before."""

from __future__ import annotations

import math

import pytest

from limbctl.view import Live, PanTilt, Scene, TeleopStatus
from limbctl.view.leader import LeaderLive, LeaderStatus, with_twist
from tests.view.browser import LEADER_RGB, LIMITS, canvas_rgb, near, text_of, wait_for

#: RGB of the leader's push (leader.js COLORS).
PUSH_RGB = (216, 27, 96)


ZERO = PanTilt(0.0, 0.0)


def teleop(cycles: int, command=PanTilt(33.0, 0.0), corrected=PanTilt(29.0, 0.0)) -> TeleopStatus:
    return TeleopStatus(command, corrected, "corrected", 200.0, cycles)


def rad(*deg: float) -> tuple[float, ...]:
    return tuple(math.radians(d) for d in deg)


def pushing(pose_deg, goal_deg) -> LeaderStatus:
    """What leader_status makes of a felt three-servo leader pushing from ``pose_deg`` toward
    ``goal_deg``."""
    status = LeaderStatus(
        PanTilt(*pose_deg[:2]), 0.3, 0.4, PanTilt(*goal_deg[:2]), 1.9, "pushing back"
    )
    return with_twist(status, rad(*pose_deg), rad(*goal_deg))


def test_leader_status_json_its_twists_and_its_checks():
    status = LeaderStatus(PanTilt(32.0, 1.0), 0.29, 0.4, PanTilt(31.7, 1.0), 1.95, "pushing back")
    live = LeaderLive("teleop", PanTilt(29.0, 0.0), leader=status)
    out = live.to_json()
    assert out["leader"] == {
        "pose": [32.0, 1.0],
        "torque_nm": 0.29,
        "cap_nm": 0.4,
        "toward": [31.7, 1.0],
        "beyond_deg": 1.95,
        "state": "pushing back",
    }
    assert {k: v for k, v in out.items() if k != "leader"} == Live(
        "teleop", PanTilt(29.0, 0.0)
    ).to_json()
    assert "leader" not in Live("teleop").to_json()  # the page of every other source: as before
    with pytest.raises(ValueError, match="torque_nm"):
        LeaderStatus(None, -0.1)
    with pytest.raises(ValueError, match="cap_nm"):
        LeaderStatus(None, 0.0, 0.0)
    with pytest.raises(ValueError, match="beyond_deg"):
        LeaderStatus(None, 0.0, None, None, math.nan)
    # a felt leader's read torque goes beside the push; none before its first read
    sensed = LeaderStatus(PanTilt(32.0, 1.0), 0.29, 0.4, None, 1.95, "free", sensed_nm=0.2834)
    assert sensed.to_json()["sensed_nm"] == 0.283
    with pytest.raises(ValueError, match="sensed_nm"):
        LeaderStatus(None, 0.0, 0.4, sensed_nm=-0.01)
    # a push in twist gives the twists and no arrow on the plane; at pan = tilt = 0 twist is roll
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


def made(driver, element_id: str) -> bool:
    """Whether the page has made the element yet (leader.js builds its panel on first sight)."""
    return driver.execute_script(f"return document.getElementById('{element_id}') !== null;")


def test_the_page_draws_a_leader_once_it_sees_one_its_push_and_a_three_servo_leaders_twist(
    browser, served
):
    board, server = served
    board.publish_scene(Scene(limits=LIMITS))
    board.publish_live(Live("teleop", PanTilt(5.0, 5.0), teleop=teleop(7)))
    browser.get(server.url)
    wait_for(browser, lambda d: text_of(d, "cycles") == "7", "teleop not shown")
    assert browser.execute_script("return document.getElementById('leader-panel');") is None
    assert browser.execute_script("return document.getElementById('leader-keys');") is None
    # the leader is pressed 2 deg past an edge at pan 30: the wall pushes it back along -pan
    leader = LeaderStatus(PanTilt(32.0, 0.0), 0.3, 0.4, PanTilt(31.7, 0.0), 2.0, "pushing back")
    board.publish_live(LeaderLive("teleop", PanTilt(29.0, 0.0), teleop=teleop(1), leader=leader))
    wait_for(
        browser, lambda d: made(d, "leader-push") and text_of(d, "leader-push") != "-", "no panel"
    )
    assert text_of(browser, "leader-pose") == "32.0, 0.0"
    assert text_of(browser, "leader-push") == "0.30 N m (cap 0.40 N m)"
    assert text_of(browser, "leader-beyond") == "2.00 deg"
    assert text_of(browser, "leader-state") == "pushing back"
    assert text_of(browser, "pose") == "29.0, 0.0"  # the follower, beside it
    fill = browser.execute_script("return document.getElementById('leader-bar-fill').style.width;")
    assert fill == "75%"  # 0.3 of 0.4
    assert browser.find_element("id", "leader-panel").is_displayed()
    assert "leader (as read)" in text_of(browser, "legend-teleop")

    x, y = browser.execute_script("return window.limbview.toCanvas(32.0, 0.0);")
    wait_for(browser, lambda d: canvas_rgb(d, x, y) == LEADER_RGB, "no leader diamond")
    # the arrow leaves the diamond toward -pan (right on the canvas: the plane is seen from
    # behind the limb), 9 + 14 + 0.75 * 56 px long
    assert near(canvas_rgb(browser, x + 20, y), PUSH_RGB)
    assert near(canvas_rgb(browser, x + 60, y), PUSH_RGB)
    assert not near(canvas_rgb(browser, x - 20, y), PUSH_RGB)
    follower = browser.execute_script("return window.limbview.toCanvas(29.0, 0.0);")
    assert canvas_rgb(browser, *follower) != LEADER_RGB

    # released: free, no arrow, an empty bar
    free = LeaderStatus(PanTilt(30.2, 0.0), 0.0, 0.4, None, 0.2, "free")
    board.publish_live(LeaderLive("teleop", PanTilt(29.0, 0.0), teleop=teleop(2), leader=free))
    wait_for(browser, lambda d: text_of(d, "leader-state") == "free", "release not shown")
    assert text_of(browser, "leader-push") == "0.00 N m (cap 0.40 N m)"
    x, y = browser.execute_script("return window.limbview.toCanvas(30.2, 0.0);")
    wait_for(browser, lambda d: not near(canvas_rgb(d, x + 40, y), PUSH_RGB), "the arrow stayed")

    # a passive leader: its marker, no push figure, no bar
    passive = LeaderStatus(PanTilt(10.0, 5.0), state="leader XL430-W250 senses no current")
    board.publish_live(LeaderLive("teleop", PanTilt(9.0, 5.0), teleop=teleop(3), leader=passive))
    wait_for(browser, lambda d: text_of(d, "leader-pose") == "10.0, 5.0", "passive not shown")
    assert text_of(browser, "leader-push") == "passive: it cannot push"
    assert text_of(browser, "leader-beyond") == "-"
    assert not browser.find_element("id", "leader-bar").is_displayed()

    # the same page given a plain teleop state (any other source): no leader drawn or told
    board.publish_live(Live("teleop", PanTilt(9.0, 5.0), teleop=teleop(9)))
    wait_for(browser, lambda d: text_of(d, "cycles") == "9", "plain state not shown")
    wait_for(
        browser, lambda d: not d.find_element("id", "leader-panel").is_displayed(), "panel stayed"
    )
    assert not browser.find_element("id", "leader-keys").is_displayed()
    x, y = browser.execute_script("return window.limbview.toCanvas(10.0, 5.0);")
    assert canvas_rgb(browser, x, y) != LEADER_RGB

    # a three-servo leader: its twist beside its pose, a push in twist on its own gauge
    leader = pushing((0.0, 0.0, 31.7), (0.005, 0.0, 31.4))
    board.publish_live(LeaderLive("teleop", ZERO, teleop=teleop(5, ZERO, ZERO), leader=leader))
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
    board.publish_live(LeaderLive("teleop", ZERO, teleop=teleop(6, ZERO, ZERO), leader=free))
    wait_for(browser, lambda d: text_of(d, "leader-twist") == "30.2 deg", "release not shown")
    assert not browser.find_element("id", "leader-twist-toward").is_displayed()
    two = LeaderStatus(PanTilt(5.0, 0.0), state="free")
    board.publish_live(LeaderLive("teleop", ZERO, teleop=teleop(8, ZERO, ZERO), leader=two))
    wait_for(browser, lambda d: text_of(d, "leader-pose") == "5.0, 0.0", "two servos not shown")
    assert not browser.find_element("id", "leader-twist-row").is_displayed()
