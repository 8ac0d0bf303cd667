"""The jobs feed the live view, watched in Chromium: a record, a teleop, a felt leader, and steering
from the page."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import socket
import threading
from dataclasses import replace
from decimal import ROUND_HALF_UP, Decimal
from pathlib import Path

import numpy as np
import pytest
from selenium.webdriver.common.action_chains import ActionChains

from calib.profile import default_sim_profile
from limbctl.demo import goal_log_excursions
from limbctl.envelope import load_model
from limbctl.errors import BusError, ConfigError
from limbctl.geometry.gimbal import pan_tilt_to_quat, quat_to_pan_tilt
from limbctl.jobs import Connection, RecordOptions, TeleopOptions, gate_for, run_record, run_teleop
from limbctl.live import (
    DEFAULT_PORT,
    TeleopFeed,
    ViewOptions,
    guide_figures,
    leader_status,
    open_view,
)
from limbctl.servo.setup import configure_servos
from limbctl.session import open_rig
from limbctl.teach.dataset import load_dataset
from limbctl.teach.guide import Guidance
from limbctl.teleop.cycle import Cycle, CycleState
from limbctl.teleop.gate import GateResult, Outcome, written_tolerance_deg
from limbctl.teleop.loop import LoopConfig, run
from limbctl.teleop.sources import LeaderSource
from limbctl.view import Board, ViewServer
from tests.safety.support import wait_for as poll
from tests.view.browser import (
    LEADER_RGB,
    assert_pose_shown,
    browser_pids,
    chromium,
    drag_on_plane,
    text_of,
    wait_for,
)


def watched(job, look, started=lambda: True) -> int:
    """``job()``'s status, run while a thread runs ``look()`` (raising what it raised), then
    sends SIGINT once ``started()``; a SIGINT outside the job's own handler is dropped."""
    raised: list[BaseException] = []

    def looking() -> None:
        try:
            look()
        except BaseException as exc:
            raised.append(exc)
        finally:
            if started():
                os.kill(os.getpid(), signal.SIGINT)

    previous = signal.signal(signal.SIGINT, lambda signum, frame: None)
    watcher = threading.Thread(target=looking, name="page-watcher")
    try:
        watcher.start()
        status = job()
        watcher.join()
    finally:
        signal.signal(signal.SIGINT, previous)
    if raised:
        raise raised[0]
    return status


#: The first region needs the fit process to start and numba's cached kernels to load.
FIRST_REGION_S = 120.0


def test_record_job_shows_its_samples_on_the_page(tmp_path, browser):
    """The page counts up, draws the region, ends on the file's count and last pose; SIGINT ends."""
    out = tmp_path / "teach.limb"
    said: list[str] = []
    with open_view(ViewOptions(enabled=True, port=0), said.append) as live:
        assert said == [f"live view: {live.url}"]
        browser.get(live.url)

        def look() -> None:
            wait_for(browser, lambda d: int(text_of(d, "sample-count")) > 50, "no samples")
            assert text_of(browser, "mode") == "record"
            first = int(text_of(browser, "sample-count"))
            wait_for(
                browser, lambda d: int(text_of(d, "sample-count")) > first + 100, "count stuck"
            )
            wait_for(
                browser,
                lambda d: text_of(d, "loop-count") not in ("", "0"),
                "no region drawn",
                timeout=FIRST_REGION_S,
            )
            assert "fitted on" in text_of(browser, "region-note"), "not the fitted region"

        options = RecordOptions(out=out, duration=600.0, connection=Connection(seed=2))
        # Ctrl-C once the job records (before, its handler is not installed)
        status = watched(
            lambda: run_record(options, view=live),
            look,
            lambda: text_of(browser, "sample-count") not in ("-", "", "0"),
        )
        assert status == 0
        data = load_dataset(out)
        wait_for(
            browser,
            lambda d: text_of(d, "sample-count") == str(len(data)),
            f"the page never showed the file's {len(data)} samples",
        )
        last = (data.pan_deg[-1], data.tilt_deg[-1])
        assert_pose_shown(text_of(browser, "pose"), last, reads_apart=True)
        assert text_of(browser, "limits") == "pan -115..115, tilt -55..70"
        # the guide's last assessment, as the recorder's summary has it
        wait_for(browser, lambda d: "edge closed" in text_of(d, "guide"), "no guide figures")
        assert "inside covered" in text_of(browser, "guide")
        assert "edge closed" in text_of(browser, "guide-text")


def test_teleop_job_shows_commanded_and_written_poses(tmp_path, hand_model_path, browser):
    """Commands go in over UDP as the page shows their effect; Ctrl-C (SIGINT) ends the job."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:  # a free port
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    telemetry = tmp_path / "telemetry.jsonl"
    options = TeleopOptions(
        model=hand_model_path,
        source=f"udp://127.0.0.1:{port}",
        telemetry=telemetry,
        quiet=True,
        duration=120.0,  # a backstop: the watcher ends the job with SIGINT
    )
    sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)

    def command(pan: float, tilt: float):
        def send_and_look(driver) -> bool:
            sender.sendto(json.dumps({"pan": pan, "tilt": tilt}).encode(), ("127.0.0.1", port))
            return text_of(driver, "commanded") == f"{pan:.1f}, {tilt:.1f}"

        return send_and_look

    page = browser
    with open_view(ViewOptions(enabled=True, port=0), lambda _: None) as live:
        page.get(live.url)

        def look() -> None:
            # far outside the taught region: the gate corrects it
            wait_for(page, command(-80.0, -40.0), "the command is not shown")
            wait_for(page, lambda d: text_of(d, "written") != "-", "no written pose shown")
            wait_for(page, lambda d: text_of(d, "outcome").startswith("corrected"), "")
            assert text_of(page, "loop-count") != "0", "the model's region is not drawn"
            assert "rigidmap model" in text_of(page, "region-note")
            wait_for(page, lambda d: float(text_of(d, "rate").split()[0]) > 20.0, "no rate")
            wait_for(page, command(20.0, 20.0), "the second command is not shown")

        status = watched(
            lambda: run_teleop(options, view=live),
            look,
            lambda: text_of(page, "cycles") not in ("-", ""),
        )
        sender.close()
        assert status == 0
        rows = [json.loads(line) for line in telemetry.read_text().splitlines()]
        last_written = [row for row in rows if row["written"]][-1]
        wait_for(page, lambda d: "ended by stopped" in text_of(d, "note"), "the end is not shown")
        assert_pose_shown(text_of(page, "written"), last_written["out"], logged_digits=4)
        assert (
            text_of(page, "commanded") == "20.0, 20.0" == "{:.1f}, {:.1f}".format(*rows[-1]["cmd"])
        )
        last_read = [row for row in rows if row["present"] is not None][-1]
        assert_pose_shown(text_of(page, "pose"), last_read["present"], 4, reads_apart=True)


def cycle(index: int, t: float, written: bool, pan: float = 0.1) -> Cycle:
    return Cycle(
        index=index,
        t=t,
        state=CycleState.RUNNING,
        complete=True,
        command_deg=(10.0, 5.0),
        result=GateResult((pan, 0.2), Outcome.PASSED),
        present=(0.0, 0.0),
        written=written,
    )


def test_teleop_feed_keeps_the_last_written_pose_names_the_edge_and_the_leaders_push():
    board = Board()
    feed = TeleopFeed(board)
    pushes = iter([0.0, 0.31])
    feed.push_nm = lambda: next(pushes, 0.0)
    feed(cycle(0, 0.0, written=True, pan=0.1))
    assert board.live.note == "the leader is free", "a free leader not said"
    feed(cycle(1, 0.005, written=False, pan=0.3))
    assert board.live.note == "the leader pushes back with 0.31 N m", "the push not said"
    for index in range(2, 201):
        feed(cycle(index, index / 200.0, written=False, pan=0.3))
    status = board.live.teleop
    assert status.written.pan_deg == pytest.approx(np.degrees(0.1)), "not the last written pose"
    assert status.commanded.pan_deg == 10.0
    assert status.rate_hz == pytest.approx(200.0), "the rate over a second of cycles"
    assert status.cycles == 200 and status.outcome == "passed"
    assert status.words == "inside: following the command" and status.blocked == ()
    # a two-servo feed has no band and shows no twist
    assert board.live.twist is None and "twist" not in board.live.to_json()
    # the command lies up and to the +pan side of where the gate keeps writing the same pose
    result = GateResult((0.1, 0.2), Outcome.CORRECTED, corrected=True)
    for index in range(201, 204):
        at_edge = replace(cycle(index, index / 200.0, written=True), result=result)
        feed(replace(at_edge, command_deg=(20.0, 40.0), present=(0.1, 0.2)))
    status = board.live.teleop
    assert status.blocked == ("+pan", "+tilt"), "the edge that holds not named"
    # the page's plane is seen from behind the limb, as the terminal names it: +pan is left
    assert status.words == "at the edge: left and up are blocked, holding there"
    # the guide's figures say what the guidance says
    # 500 samples tracing the edge: 62.5 % of it closed, a quarter of the inside covered
    guidance = Guidance(500, "edge", 0.625, 0.25, (), (), False, (10.0, 5.0), 20.0)
    figures, advice = guide_figures(guidance)
    shown = {figure.label: (figure.value, figure.unit) for figure in figures}
    assert shown["edge closed"] == (62.5, "%") and shown["inside covered"] == (25.0, "%")
    assert shown["edge gaps"] == (0, "") and shown["inside gaps"] == (0, "")
    assert advice == guidance.line()


def test_view_options_and_ports_and_the_page_source_needs_the_view(hand_model_path):
    assert ViewOptions(enabled=False).wanted() is False
    with open_view(ViewOptions(enabled=False), lambda _: None) as off:
        assert not off.active and off.teleop_observer(None, None) is None
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        # a port asked for and taken: refused, saying what to do
        with pytest.raises(ConfigError, match="--view-port"):
            with open_view(ViewOptions(enabled=True, port=port), lambda _: None):
                pass
    # the default port taken (by this test or anyone): any free port instead
    with socket.socket() as default:
        try:
            default.bind(("127.0.0.1", DEFAULT_PORT))
            default.listen()
        except OSError:
            pass  # already taken by someone else: the same case
        with open_view(ViewOptions(enabled=True), lambda _: None) as live:
            assert live.active and not live.url.endswith(f":{DEFAULT_PORT}/")
    # the page source refuses --no-view before anything opens
    options = TeleopOptions(model=hand_model_path, source="page", view=ViewOptions(enabled=False))
    with pytest.raises(ConfigError, match="drop --no-view"):
        run_teleop(options)


# -- a felt leader on the page ------------------------------------------------------------------

IDS = (3, 4)
EDGE = 30.0
#: The operator means to go 20 deg past the edge and stays there (a relaxed 0.3 N m hand).
PRESS = {"script": [[0.0, 0.0, 0.0], [1.5, EDGE + 20.0, 0.0]], "max_torque_nm": 0.3}
#: What the page received last, what it shows, and the leader diamond's pixel, read at once.
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


def js_fixed(values, digits: int) -> str:
    """``values`` as JavaScript's ``toFixed(digits)`` writes them (0.125 -> "0.13")."""
    step = Decimal(1).scaleb(-digits)
    return ", ".join(
        ("-" if v < 0 else "") + str(abs(Decimal(v)).quantize(step, ROUND_HALF_UP)) for v in values
    )


def test_the_page_shows_the_felt_leader_beside_the_follower_and_how_hard_it_pushes(
    cone_file, browser
):
    cone, sim = cone_file(EDGE), default_sim_profile()
    board = Board()
    feed, published = TeleopFeed(board), []

    def on_cycle(cycle) -> None:  # the page's feed, keeping all it published
        feed(cycle)
        published.append(board.live.to_json())

    leader = {"ids": list(IDS), "model": "xm430-w350"}
    # the page loads first: loading takes the CPU the simulator needs to answer the set-up
    with ViewServer(board, port=0) as server:
        browser.get(server.url)
        wait_for(browser, lambda d: text_of(d, "connection") == "live", "the page did not connect")
        with open_rig(extra_ids=IDS, sim_options={"leader": leader}) as session:
            rig = session.rig
            limits = {**rig.tick_limits(), **dict.fromkeys(IDS, (0, 4095))}
            try:
                configure_servos(rig.bus, limits)
            except BusError:  # a starved machine may garble a set-up read-back: not tested here
                configure_servos(rig.bus, limits)
            # checked against 25 Hz: a busy machine's loop (30-40 Hz) keeps the feel on
            source = LeaderSource(rig, IDS, rate_hz=25.0)
            stop = threading.Event()
            with source:
                feed.leader = leader_status(source)
                rig.set_torque(True)
                gate = gate_for(cone, sim, 200.0, 120.0)
                config = LoopConfig(on_cycle=on_cycle)
                thread = threading.Thread(target=lambda: run(rig, gate, source, config, stop=stop))
                thread.start()
                try:
                    session.simulator.set_operator(PRESS)

                    def pushing(driver):
                        shown = driver.execute_script(SHOWN)
                        drawn = shown and tuple(shown["rgb"]) == LEADER_RGB
                        return shown if drawn and shown["leader"]["torque_nm"] > 0.0 else None

                    shown = wait_for(browser, pushing, "the page never showed the leader pushing")
                finally:
                    stop.set()
                    thread.join(timeout=10.0)
    leader_part = shown["leader"]
    # what the page shows is what the feed published in one cycle, with that cycle's follower
    together = [live["pose"] for live in published if live["leader"] == leader_part]
    assert together, f"the page's {leader_part} was never published"
    assert shown["follower"] in together
    # the readouts say those values, as JavaScript rounds them (0.125 -> "0.13")
    assert shown["pose"] == js_fixed(leader_part["pose"], 1)
    torque, cap = leader_part["torque_nm"], leader_part["cap_nm"]
    sensed = leader_part["sensed_nm"]  # the motors' torque as read, beside the push allowed
    push = f"{js_fixed([torque], 2)} N m (cap {js_fixed([cap], 2)} N m)"
    assert shown["push"] == f"{push}, sensed {js_fixed([sensed], 2)} N m"
    assert 0.0 <= sensed <= cap + 0.01
    assert shown["state"] == "pushing back"
    assert tuple(shown["rgb"]) == LEADER_RGB  # the leader's diamond where it is
    # the leader is past the edge and the follower is not; the push is within the cap
    assert leader_part["pose"][0] > EDGE and leader_part["beyond_deg"] > 0.4
    assert 0.0 < leader_part["torque_nm"] <= leader_part["cap_nm"] <= 0.4
    assert leader_part["toward"][0] < leader_part["pose"][0]  # pushed back toward the region
    assert all(live["leader"]["cap_nm"] == leader_part["cap_nm"] for live in published)


def test_a_teleop_job_with_a_passive_leader_shows_it_and_says_it_cannot_push(
    tmp_path, hand_model_path, browser
):
    """``--source leader:3,4`` on the embedded simulator (XL430s, no current sensing): passive."""
    options = TeleopOptions(model=hand_model_path, source="leader:3,4", quiet=True, duration=3.0)
    page = browser
    with open_view(ViewOptions(enabled=True, port=0), lambda _: None) as live:
        page.get(live.url)
        assert run_teleop(options, view=live) == 0
        wait_for(page, lambda d: "ended by duration" in text_of(d, "note"), "the end not shown")
        wait_for(page, lambda d: tuple(d.execute_script(SHOWN)["rgb"]) == LEADER_RGB, "no diamond")
        shown = page.execute_script(SHOWN)
    assert shown is not None, "no leader drawn"
    assert shown["push"] == "passive: it cannot push"
    assert "senses no current" in shown["state"]
    assert shown["leader"]["cap_nm"] is None and shown["leader"]["torque_nm"] == 0.0
    assert shown["pose"] == js_fixed(shown["leader"]["pose"], 1)
    assert tuple(shown["rgb"]) == LEADER_RGB


# -- steering from the page ---------------------------------------------------------------------

#: Cycles in a row holding, no goal written, for a frozen page to count as held (1 s at 200 Hz).
HELD_CYCLES = 200
#: The drag's path (pan, tilt deg): from inside the region (pan -68..43, tilt -33..38) up through
#: its top edge and on to the right, far outside.
PATH = [(-18.0, -4.0), (-10.0, 20.0), (0.0, 50.0), (20.0, 60.0), (40.0, 60.0)]


def telemetry_rows(path: Path) -> list[dict]:
    lines = path.read_text().splitlines() if path.exists() else []
    return [json.loads(line) for line in lines if line.endswith("}")]


def goals_logged(path: Path) -> int:
    return len(path.read_text().splitlines()) if path.exists() else 0


def held_since(rows: list[dict], start: int) -> int:
    """Cycles in a row from ``start`` up to the last holding the limb, no goal written."""
    held = [row["outcome"] == "held" and not row["written"] for row in rows[start:]]
    return ([False, *held][::-1]).index(False)


def wait_held(telemetry: Path, start: int, what: str) -> None:
    """Wait until the limb was held :data:`HELD_CYCLES` cycles in a row since row ``start``."""
    poll(lambda: held_since(telemetry_rows(telemetry), start) >= HELD_CYCLES, 60.0, what)


def test_a_page_steers_along_the_edge_a_frozen_page_holds_a_killed_one_ends_well(
    tmp_path, capsys, hand_model_path
):
    goal_log, telemetry = tmp_path / "goals.jsonl", tmp_path / "telemetry.jsonl"
    options = TeleopOptions(
        model=hand_model_path,
        source="page",
        goal_log=goal_log,
        telemetry=telemetry,
        quiet=True,
        duration=300.0,  # a backstop: the watcher ends the job with SIGINT
    )
    model = load_model(hand_model_path)
    target = pan_tilt_to_quat(*np.radians(PATH[-1]))
    edge_pan, edge_tilt = np.degrees(quat_to_pan_tilt(model.correct(target)))
    said: list[str] = []
    seen: dict[str, object] = {}

    with open_view(ViewOptions(enabled=True, port=0), said.append) as live, chromium() as page:

        def look() -> None:
            page.get(live.control_url)
            wait_for(page, lambda d: "you steer the limb" in text_of(d, "control"), "no control")
            wait_for(page, lambda d: text_of(d, "cycles") not in ("-", ""), "not running")
            # drag out through the top edge and along it, and keep the button down there
            drag_on_plane(page, PATH)
            wait_for(
                page,
                lambda d: "up" in text_of(d, "words") and "blocked" in text_of(d, "words"),
                "the edge is not named",
            )
            wait_for(page, lambda d: "upper edge" in text_of(d, "holds"), "no holding edge")
            seen["words"], seen["holds"] = text_of(page, "words"), text_of(page, "holds")
            poll(
                lambda: (
                    (rows := telemetry_rows(telemetry))
                    and rows[-1]["out"] is not None
                    and abs(rows[-1]["out"][0] - edge_pan) < 1.0
                    and abs(rows[-1]["out"][1] - edge_tilt) < 1.0
                ),
                60.0,
                "the limb did not reach the edge's nearest point",
            )
            seen["at_edge"] = telemetry_rows(telemetry)[-1]["out"]

            # drag back inside, and freeze the whole browser mid-drag
            ActionChains(page).release().perform()
            drag_on_plane(page, [PATH[-1], (0.0, 10.0), (-10.0, 0.0)], pause_s=0.05)
            pids = browser_pids(page)
            frozen_at = len(telemetry_rows(telemetry))
            for pid in pids:  # a process that ended since the listing is passed over
                with contextlib.suppress(ProcessLookupError):
                    os.kill(pid, signal.SIGSTOP)
            wait_held(telemetry, frozen_at, "a frozen page did not hold the limb")
            goals = goals_logged(goal_log)
            held_rows = len(telemetry_rows(telemetry))
            more = held_rows + HELD_CYCLES
            poll(lambda: len(telemetry_rows(telemetry)) >= more, 60.0, "the loop stopped")
            seen["goals_while_frozen"] = goals_logged(goal_log) - goals
            seen["held_while_frozen"] = held_since(telemetry_rows(telemetry), frozen_at)

            # kill it: the limb holds, and the session ends normally
            for pid in pids:
                with contextlib.suppress(ProcessLookupError):
                    os.kill(pid, signal.SIGKILL)
            killed_at = len(telemetry_rows(telemetry))
            wait_held(telemetry, killed_at, "a killed page did not leave the limb held")

        status = watched(lambda: run_teleop(options, view=live), look)

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
