"""The page in headless Chromium: what it shows matches what was published, and it keeps up."""

from __future__ import annotations

import numpy as np

from limbctl.view import EdgeLoop, GuideFigure, Live, PanTilt, Scene, TeleopStatus
from tests.view.browser import LIMITS, canvas_rgb, chromium, text_of, wait_for

#: A 40 x 20 deg rectangle, its top edge traced, the rest not yet.
SQUARE = EdgeLoop(
    pan_tilt_deg=[[-20.0, -10.0], [20.0, -10.0], [20.0, 10.0], [-20.0, 10.0]],
    traced=[False, False, True, False],
)
#: RGB of the region's fill in view.js (COLORS.region).
REGION_RGB = (150, 220, 150)


def pixel(driver, pan: float, tilt: float) -> tuple[int, int, int]:
    return tuple(driver.execute_script(f"return window.limbview.pixel({pan}, {tilt});")[:3])


def test_page_shows_the_record_then_the_teleop_state_to_several_browsers_five_times_a_second(
    browser, served
):
    board, server = served
    samples = np.column_stack([np.linspace(-15, 15, 300), np.linspace(-8, 8, 300)])
    board.publish_scene(
        Scene(
            samples_deg=samples,
            loops=(SQUARE,),
            limits=LIMITS,
            region_note="fitted on 300 samples",
            guide=(GuideFigure("edge closed", 25.0, "%"), GuideFigure("edge gaps", 3)),
            guide_text="trace the lower edge",
        )
    )
    board.publish_live(Live(mode="record", pose=PanTilt(31.25, -12.5), sample_count=300))
    browser.get(server.url)

    wait_for(browser, lambda d: text_of(d, "sample-count") == "300", "sample count not shown")
    assert text_of(browser, "pose") == "31.3, -12.5"
    assert text_of(browser, "mode") == "record"
    assert text_of(browser, "region-note") == "fitted on 300 samples"
    assert text_of(browser, "loop-count") == "1"
    assert text_of(browser, "traced-share") == "25 % of 4 stretches"
    assert text_of(browser, "limits") == "pan -90..90, tilt -40..60"
    assert "edge closed" in text_of(browser, "guide") and "25.0 %" in text_of(browser, "guide")
    assert "edge gaps3" in text_of(browser, "guide")  # a count, without decimals
    assert text_of(browser, "guide-text") == "trace the lower edge"
    assert browser.find_element("id", "teleop").is_displayed() is False
    assert browser.find_element("id", "fault").is_displayed() is False
    # the region is drawn: its fill inside the rectangle (away from samples, markers), not outside
    wait_for(browser, lambda d: pixel(d, -15.0, 5.0) == REGION_RGB, "region fill not drawn")
    assert pixel(browser, 50.0, 40.0) != REGION_RGB, "region fill outside the region"
    # several browsers watch at once
    board.publish_live(Live(mode="record", sample_count=7))
    wait_for(browser, lambda d: text_of(d, "sample-count") == "7", "first browser")
    with chromium() as second:
        second.get(server.url)
        board.publish_live(Live(mode="record", sample_count=8))
        for driver in (browser, second):
            wait_for(driver, lambda d: text_of(d, "sample-count") == "8", "both update")
    # the page updates the pose at least five times a second
    board.publish_live(Live(mode="record", pose=PanTilt(0.0, 0.0)))
    wait_for(browser, lambda d: text_of(d, "pose") == "0.0, 0.0", "first pose not shown")
    # the page counts the live frames it received; publish a new pose every few ms for ~2 s
    start = int(text_of(browser, "live-frames"))
    t0 = browser.execute_script("return performance.now();")
    pose = 0
    while browser.execute_script("return performance.now();") - t0 < 2000.0:
        pose += 1
        board.publish_live(Live(mode="record", pose=PanTilt(float(pose % 90), 0.0)))
    elapsed_s = (browser.execute_script("return performance.now();") - t0) / 1000.0
    frames = int(text_of(browser, "live-frames")) - start
    assert frames / elapsed_s >= 5.0, f"{frames} pose updates in {elapsed_s:.2f} s"

    # the same page in teleop: the limb slides right along the top edge, which blocks it upward
    board.publish_scene(Scene(loops=(SQUARE,), limits=LIMITS, region_note="the model's region"))
    words = "at the edge: up is blocked, sliding along it"
    for step in range(6):
        # the written pose held below the command, the present pose behind both
        written, commanded = PanTilt(2.0 * step, 10.0), PanTilt(2.0 * step + 5.0, 30.0 + step)
        status = TeleopStatus(commanded, written, "corrected", 199.6, step + 1, words, ("+tilt",))
        board.publish_live(Live(mode="teleop", pose=PanTilt(2.0 * step, 1.0), teleop=status))
        wait_for(browser, lambda d, s=step: text_of(d, "cycles") == str(s + 1), f"step {step}")
        assert text_of(browser, "commanded") == f"{2.0 * step + 5.0:.1f}, {30.0 + step:.1f}"
        assert text_of(browser, "written") == f"{2.0 * step:.1f}, 10.0"
        assert text_of(browser, "pose") == f"{2.0 * step:.1f}, 1.0"
    assert text_of(browser, "mode") == "teleop" and text_of(browser, "outcome") == "corrected"
    assert text_of(browser, "rate") == "199.6 Hz"
    assert browser.find_element("id", "teleop").is_displayed()
    assert text_of(browser, "words") == words
    assert text_of(browser, "holds") == "the upper edge"
    assert browser.find_element("id", "legend-teleop").is_displayed()
    assert not browser.find_element("id", "legend-record").is_displayed()
    assert not browser.find_element("id", "guide-panel").is_displayed()
    # watching without the key: nobody's steering is offered
    assert text_of(browser, "control") == "-"
    # the written pose's trail, and the red bar above it (the edge that holds it)
    trail = browser.execute_script("return window.limbview.state.trail;")
    assert trail == [[2.0 * s, 10.0] for s in range(6)]

    def red_above(driver) -> bool:
        x, y = driver.execute_script("return window.limbview.toCanvas(10.0, 10.0);")
        return canvas_rgb(driver, x, y - 16) == (208, 16, 16)

    wait_for(browser, red_above, "no bar on the blocked side")
    board.publish_live(Live(mode="teleop", fault="servo 2 vanished: holding the last safe pose"))
    wait_for(browser, lambda d: d.find_element("id", "fault").is_displayed(), "fault not shown")
    assert "servo 2 vanished" in text_of(browser, "fault")
