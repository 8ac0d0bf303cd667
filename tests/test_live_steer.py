"""Steering from the page: `teleop --source page` on the simulator, driven from headless Chromium.

A drag that leaves the region moves the simulated limb along its edge, judged by the simulator's
own goal log; a frozen browser (SIGSTOP) holds the limb; a killed one leaves it held and the
session ends normally.
"""

from __future__ import annotations

import json
import os
import signal
import time
from pathlib import Path

import numpy as np
import pytest
from selenium.webdriver.common.action_chains import ActionChains

from limbctl.demo import goal_log_excursions
from limbctl.envelope import load_model
from limbctl.geometry.gimbal import pan_tilt_to_quat, quat_to_pan_tilt
from limbctl.jobs import TeleopOptions, run_teleop
from limbctl.live import ViewOptions, open_view
from limbctl.teleop.gate import written_tolerance_deg
from tests.test_live import Watcher, model_path  # noqa: F401 (the module's model fixture)
from tests.view.browser import browser_pids, chromium, drag_on_plane, text_of, wait_for

#: Cycles in a row that must hold, with no goal written, before a frozen page counts as held:
#: a second at 200 Hz, twice the loop's 0.5 s silence.
HELD_CYCLES = 200
#: The drag's path (pan, tilt deg): from inside the taught region up through its top edge and on
#: to the right, far outside (the region spans about pan -68..43, tilt -33..38).
PATH = [(-18.0, -4.0), (-10.0, 20.0), (0.0, 50.0), (20.0, 60.0), (40.0, 60.0)]


def telemetry_rows(path: Path) -> list[dict]:
    lines = path.read_text().splitlines() if path.exists() else []
    return [json.loads(line) for line in lines if line.endswith("}")]


def goals_logged(path: Path) -> int:
    return len(path.read_text().splitlines()) if path.exists() else 0


def wait_until(condition, message: str, timeout: float = 60.0) -> None:
    """Wait for a condition of the files the session writes (the browser may be frozen)."""
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, message
        time.sleep(0.05)


def held_since(rows: list[dict], start: int) -> int:
    """How many of the last rows after ``start`` held without writing, in a row."""
    count = 0
    for row in reversed(rows[start:]):
        if row["outcome"] != "held" or row["written"]:
            break
        count += 1
    return count


def test_a_page_steers_along_the_edge_a_frozen_page_holds_a_killed_one_ends_well(
    tmp_path,
    capsys,
    model_path,  # noqa: F811
):
    goal_log, telemetry = tmp_path / "goals.jsonl", tmp_path / "telemetry.jsonl"
    options = TeleopOptions(
        model=model_path,
        source="page",
        goal_log=goal_log,
        telemetry=telemetry,
        quiet=True,
        duration=300.0,  # a backstop only: the watcher ends the job with SIGINT
    )
    model = load_model(model_path)
    target = pan_tilt_to_quat(*np.radians(PATH[-1]))
    edge_pan, edge_tilt = np.degrees(quat_to_pan_tilt(model.correct(target)))
    said: list[str] = []
    seen: dict[str, object] = {}

    with open_view(ViewOptions(enabled=True, port=0), said.append) as live, chromium() as page:

        def look() -> None:
            try:
                page.get(live.control_url)
                wait_for(
                    page, lambda d: "you steer the limb" in text_of(d, "control"), "no control"
                )
                wait_for(page, lambda d: text_of(d, "cycles") not in ("-", ""), "not running")
                # the teleop page tells the teleop story: its legend, no guide panel
                assert page.find_element("id", "legend-teleop").is_displayed()
                assert not page.find_element("id", "legend-record").is_displayed()
                assert not page.find_element("id", "guide-panel").is_displayed()

                # drag out through the top edge and along it, and keep the button down there
                drag_on_plane(page, PATH)
                wait_for(
                    page,
                    lambda d: "up" in text_of(d, "words") and "blocked" in text_of(d, "words"),
                    "the edge is not named",
                )
                wait_for(page, lambda d: "upper edge" in text_of(d, "holds"), "no holding edge")
                seen["words"], seen["holds"] = text_of(page, "words"), text_of(page, "holds")
                wait_until(
                    lambda: (
                        (rows := telemetry_rows(telemetry))
                        and rows[-1]["out"] is not None
                        and abs(rows[-1]["out"][0] - edge_pan) < 1.0
                        and abs(rows[-1]["out"][1] - edge_tilt) < 1.0
                    ),
                    "the limb did not reach the edge's nearest point",
                )
                seen["at_edge"] = telemetry_rows(telemetry)[-1]["out"]

                # drag back inside, and freeze the whole browser mid-drag
                ActionChains(page).release().perform()
                drag_on_plane(page, [PATH[-1], (0.0, 10.0), (-10.0, 0.0)], pause_s=0.05)
                pids = browser_pids(page)
                frozen_at = len(telemetry_rows(telemetry))
                for pid in pids:
                    os.kill(pid, signal.SIGSTOP)
                wait_until(
                    lambda: held_since(telemetry_rows(telemetry), frozen_at) >= HELD_CYCLES,
                    "a frozen page did not hold the limb",
                )
                goals = goals_logged(goal_log)
                held_rows = len(telemetry_rows(telemetry))
                wait_until(
                    lambda: len(telemetry_rows(telemetry)) >= held_rows + HELD_CYCLES,
                    "the loop stopped",
                )
                seen["goals_while_frozen"] = goals_logged(goal_log) - goals
                seen["held_while_frozen"] = held_since(telemetry_rows(telemetry), frozen_at)

                # kill it: the limb holds, and the session ends normally
                for pid in pids:
                    os.kill(pid, signal.SIGKILL)
                killed_at = len(telemetry_rows(telemetry))
                wait_until(
                    lambda: held_since(telemetry_rows(telemetry), killed_at) >= HELD_CYCLES,
                    "a killed page did not leave the limb held",
                )
            finally:
                os.kill(os.getpid(), signal.SIGINT)  # Ctrl-C ends the job

        watcher = Watcher(look)
        watcher.start()
        status = run_teleop(options, view=live)
        watcher.result()

    assert status == 0
    # the address that steers was printed once, with the session's key
    printed = capsys.readouterr().err
    assert printed.count(live.control_url) == 1 and "key=" in live.control_url
    assert said == [f"live view: {live.url}"] and "key=" not in live.url
    assert "up" in seen["words"] and "blocked" in seen["words"]
    assert seen["goals_while_frozen"] == 0
    assert seen["held_while_frozen"] >= 2 * HELD_CYCLES
    # every goal the simulator received lies inside the region, up to rounding to ticks
    excursions = goal_log_excursions(goal_log, model)
    print(f"seen {seen}; {len(excursions)} goals, at most {excursions.max():.4f} deg outside")
    assert len(excursions) > 50  # goal packets the simulator logged (a few hundred here)
    assert excursions.max() <= written_tolerance_deg(), excursions.max()
    rows = telemetry_rows(telemetry)
    corrected = [row for row in rows if row["outcome"] == "corrected" and row["written"]]
    assert len(corrected) > 50  # the limb slid along the edge, written pose by pose
    assert seen["at_edge"] == pytest.approx([edge_pan, edge_tilt], abs=1.0)


def test_the_page_source_refuses_no_view_before_anything_opens(model_path):  # noqa: F811
    from limbctl.errors import ConfigError

    options = TeleopOptions(model=model_path, source="page", view=ViewOptions(enabled=False))
    with pytest.raises(ConfigError, match="drop --no-view"):
        run_teleop(options)
