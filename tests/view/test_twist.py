"""The twist the page draws: cells over the swing plane and the present pose's gauge, and a
three-servo record and teleop watched in headless Chromium."""

from __future__ import annotations

import json
import math
from collections import Counter
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from limbctl.envelope import RigidMap, load_model
from limbctl.envelope.synthetic_twist import ShoulderRegion
from limbctl.geometry.gimbal import chain_twist, pan_tilt_roll_scalar
from limbctl.geometry.twist import compose, decompose
from limbctl.jobs import Connection, RecordOptions, TeleopOptions, run_record, run_teleop
from limbctl.live import TeleopFeed, ViewOptions, open_view
from limbctl.teach.dataset import load_dataset
from limbctl.teach.twist_guide import TwistPlace
from limbctl.teleop.gate import GateResult, Outcome
from limbctl.view import Board, Live, PanTilt, Scene
from limbctl.view.feed import PoseTap
from limbctl.view.twist import (
    TwistGauge,
    TwistMap,
    band_gauge,
    model_band_map,
    pose_twist,
    taught_gauge,
    taught_map,
)
from tests.test_live import cycle
from tests.view.browser import near, text_of, wait_for


def test_twist_values_json_maps_and_the_taught_gauge():
    # two servos: no twist keys
    live = Live("record", PanTilt(1.0, 2.0), 3).to_json()
    scene = Scene().to_json()
    assert "twist" not in live and "twist" not in scene
    assert list(live) == ["kind", "mode", "pose", "sample_count", "teleop", "fault", "note"]
    gauge = TwistGauge(12.345, -40.0, 35.0, "taught here")
    out = Live("record", twist=gauge).to_json()["twist"]
    assert out == {"twist": 12.35, "low": -40.0, "high": 35.0, "of": "taught here", "written": None}
    # a twist map finds the cell of a pose and refuses unknown states
    cells = np.array([[0, 0, -30.0, 40.0], [-1, 2, 5.0, 8.0]])
    shown = TwistMap(15.0, cells, ("turned", "short"), "taught")
    assert shown.at(7.0, 14.9) == (-30.0, 40.0, "turned")
    assert shown.at(-0.1, 31.0) == (5.0, 8.0, "short")
    assert shown.at(15.0, 0.0) is None
    assert shown.to_json()["cells"][1] == [-1, 2, 5.0, 8.0, "short"]
    with pytest.raises(ValueError, match="unknown cell states"):
        TwistMap(15.0, cells, ("turned", "maybe"), "taught")
    with pytest.raises(ValueError, match="2 cells but 1 states"):
        TwistMap(15.0, cells, ("turned",), "taught")
    # the taught map says which places lack a stop
    places = (
        TwistPlace(0, 0, -40.0, 40.0, 100, True),
        TwistPlace(1, 0, -2.0, 3.0, 100, False),
        TwistPlace(2, 0, 0.0, 0.0, 5, False),
    )
    shown = taught_map(places, 15.0, 30)
    assert shown.states == ("turned", "short", "few")
    # the gauge reads the range of the pose's cell, and the pose's twist exactly
    pan, tilt, roll = math.radians(20.0), math.radians(5.0), math.radians(10.0)
    gauge = taught_gauge(shown, pan, tilt, roll)
    assert (gauge.low_deg, gauge.high_deg, gauge.of) == (-2.0, 3.0, "taught here")
    # the chain's twist is roll + 2 atan(tan(pan/2) tan(tilt/2))
    assert gauge.twist_deg == pytest.approx(10.0 + math.degrees(chain_twist(pan, tilt)))
    assert taught_gauge(None, pan, tilt, roll).low_deg is None


def test_the_band_gauge_map_feed_and_pose_tap_agree_with_the_region(shoulder_model_path):
    region, model = ShoulderRegion(), load_model(shoulder_model_path)
    band = model.region.band
    rng = np.random.default_rng(1)
    checked = 0
    for q in region.teaching(400, 0, 0, rng):
        d, tau = decompose(q)
        tau_deg = math.degrees(float(tau))
        if not model.region.mesh.contains(np.reshape(d, (1, 3)))[0]:
            continue
        for offset in (-100.0, -30.0, 0.0, 30.0, 100.0):
            p = compose(d, math.radians(tau_deg + offset))
            pose = tuple(float(a) for a in pan_tilt_roll_scalar(p, 0.0, 0.0, -math.pi, math.pi))
            gauge = band_gauge(band, pose, None)
            assert gauge.twist_deg == pytest.approx(math.degrees(decompose(p)[1]), abs=1e-9)
            twist = gauge.twist_deg
            # inside the gauge's range (away from its limits) exactly when the model holds it
            room = min(twist - gauge.low_deg, gauge.high_deg - twist)
            if abs(room) > 0.05:
                assert (room > 0) == bool(model.contains(p)), (pose, gauge)
                checked += 1
    assert checked > 1000
    # the map: cells inside the swing region, each the band at its centre
    shown = model_band_map(model, (-115.0, 115.0), (-55.0, 70.0))
    assert len(shown.cells) > 100 and set(shown.states) == {"band"}
    widths = shown.cells[:, 3] - shown.cells[:, 2]
    tilt = (shown.cells[:, 1] + 0.5) * shown.cell_deg
    # the shoulder's band narrows as the limb rises (75 deg half-width low, 25 high)
    assert np.corrcoef(tilt, widths)[0, 1] < -0.8
    assert model_band_map(RigidMap(), (-1.0, 1.0), (-1.0, 1.0)) is None
    # the teleop feed and the pose tap show the twist
    board = Board()
    feed = TeleopFeed(board)
    feed.band = model.region.band
    present = (math.radians(20.0), math.radians(10.0), math.radians(15.0))
    written = GateResult((present[0], present[1], math.radians(12.0)), Outcome.PASSED)
    feed(replace(cycle(0, 0.0, True), command_deg=(20.0, 10.0), result=written, present=present))
    live = board.live
    assert live.pose.pan_deg == pytest.approx(20.0)
    expected = band_gauge(model.region.band, present, pose_twist(*written.pose))
    assert live.twist == expected and live.twist.written_deg is not None
    # the pose tap shows a new taught range at once, with the last pose
    board = Board()
    pose = (math.radians(20.0), math.radians(5.0), math.radians(10.0))
    tap = PoseTap(SimpleNamespace(read_pose=lambda: pose), board, "record")  # a still limb
    assert tap.read_pose() == pose
    first = board.live.twist
    assert first.low_deg is None and first.of == "nothing taught here yet"
    assert first.twist_deg == pytest.approx(math.degrees(pose_twist(*pose)))
    # the guide's next assessment: the range there shows without waiting for the next read
    places = (TwistPlace(1, 0, -30.0, 45.0, 100, True),)
    tap.set_twist_map(taught_map(places, 15.0, 30))
    shown = board.live
    assert (shown.twist.low_deg, shown.twist.high_deg) == (-30.0, 45.0)
    assert shown.sample_count == 1 and shown.pose.pan_deg == pytest.approx(20.0)


# -- on the page, in headless Chromium ------------------------------------------------------

#: The gauge's needle colour (twist.js GAUGE.twist, #1f5fd0) and the "short" cells' fill.
NEEDLE = (31, 95, 208)
SHORT = (245, 170, 80)
#: Pixels of the gauge's needle: the axis (AXIS.y, 30 px) less 10, on the needle's stroke.
NEEDLE_Y = 20


def js(browser, script: str):
    return browser.execute_script(f"return {script};")


def shows(text: str, value: float) -> bool:
    """Whether ``text``'s first number is ``value`` (deg) to the page's and the feed's rounding."""
    return abs(float(text.split()[0]) - value) <= 0.05 + 0.005 + 1e-9


def range_shows(text: str, low: float, high: float, of: str) -> bool:
    """Whether ``"low .. high deg (of)"`` shows these limits (deg) to the page's rounding."""
    numbers, words = text.split(" deg ")
    a, b = numbers.split(" .. ")
    return shows(a, low) and shows(b, high) and words == f"({of})"


def twist_deg(pose_deg) -> float:
    return math.degrees(pose_twist(*(math.radians(v) for v in pose_deg)))


def cell_colour(page, i: int, j: int) -> tuple[int, int, int]:
    """The most common colour of a cell's four corners (the region's edge may cross some)."""
    corners = [tuple(c) for c in js(page, f"window.limbtwist.cellPixels({i}, {j})")]
    return Counter(corners).most_common(1)[0][0]


def needle_near(page, twist: float) -> bool:
    """Whether the gauge's needle is drawn at ``twist`` (deg)."""
    x = js(page, f"window.limbtwist.gaugeX({twist})")
    return near(js(page, f"window.limbtwist.pixel('twist-gauge', {x}, {NEEDLE_Y})")[:3], NEEDLE, 6)


def test_a_three_servo_record_shows_the_twist_taught_by_place_and_the_gauge(tmp_path, browser):
    out, page = tmp_path / "teach.limb", browser
    with open_view(ViewOptions(enabled=True, port=0), lambda _: None) as live:
        page.get(live.url)
        options = RecordOptions(
            out=out, duration=12.0, connection=Connection(seed=3, rig=Path("sim3"))
        )
        assert run_record(options, view=live) == 0
        data = load_dataset(out)
        wait_for(page, lambda d: text_of(d, "sample-count") == str(len(data)), "not the end")
        board = live.board
        gauge, scene = board.live.twist, board.scene.twist
        assert gauge is not None and scene is not None and len(scene.cells) > 0
        # the gauge's text is the feed's twist, which is the last sample's (from the file)
        wait_for(page, lambda d: js(d, "window.limbtwist.drawnCells()") == len(scene.cells), "")
        assert shows(text_of(page, "twist-now"), gauge.twist_deg)
        last = math.degrees(float(decompose(data.quaternions[-1])[1]))
        assert abs(gauge.twist_deg - last) < 1e-6
        if gauge.low_deg is None:
            assert text_of(page, "twist-range") == gauge.of
        else:
            text = text_of(page, "twist-range")
            assert range_shows(text, gauge.low_deg, gauge.high_deg, gauge.of), (text, gauge)
        assert not js(page, "document.getElementById('twist-panel').hidden")
        assert not js(page, "document.getElementById('twist-figure').hidden")
        # drawn as the plane above it, and it says so
        legend = text_of(page, "twist-legend")
        assert legend.startswith("seen from behind the limb (+pan to the left)"), legend
        assert needle_near(page, gauge.twist_deg), "the needle is not where the twist lies"
        # every cell is painted; a cell still short of a stop in the warning colour
        states = dict(zip(map(tuple, scene.cells[:, :2].astype(int).tolist()), scene.states))
        for (i, j), state in states.items():
            colour = cell_colour(page, i, j)
            if state == "short":
                assert near(colour, SHORT, 6), (i, j, colour)
            elif state == "turned":
                assert colour != (255, 255, 255) and not near(colour, SHORT, 6), (i, j, colour)
        assert "turned" in states.values()
        # the guide says where the twist is untaught, in words and figures
        assert "twist:" in text_of(page, "guide-text")
        assert "twist: turned both ways" in text_of(page, "guide")


def test_a_three_servo_teleop_shows_the_learned_band_and_the_gauge(
    tmp_path, shoulder_model_path, browser
):
    page = browser
    # a replayed sweep turning the limb far past its band (roll +-120 deg) as it swings
    commands = tmp_path / "commands.jsonl"
    t = np.arange(300) / 100.0
    sweep = np.column_stack([t, 30.0 * np.sin(t), 20.0 * np.sin(2 * t), 120.0 * np.sin(3 * t)])
    replayed = [dict(zip(("t", "pan", "tilt", "roll"), map(float, row))) for row in sweep]
    commands.write_text("".join(json.dumps(row) + "\n" for row in replayed))
    telemetry = tmp_path / "telemetry.jsonl"
    options = TeleopOptions(
        model=shoulder_model_path,
        source=f"replay:{commands}",
        telemetry=telemetry,
        quiet=True,
        connection=Connection(rig=Path("sim3")),
    )
    with open_view(ViewOptions(enabled=True, port=0), lambda _: None) as live:
        page.get(live.url)
        assert run_teleop(options, view=live) == 0
        rows = [json.loads(line) for line in telemetry.read_text().splitlines()]
        wait_for(page, lambda d: "ended by" in text_of(d, "note"), "the end is not shown")
        board = live.board
        gauge, scene = board.live.twist, board.scene.twist
        assert scene.of == "band" and len(scene.cells) > 50
        # the gauge: the feed's twist, which is a last pose read's (the telemetry's to 1e-4 deg;
        # the cycle that found the input ended may have read once more)
        assert shows(text_of(page, "twist-now"), gauge.twist_deg)
        read = [twist_deg(row["present"]) for row in rows if row["present"] is not None][-3:]
        assert min(abs(gauge.twist_deg - t) for t in read) < 1e-3, (gauge, read)
        text = text_of(page, "twist-range")
        assert range_shows(text, gauge.low_deg, gauge.high_deg, "the learned band here"), text
        # the twist written: the feed's, a last goal the gate wrote (telemetry)
        assert shows(text_of(page, "twist-written"), gauge.written_deg)
        written = [twist_deg(row["out"]) for row in rows if row["written"]][-3:]
        assert min(abs(gauge.written_deg - t) for t in written) < 1e-3, (gauge, written)
        # the sweep turned past the band: the gate held the twist in it, and the page said so
        words = {row["outcome"] for row in rows}
        assert "corrected" in words
        # the band's picture: every cell painted, wide and narrow cells in different colours
        wait_for(page, lambda d: js(d, "window.limbtwist.drawnCells()") == len(scene.cells), "")
        widths = scene.cells[:, 3] - scene.cells[:, 2]
        ends = (int(np.argmin(widths)), int(np.argmax(widths)))
        colours = [cell_colour(page, *(int(v) for v in scene.cells[k, :2])) for k in ends]
        assert widths.max() - widths.min() > 30.0
        assert not near(colours[0], colours[1], tol=40), colours
        assert needle_near(page, gauge.twist_deg), "the needle is not where the twist lies"
