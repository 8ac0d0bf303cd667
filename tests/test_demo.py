"""The README's main job on the simulator: teach an irregular region by hand, train, teleop a
sweep out of it, judged by the simulator's goal log against the region really taught."""

import json
import re

import numpy as np
import pytest
import yaml
from PIL import Image

from firmware_sim.regions import PolygonRegion as SimPolygon
from limbctl.demo import TRUE_OUTLINE_POINTS, run_demo, true_outline, write_command_stream
from limbctl.envelope.synthetic import PolygonRegion
from limbctl.errors import ConfigError
from limbctl.plot import plot_leader
from limbctl.session import demo_region_path
from limbctl.teach.dataset import load_dataset
from tests.safety.support import packet_directions


def test_teach_train_teleop_keeps_every_goal_in_the_taught_region(tmp_path):
    out = tmp_path / "demo"
    # 30 s: the hand traces the whole edge once (about 24 s), then wanders the middle
    assert run_demo(out, teach_seconds=30.0, seed=0) == 0
    for name in ("teach.limb", "model.npz", "model.png", "teleop.png", "telemetry.jsonl"):
        assert (out / name).stat().st_size > 0, name
    assert len(load_dataset(out / "teach.limb")) >= 3000  # 30 s at >= 100 Hz

    polygon = yaml.safe_load(demo_region_path().read_text())["region"]["polygon"]
    truth = PolygonRegion(polygon_deg=polygon)
    d = packet_directions(out / "goals.jsonl")
    assert len(d) > 500
    depth_deg = np.degrees(truth.depth(d))
    # every goal the servos received lies in the taught region, or within 2 degrees of it
    assert depth_deg.min() >= -2.0, f"a goal {-depth_deg.min():.2f} deg outside the region"
    # the sweep leaves the region, so the gate had to work: it corrected most cycles and many
    # goals sit at the edge (the share near the edge varies with the taught shape: 0.26-0.4)
    assert np.sum(depth_deg < 5.0) >= 100

    rows = [json.loads(x) for x in (out / "telemetry.jsonl").read_text().splitlines()]
    assert np.mean([r["outcome"] == "corrected" for r in rows]) > 0.5
    commanded = np.radians([r["cmd"] for r in rows if r["cmd"] is not None])
    assert np.degrees(np.abs(commanded[:, 0])).max() > 100  # the commands did leave the region


def test_command_stream_has_bad_lines_and_the_demo_refuses_what_it_cannot_run(tmp_path):
    path = tmp_path / "c.jsonl"
    n = write_command_stream(path, seconds=4.0, rate_hz=50.0)
    lines = path.read_text().splitlines()
    assert n == 200 and len(lines) == 204
    pans = [json.loads(x)["pan"] for x in lines if x.startswith('{"t"')]
    assert max(pans) > 100 and min(pans) < -100
    # the demo refuses to overwrite an earlier run, or an unknown rig
    (tmp_path / "teach.limb").write_text("old data")
    with pytest.raises(ConfigError, match="exists"):
        run_demo(tmp_path, teach_seconds=5.0)
    assert (tmp_path / "teach.limb").read_text() == "old data"
    with pytest.raises(ConfigError, match="choose one of sim, sim3"):
        run_demo(tmp_path / "x", rig="sim4")


def test_the_teleop_picture_outlines_the_true_region_and_the_leaders_shows_its_twist(tmp_path):
    outline = true_outline(demo_region_path())
    vertices = np.asarray(yaml.safe_load(demo_region_path().read_text())["region"]["polygon"])
    truth = SimPolygon(vertices.tolist())
    assert outline.shape == (TRUE_OUTLINE_POINTS, 2)
    # every point on the polygon's edge, and the outline spans it (points ~0.7 deg apart)
    assert np.abs(truth.edge_distance_deg(outline[:, 0], outline[:, 1])).max() < 1e-9
    assert np.ptp(outline[:, 0]) == pytest.approx(np.ptp(vertices[:, 0]), abs=1.0)
    assert np.ptp(outline[:, 1]) == pytest.approx(np.ptp(vertices[:, 1]), abs=1.0)
    # the leader picture draws the twist of a three-servo leader
    t = np.linspace(0.0, 1.0, 50)
    poses = np.column_stack([t * 90, t * 0 + 10, t * 60])
    plot_leader(tmp_path / "l3.png", t, poses, np.minimum(poses, 37.0), 0.3 * t)
    plot_leader(tmp_path / "l2.png", t, poses[:, :2], np.minimum(poses[:, :2], 79.0), 0.3 * t)
    assert Image.open(tmp_path / "l3.png").size[1] > Image.open(tmp_path / "l2.png").size[1]


def test_the_three_servo_demo_keeps_every_goal_in_the_learned_region(tmp_path, capsys):
    from limbctl.eval.twist_demo import logged_orientations, twist_excursions, written_orientations
    from limbctl.teleop.gate import written_tolerance_deg

    out = tmp_path / "demo3"
    # 60 s: the hand traces the edge turning the twist to its stops, then wanders (30 s taught
    # too narrow a band for the waiting start)
    assert run_demo(out, teach_seconds=60.0, seed=0, rig="sim3") == 0
    for name in ("teach.limb", "model.npz", "twist.png", "telemetry.jsonl", "goals.jsonl"):
        assert (out / name).stat().st_size > 0, name
    data = load_dataset(out / "teach.limb")
    assert set(data.header.calibration.to_dict()) == {"pan", "tilt", "roll"}
    from limbctl.envelope import load_model

    model = load_model(out / "model.npz")
    assert model.twist
    goals = logged_orientations(out / "goals.jsonl")
    assert len(goals) > 500
    # the stream swings the roll +-150 deg: the goals turn the limb about its axis both ways
    twist = np.degrees(2 * np.arctan2(goals[:, 1], goals[:, 0]))
    assert twist.max() > 10 and twist.min() < -10
    excursion = twist_excursions(
        out / "goals.jsonl", model, written_orientations(out / "telemetry.jsonl")
    )
    assert excursion.max() <= written_tolerance_deg(joints=3)
    # step 5, the felt leader pushed past the edge in swing, then in twist: its picture and its
    # report; or, on a machine too busy for its 200 Hz, the start's refusal
    said = capsys.readouterr().err
    assert "== 5/5 leader" in said
    if "skipped:" in said:
        assert "lower --rate" in said and not (out / "leader.png").exists()
        return
    assert (out / "leader.png").stat().st_size > 0
    assert "(three servos) feels the edge in swing and twist" in said
    pressed = re.search(r"pressed beyond the edge for ([\d.]+) s", said)
    # two presses of about 1.5 s each; or, under 160 Hz (a loaded machine), the push said off
    paced_out = re.search(r"the loop runs at \d+ Hz, under the 200 Hz .* without feel", said)
    assert (pressed and float(pressed[1]) > 1.0) or paced_out, said[-600:]


def test_the_three_servo_leader_run_goes_past_the_true_edge_in_swing_then_in_twist():
    from firmware_sim.hand import Hand
    from limbctl.demo import RIGS
    from limbctl.operators import load_operator

    name, ids, seconds = RIGS["sim3"].leader
    operator = load_operator(name, len(ids))
    script, let_go_s = operator.grip["script"], operator.grip["let_go_s"]

    hand = Hand.from_yaml(demo_region_path().with_name("demo_region3.yaml"))
    region, band = hand.region, hand.band
    points = {tuple(p[1:]) for p in script}
    middle, swing, twist = (0.0, 10.0, 0.0), (100.0, 10.0, 0.0), (0.0, 10.0, 60.0)
    assert points == {middle, swing, twist}
    assert region.contains(*middle[:2]) and abs(middle[2]) < band.limits_deg(*middle[:2])[1]
    # 20 deg past the swing outline's edge (pan 79 at tilt 10), and past the band's edge in
    # twist at a swing well inside (at pan 0 the chain adds no twist: twist = roll)
    assert not region.contains(*swing[:2])
    assert region.edge_distance_deg(np.array([swing[0]]), np.array([swing[1]]))[0] < -15.0
    assert region.contains(*twist[:2]) and twist[2] > band.limits_deg(*twist[:2])[1] + 15.0
    # held at the twist edge before the let go, which leaves time to walk back
    assert script[-1][0] < let_go_s < seconds - 1.0
