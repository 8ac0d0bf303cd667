"""Headless Chromium through Selenium with the system chromedriver, and what the page tests read
of it (also used by benchmarks/)."""

from __future__ import annotations

import contextlib
import os
import signal
import tempfile
from collections.abc import Iterator
from pathlib import Path

from selenium import webdriver
from selenium.webdriver.chrome.service import Service
from selenium.webdriver.common.action_chains import ActionChains
from selenium.webdriver.support.ui import WebDriverWait

from limbctl.view import HardLimits
from tests.system_tools import find

#: Flags without which Chromium stalls here (root, closed network, no GPU).
FLAGS = (
    "--headless --no-sandbox --disable-gpu --disable-quic --no-first-run --disable-sync"
    " --disable-background-networking --disable-component-update --window-size=1300,820"
).split()
#: Longest wait (s) for what a page should show: generous for a 2-core machine under load.
WAIT_S = 30.0
#: The hard limits the page tests' scenes carry.
LIMITS = HardLimits(pan_deg=(-90.0, 90.0), tilt_deg=(-40.0, 60.0))
#: RGB of the leader's diamond (leader.js COLORS.leader).
LEADER_RGB = (0, 137, 123)


@contextlib.contextmanager
def chromium() -> Iterator[webdriver.Chrome]:
    """A headless Chromium with a new empty profile, quit on exit."""
    with tempfile.TemporaryDirectory(prefix="limbctl-chromium-") as profile:
        options = webdriver.ChromeOptions()
        options.binary_location = find("chromium")
        for flag in FLAGS:
            options.add_argument(flag)
        options.add_argument(f"--user-data-dir={profile}")
        driver = webdriver.Chrome(service=Service(find("chromedriver")), options=options)
        try:
            yield driver
        finally:
            driver.quit()


def wait_for(driver: webdriver.Chrome, condition, message: str, timeout: float = WAIT_S):
    """Wait until ``condition(driver)`` is truthy and return it; fail with ``message`` if not."""
    return WebDriverWait(driver, timeout, poll_frequency=0.05).until(condition, message)


def text_of(driver: webdriver.Chrome, element_id: str) -> str:
    """The text an element shows (textContent, so hidden tables read too)."""
    return driver.execute_script(f"return document.getElementById('{element_id}').textContent;")


#: Half the last digit of a pose the page shows ("pan, tilt", one decimal): compared with the
#: value, as JavaScript's toFixed and Python's format round the ties of tick poses apart.
SHOWN_HALF_DIGIT_DEG = 0.05


def canvas_rgb(driver: webdriver.Chrome, x: float, y: float) -> tuple[int, int, int]:
    """The RGB of the plane canvas's pixel at (``x``, ``y``) (canvas px, rounded)."""
    return tuple(
        driver.execute_script(
            "return Array.from(document.getElementById('plane').getContext('2d')"
            f".getImageData({round(x)}, {round(y)}, 1, 1).data);"
        )[:3]
    )


def near(rgb, target, tol: int = 8) -> bool:
    """The same colour but for the canvas's antialiasing (each channel within ``tol``)."""
    return all(abs(a - b) <= tol for a, b in zip(rgb, target, strict=True))


#: One tick of an X-series servo (360 / 4096 deg): a read just before or after the logged one.
TICK_DEG = 360.0 / 4096.0


def assert_pose_shown(
    text: str, pose_deg, logged_digits: int | None = None, reads_apart: bool = False
) -> None:
    """The page's "pan, tilt" ``text`` shows ``pose_deg`` within its rounding and that of
    ``logged_digits`` (the decimals ``pose_deg`` was rounded to); with ``reads_apart``, give or
    take one tick (frames are pushed at their own rate beside the reads)."""
    shown = [float(part) for part in text.split(",")]
    slack = SHOWN_HALF_DIGIT_DEG + (0.5 * 10.0**-logged_digits if logged_digits else 0.0)
    slack += TICK_DEG if reads_apart else 0.0
    assert len(shown) == len(pose_deg) == 2, f"not a pose: {text!r}"
    assert all(abs(a - b) <= slack + 1e-9 for a, b in zip(shown, pose_deg)), (
        f"the page shows {text}, the pose is {tuple(pose_deg)}"
    )


def browser_pids(driver: webdriver.Chrome) -> list[int]:
    """The browser's processes (every descendant of chromedriver), to freeze or kill them."""
    children: dict[int, list[int]] = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue  # the process ended while being read
        children.setdefault(int(fields[1]), []).append(int(stat.parent.name))
    out, todo = [], list(children.get(driver.service.process.pid, []))
    while todo:
        pid = todo.pop()
        out.append(pid)
        todo += children.get(pid, [])
    return out


@contextlib.contextmanager
def frozen(driver: webdriver.Chrome) -> Iterator[list[int]]:
    """The whole browser stopped (SIGSTOP) for the block, then continued (SIGCONT); a process
    gone before its signal is passed over, and every one stopped is continued even on failure."""
    stopped: list[int] = []
    try:
        for pid in browser_pids(driver):
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGSTOP)
                stopped.append(pid)
        yield stopped
    finally:
        for pid in stopped:
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGCONT)


def drag_on_plane(driver: webdriver.Chrome, points, pause_s: float = 0.15) -> None:
    """Press on the plane at the first (pan, tilt) deg point and move through the others,
    pausing ``pause_s`` at each; the button stays down."""
    canvas = driver.find_element("id", "plane")
    size = driver.execute_script("const c = arguments[0]; return [c.width, c.height];", canvas)
    actions = ActionChains(driver, duration=50)
    for i, (pan, tilt) in enumerate(points):
        x, y = driver.execute_script(f"return window.limbview.toCanvas({pan}, {tilt});")
        dx, dy = round(x - size[0] / 2), round(y - size[1] / 2)  # from the canvas's centre
        actions.move_to_element_with_offset(canvas, dx, dy)
        if i == 0:
            actions.click_and_hold()
        actions.pause(pause_s)
    actions.perform()
