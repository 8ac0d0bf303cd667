"""The jobs feed the live view: a record and a teleop on the simulator, watched in Chromium."""

from __future__ import annotations

import json
import os
import signal
import socket
import threading
from pathlib import Path

import numpy as np
import pytest

from calib.profile import default_sim_profile
from limbctl.envelope import RigidMap
from limbctl.errors import ConfigError
from limbctl.jobs import Connection, RecordOptions, TeleopOptions, run_record, run_teleop
from limbctl.live import DEFAULT_PORT, TeleopFeed, ViewOptions, guide_figures, open_view
from limbctl.teach.dataset import load_dataset
from limbctl.teach.guide import Guidance
from limbctl.teleop.cycle import Cycle, CycleState
from limbctl.teleop.gate import GateResult, Outcome
from limbctl.view import Board
from tests.view.browser import assert_pose_shown, chromium, text_of, wait_for

DATA = Path(__file__).parent / "data" / "hand_irregular_seed0_20s.limb"


def pose_text(pan_deg: float, tilt_deg: float) -> str:
    return f"{pan_deg:.1f}, {tilt_deg:.1f}"


class Watcher(threading.Thread):
    """Runs ``look(browser)`` beside a job (jobs take signals, so they run in the main thread);
    whatever it raised is raised again by :meth:`result`."""

    def __init__(self, look) -> None:
        super().__init__(name="page-watcher")
        self.look = look
        self.error: BaseException | None = None

    def run(self) -> None:
        try:
            self.look()
        except BaseException as exc:  # handed to the test's thread
            self.error = exc

    def result(self) -> None:
        self.join()
        if self.error is not None:
            raise self.error


@pytest.fixture(scope="module")
def model_path(tmp_path_factory):
    """A Rigid Map trained on a 20 s recording of the simulated rig."""
    path = tmp_path_factory.mktemp("model") / "model.npz"
    sim = default_sim_profile()
    metadata = {"rig": sim.name, "calibration": sim.calibration.to_dict()}
    RigidMap().fit(load_dataset(DATA).quaternions).save(path, metadata=metadata)
    return path


def test_record_job_shows_its_samples_on_the_page(tmp_path):
    out = tmp_path / "teach.limb"
    said: list[str] = []
    with open_view(ViewOptions(enabled=True, port=0), said.append) as live, chromium() as browser:
        assert said == [f"live view: {live.url}"]
        browser.get(live.url)

        def look() -> None:
            wait_for(browser, lambda d: int(text_of(d, "sample-count")) > 50, "no samples shown")
            assert text_of(browser, "mode") == "record"

        watcher = Watcher(look)
        watcher.start()
        status = run_record(
            RecordOptions(out=out, duration=6.0, connection=Connection(seed=2)), view=live
        )
        watcher.result()
        assert status == 0
        data = load_dataset(out)
        wait_for(
            browser,
            lambda d: text_of(d, "sample-count") == str(len(data)),
            f"the page never showed the file's {len(data)} samples",
        )
        assert_pose_shown(text_of(browser, "pose"), (data.pan_deg[-1], data.tilt_deg[-1]))
        assert text_of(browser, "limits") == "pan -115..115, tilt -55..70"
        # the guide's last assessment, as the recorder's summary has it
        wait_for(browser, lambda d: "edge closed" in text_of(d, "guide"), "no guide figures")
        assert "inside covered" in text_of(browser, "guide")
        assert "edge closed" in text_of(browser, "guide-text")


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def test_teleop_job_shows_commanded_and_written_poses(tmp_path, model_path):
    """Commands go in over UDP as the page shows their effect; Ctrl-C (SIGINT) ends the job."""
    port = free_udp_port()
    telemetry = tmp_path / "telemetry.jsonl"
    options = TeleopOptions(
        model=model_path,
        source=f"udp://127.0.0.1:{port}",
        telemetry=telemetry,
        quiet=True,
        duration=120.0,  # a backstop only: the watcher ends the job with SIGINT
    )
    sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)

    def command(pan: float, tilt: float):
        def send_and_look(driver) -> bool:
            sender.sendto(json.dumps({"pan": pan, "tilt": tilt}).encode(), ("127.0.0.1", port))
            return text_of(driver, "commanded") == pose_text(pan, tilt)

        return send_and_look

    with open_view(ViewOptions(enabled=True, port=0), lambda _: None) as live, chromium() as page:
        page.get(live.url)

        def look() -> None:
            try:
                # far outside the taught region: the gate corrects it
                wait_for(page, command(-80.0, -40.0), "the command is not shown")
                wait_for(page, lambda d: text_of(d, "written") != "-", "no written pose shown")
                wait_for(page, lambda d: text_of(d, "outcome").startswith("corrected"), "")
                assert text_of(page, "loop-count") != "0", "the model's region is not drawn"
                assert "rigidmap model" in text_of(page, "region-note")
                # the rate is measured over a second of cycles
                wait_for(page, lambda d: float(text_of(d, "rate").split()[0]) > 20.0, "no rate")
                # inside it
                wait_for(page, command(20.0, 20.0), "the second command is not shown")
            finally:
                # Ctrl-C: the job's handler stops the loop (only once it runs: before, the signal
                # would reach the test runner; the duration is the backstop then)
                if text_of(page, "cycles") not in ("-", ""):
                    os.kill(os.getpid(), signal.SIGINT)

        watcher = Watcher(look)
        watcher.start()
        status = run_teleop(options, view=live)
        watcher.result()
        sender.close()
        assert status == 0
        rows = [json.loads(line) for line in telemetry.read_text().splitlines()]
        last_written = [row for row in rows if row["written"]][-1]
        wait_for(page, lambda d: "ended by stopped" in text_of(d, "note"), "the end is not shown")
        assert_pose_shown(text_of(page, "written"), last_written["out"], logged_digits=4)
        assert text_of(page, "commanded") == pose_text(20.0, 20.0) == pose_text(*rows[-1]["cmd"])
        last_read = [row for row in rows if row["present"] is not None][-1]
        assert_pose_shown(text_of(page, "pose"), last_read["present"], logged_digits=4)


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


def test_teleop_feed_keeps_the_last_written_pose_and_measures_the_rate():
    board = Board()
    feed = TeleopFeed(board)
    feed(cycle(0, 0.0, written=True, pan=0.1))
    for index in range(1, 201):
        feed(cycle(index, index / 200.0, written=False, pan=0.3))
    status = board.live.teleop
    assert status.written.pan_deg == pytest.approx(np.degrees(0.1))
    assert status.commanded.pan_deg == 10.0
    assert status.rate_hz == pytest.approx(200.0)
    assert status.cycles == 200 and status.outcome == "passed"
    assert status.words == "inside: following the command" and status.blocked == ()


def test_teleop_feed_names_the_edge_that_holds_as_the_page_draws_it():
    board = Board()
    feed = TeleopFeed(board)
    # the command lies up and to the +pan side of where the gate keeps writing the same pose
    for index in range(3):
        feed(
            Cycle(
                index=index,
                t=index / 200.0,
                state=CycleState.RUNNING,
                complete=True,
                command_deg=(20.0, 40.0),
                result=GateResult((0.1, 0.2), Outcome.CORRECTED, corrected=True),
                present=(0.1, 0.2),
                written=True,
            )
        )
    status = board.live.teleop
    assert status.blocked == ("+pan", "+tilt")
    # the page's plane is seen from behind the limb, as the terminal names it: +pan is left
    assert status.words == "at the edge: left and up are blocked, holding there"


def test_teleop_feed_says_how_hard_a_felt_leader_pushes_back():
    board = Board()
    feed = TeleopFeed(board)
    pushes = iter([0.0, 0.31])
    feed.push_nm = lambda: next(pushes)
    feed(cycle(0, 0.0, written=True, pan=0.1))
    assert board.live.note == "the leader is free"
    feed(cycle(1, 0.005, written=True, pan=0.1))
    assert board.live.note == "the leader pushes back with 0.31 N m"


def test_guide_figures_say_what_the_guidance_says():
    guidance = Guidance(
        samples=500,
        phase="edge",
        edge_closed=0.625,
        inside_covered=0.25,
        edge_gaps=(),
        inside_gaps=(),
        ready=False,
        centre_deg=(10.0, 5.0),
        spread_deg=20.0,
    )
    figures, advice = guide_figures(guidance)
    shown = {figure.label: (figure.value, figure.unit) for figure in figures}
    assert shown["edge closed"] == (62.5, "%") and shown["inside covered"] == (25.0, "%")
    assert shown["edge gaps"] == (0, "") and shown["inside gaps"] == (0, "")
    assert advice == guidance.line()


def test_view_options_and_ports():
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
