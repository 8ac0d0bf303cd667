"""A three-servo record and teleop watched in headless Chromium: the twist band over the swing
plane and the twist gauge draw what the feed says."""

from __future__ import annotations

import json
import math
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from calib.profile import default_sim_profile
from limbctl.envelope import RigidMap
from limbctl.envelope.synthetic_twist import ShoulderRegion
from limbctl.geometry.twist import decompose
from limbctl.jobs import Connection, RecordOptions, TeleopOptions, run_record, run_teleop
from limbctl.live import ViewOptions, open_view
from limbctl.teach.dataset import load_dataset
from limbctl.view.twist import pose_twist
from tests.view.browser import chromium, text_of, wait_for

#: The gauge's needle colour (twist.js GAUGE.twist, #1f5fd0) and the "short" cells' fill.
NEEDLE = (31, 95, 208)
SHORT = (245, 170, 80)
#: Pixels of the gauge's needle: the axis (AXIS.y, 30 px) less 10, on the needle's stroke.
NEEDLE_Y = 20


def js(browser, script: str):
    return browser.execute_script(f"return {script};")


def deg_of(text: str) -> float:
    """``"-12.3 deg"`` -> -12.3."""
    return float(text.split()[0])


def shows(text: str, value: float) -> bool:
    """Whether ``text`` (``"-12.3 deg"``, or its first number) is ``value`` (deg) to the page's
    rounding (0.05 deg, of a value the feed rounded to 0.01 deg)."""
    return abs(deg_of(text) - value) <= 0.05 + 0.005 + 1e-9


def range_shows(text: str, low: float, high: float, of: str) -> bool:
    """Whether ``"low .. high deg (of)"`` shows these limits (deg) to the page's rounding."""
    numbers, words = text.split(" deg ")
    a, b = numbers.split(" .. ")
    return shows(a, low) and shows(b, high) and words == f"({of})"


def twist_deg(pose_deg) -> float:
    """The twist (deg) of a logged (pan, tilt, roll) pose (deg)."""
    return math.degrees(pose_twist(*(math.radians(v) for v in pose_deg)))


def rgb(pixel) -> tuple[int, int, int]:
    return tuple(int(v) for v in pixel[:3])


def cell_colour(page, i: int, j: int) -> tuple[int, int, int]:
    """The colour a cell is painted: the most common of its four corners' (the region's edge,
    drawn over the cells, may cross one or two of them)."""
    corners = [tuple(c) for c in js(page, f"window.limbtwist.cellPixels({i}, {j})")]
    return Counter(corners).most_common(1)[0][0]


def near(a, b, tol: int = 6) -> bool:
    return all(abs(x - y) <= tol for x, y in zip(a, b, strict=True))


def test_a_three_servo_record_shows_the_twist_taught_by_place_and_the_gauge(tmp_path):
    out = tmp_path / "teach.limb"
    with open_view(ViewOptions(enabled=True, port=0), lambda _: None) as live, chromium() as page:
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
        assert text_of(page, "twist-legend").startswith(
            "seen from behind the limb (+pan to the left)"
        )
        # the needle is drawn where the twist lies on the gauge
        x = js(page, f"window.limbtwist.gaugeX({gauge.twist_deg})")
        needle = js(page, f"window.limbtwist.pixel('twist-gauge', {x}, {NEEDLE_Y})")
        assert near(rgb(needle), NEEDLE), needle
        # every cell is painted; a cell still short of a stop in the warning colour
        states = dict(zip(map(tuple, scene.cells[:, :2].astype(int).tolist()), scene.states))
        for (i, j), state in states.items():
            colour = cell_colour(page, i, j)
            if state == "short":
                assert near(colour, SHORT), (i, j, colour)
            elif state == "turned":
                assert colour != (255, 255, 255) and not near(colour, SHORT), (i, j, colour)
        assert "turned" in states.values()
        # the guide says where the twist is untaught, in words and figures
        assert "twist:" in text_of(page, "guide-text")
        assert "twist: turned both ways" in text_of(page, "guide")


@pytest.fixture(scope="module")
def shoulder_model_path(tmp_path_factory):
    """A Rigid Map with twist, learned from a shoulder-like region, for the sim3 rig."""
    path = tmp_path_factory.mktemp("model3") / "model.npz"
    taught = ShoulderRegion().teaching(2500, 1200, 1200, np.random.default_rng(0))
    sim3 = default_sim_profile("sim3")
    metadata = {"rig": sim3.name, "calibration": sim3.calibration.to_dict()}
    RigidMap(twist=True).fit(taught).save(path, metadata=metadata)
    return path


def test_a_three_servo_teleop_shows_the_learned_band_and_the_gauge(tmp_path, shoulder_model_path):
    # a replayed sweep turning the limb far past its band (roll +-120 deg) as it swings
    commands = tmp_path / "commands.jsonl"
    with open(commands, "w", encoding="utf-8") as fh:
        for k in range(300):
            t = k / 100.0
            row = {
                "t": t,
                "pan": 30.0 * math.sin(t),
                "tilt": 20.0 * math.sin(2 * t),
                "roll": 120.0 * math.sin(3 * t),
            }
            fh.write(json.dumps(row) + "\n")
    telemetry = tmp_path / "telemetry.jsonl"
    options = TeleopOptions(
        model=shoulder_model_path,
        source=f"replay:{commands}",
        telemetry=telemetry,
        quiet=True,
        connection=Connection(rig=Path("sim3")),
    )
    with open_view(ViewOptions(enabled=True, port=0), lambda _: None) as live, chromium() as page:
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
        colours = []
        for k in (int(np.argmin(widths)), int(np.argmax(widths))):
            colours.append(cell_colour(page, *(int(v) for v in scene.cells[k, :2])))
        assert widths.max() - widths.min() > 30.0
        assert not near(colours[0], colours[1], tol=40), colours
        x = js(page, f"window.limbtwist.gaugeX({gauge.twist_deg})")
        assert near(
            rgb(js(page, f"window.limbtwist.pixel('twist-gauge', {x}, {NEEDLE_Y})")), NEEDLE
        )
