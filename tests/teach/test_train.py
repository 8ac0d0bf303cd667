"""Training from a dataset file to a checked model file, and pictures of both."""

import math
from dataclasses import replace

import numpy as np
import pytest

from calib.profile import default_sim_profile
from limbctl.envelope import Cone, RigidMap, build_model, load_header, load_model
from limbctl.envelope.synthetic import NOTCH, PolygonRegion, rounded, to_quaternions
from limbctl.errors import ConfigError
from limbctl.file_jobs import model_options, plot_files
from limbctl.geometry.gimbal import direction_to_pan_tilt
from limbctl.geometry.quat import limb_direction, swing_from_direction
from limbctl.geometry.twist import decompose
from limbctl.region import RegionParams
from limbctl.region import taught as taught_region
from limbctl.teach.dataset import DatasetWriter
from limbctl.teach.train import summarize, train
from tests.region.test_twist_evidence import DIP_AT, dipped_teaching


def write_cone_dataset(path, n=400, half_angle_deg=30.0, seed=0, calibration=None):
    rng = np.random.default_rng(seed)
    with DatasetWriter(path, rig="sim", calibration=calibration) as writer:
        for i in range(n):
            # directions uniform over the cap: cos(angle) uniform in [cos R, 1]
            c = rng.uniform(math.cos(math.radians(half_angle_deg)), 1.0)
            az = rng.uniform(-math.pi, math.pi)
            s = math.sqrt(1 - c * c)
            d = np.array([c, s * math.cos(az), s * math.sin(az)])
            writer.append(i * 0.01, math.atan2(d[1], d[0]), math.asin(d[2]))
    return path


def test_train_a_cone_and_a_rigidmap_read_back_plotted_with_the_recordings_calibration(tmp_path):
    data = write_cone_dataset(tmp_path / "teach.limb")
    summary = train(data, tmp_path / "cone.npz", kind="cone")
    assert summary.samples == 400
    assert summary.contained_fraction == 1.0
    assert summary.spread_deg <= 31.0
    model = load_model(tmp_path / "cone.npz")
    assert isinstance(model, Cone)
    assert 28.0 <= model.half_angle_deg <= 30.0
    assert load_header(tmp_path / "cone.npz")["metadata"]["rig"] == "sim"
    assert any("samples inside" in line for line in summary.lines())
    summary = train(data, tmp_path / "rm.npz", kind="rigidmap", options={"nodes": 500})
    assert summary.nodes >= 500
    assert summary.contained_fraction >= 0.95, "a Rigid Map does not contain its samples"
    # the summary says which edge the gate took, and what that means
    assert summary.edge in ("smooth", "traced", "supported")
    assert any(line.startswith(f"edge               {summary.edge} (") for line in summary.lines())
    png = plot_files([data, tmp_path / "rm.npz"], tmp_path / "rm.png")
    assert png.stat().st_size > 20_000
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # the model carries the recording's calibration, and says when there was none
    calibration = default_sim_profile().calibration
    data = write_cone_dataset(tmp_path / "cal.limb", n=50, calibration=calibration)
    summary = train(data, tmp_path / "cal.npz", kind="cone")
    metadata = load_header(tmp_path / "cal.npz")["metadata"]
    assert metadata["calibration"] == calibration.to_dict()
    assert summary.calibration_recorded
    assert not any("calibration" in line for line in summary.lines())
    older = write_cone_dataset(tmp_path / "older.limb", n=50)  # no calibration recorded
    summary = train(older, tmp_path / "older.npz", kind="cone")
    assert "calibration" not in load_header(tmp_path / "older.npz")["metadata"]
    assert not summary.calibration_recorded
    assert summary.lines()[-1].startswith("calibration        NOT RECORDED")


def test_too_few_samples_and_unknown_kinds_are_refused_and_kinds_come_from_one_registry(
    tmp_path,
):
    data = write_cone_dataset(tmp_path / "few.limb", n=5)
    with pytest.raises(ConfigError, match="only 5 samples"):
        train(data, tmp_path / "m.npz")
    with pytest.raises(ConfigError, match="choose one of"):
        build_model("kmeans")
    with pytest.raises(ConfigError, match="bad options"):
        build_model("cone", nodes=3)
    # the kinds come from one registry
    from limbctl.cli import build_parser
    from limbctl.envelope import MODEL_KINDS, model_class
    from limbctl.eval.experiments import build_model as eval_build_model
    from limbctl.eval.grids import ModelSpec

    assert MODEL_KINDS == ("rigidmap", "som", "cone")
    assert model_class("rigidmap") is RigidMap
    train_parser = next(a for a in build_parser()._actions if a.dest == "command").choices["train"]
    kind = next(a for a in train_parser._actions if a.dest == "kind")
    assert tuple(kind.choices) == MODEL_KINDS and kind.default == "rigidmap"
    # options by kind: the seed where the kind takes one, node options for the Rigid Map only
    assert model_options("rigidmap", 7, nodes=50, layout=None) == {"seed": 7, "nodes": 50}
    assert model_options("som", 7, nodes=None, layout=None) == {"seed": 7}
    assert model_options("cone", 7, nodes=None, layout=None) == {}
    with pytest.raises(ConfigError, match="--nodes and --layout apply to --kind rigidmap only"):
        model_options("cone", 0, nodes=50, layout=None)
    kmeans, cone = (ModelSpec(label=k, kind=k, options=(), answers=()) for k in ("kmeans", "cone"))
    with pytest.raises(ConfigError, match="rigidmap, som, cone"):
        eval_build_model(kmeans, seed=0, range_deg=30.0)
    assert isinstance(eval_build_model(cone, 0, 30.0), Cone)


#: A shoulder whose twist band's centre turns with pan (1 deg a deg) and is 20 deg wide either
#: side: past pan +20 deg the band excludes twist 0, though the directions are in the region.
TURNING_BAND = {"half_low_deg": 20.0, "half_high_deg": 20.0, "centre_pan": 1.0, "centre_tilt": 0.0}


@pytest.fixture(scope="module", params=["two servos", "three servos"])
def rig_model(request):
    """(rig, samples (N, 4), fitted Rigid Map) of the shoulder outline: on two servos its
    twist-free directions, on three the shoulder with TURNING_BAND."""
    from limbctl.envelope.synthetic_twist import SHOULDER, ShoulderRegion

    truth = ShoulderRegion(rounded(SHOULDER), centre_deg=0.0, **TURNING_BAND)
    q = truth.teaching(1500, 800, 1200, np.random.default_rng(0))
    three = request.param == "three servos"
    if not three:
        q = swing_from_direction(limb_direction(q))
    return request.param, q, RigidMap(nodes=500, seed=0, twist=three).fit(q)


def test_the_summary_and_the_plot_show_the_whole_region_of_either_rig(rig_model):
    from limbctl.plot import region_grid

    rig, q, model = rig_model
    summary = summarize(model, q)
    # the learned region reaches the taught edge on every side, past where a band leaves twist 0
    for learned, taught in (
        (summary.boundary_pan_range_deg, summary.pan_range_deg),
        (summary.boundary_tilt_range_deg, summary.tilt_range_deg),
    ):
        assert abs(learned[0] - taught[0]) < 2.0 and abs(learned[1] - taught[1]) < 2.0, rig
    # the picture shades the region out to the taught edge on every side too (1.4 deg cells)
    pan, tilt = (np.degrees(a) for a in direction_to_pan_tilt(limb_direction(q)))
    grid_pan, grid_tilt, inside = region_grid(
        model, (pan.min() - 5, pan.max() + 5), (tilt.min() - 5, tilt.max() + 5), n=120
    )
    for shaded, taught in ((grid_pan[inside], pan), (grid_tilt[inside], tilt)):
        assert abs(shaded.min() - taught.min()) < 2.0 and abs(shaded.max() - taught.max()) < 2.0
    out = round((1.0 - summary.contained_fraction) * summary.samples)
    lines = "\n".join(summary.lines())
    if rig == "three servos":
        # the twist over the whole region, and every sample left out counted by why
        taught = np.degrees(decompose(q)[1])
        assert abs(summary.twist_range_deg[0] - taught.min()) < 2.0
        assert abs(summary.twist_range_deg[1] - taught.max()) < 2.0
        assert summary.outside_direction + summary.outside_twist == out
        assert "learned twist" in lines and "twists past the band's limits" in lines
    else:
        assert summary.twist_range_deg is None and summary.outside_direction == out
        assert "twist" not in lines


# ---- what the teaching did not support, named (issue 35) ----------------------------------


def test_train_names_where_the_edge_bridges_what_the_samples_surround(monkeypatch):
    truth = PolygonRegion(NOTCH)  # a 12 x 12 deg notch in the top edge
    q = to_quaternions(truth.sample(8000, np.random.default_rng(0)))
    # a coarse alpha shape bridges the notch; uncarved (as where carving would drop samples)
    monkeypatch.setattr(taught_region, "CARVE_ROUNDS", 0)
    model = RigidMap(nodes=200, seed=0, region=RegionParams(edge="supported", alpha_factor=8.0))
    model.fit(q)
    stretches = model.region.unsupported_edge
    assert stretches, "the bridged notch must be found"
    # the farthest stretch lies over the notch (pan -6..6, tilt 3..15), the region held there
    assert -8 <= stretches[0].pan_deg <= 8 and 1 <= stretches[0].tilt_deg <= 17
    assert model.region.held_edge and stretches[0].held
    # the samples reach the notch's walls, its bridge within their outline: held, not asked
    assert stretches[0].settled
    lines = summarize(model, q).lines()
    assert any(line.startswith("edge held") for line in lines), lines
    assert f"  {stretches[0].line()}" in lines
    # where no outline is read (fewer samples round it) the distance alone decides: asked
    unread = tuple(replace(s, outline_deg=None) for s in stretches)
    model.region.unsupported_edge = unread
    lines = summarize(model, q).lines()
    assert any(line.startswith("edge unsupported") for line in lines), lines
    named = [line for line in lines if line.strip().startswith("trace the edge near pan")]
    settled = [line for line in lines if line.startswith("  near pan")]
    # a stretch held where the learned edge stood near the samples is listed as held, not asked
    assert len(named) == sum(not s.settled for s in unread) > 0
    assert len(settled) == sum(s.settled for s in unread)
    assert "held at the evidence" in named[0]


def test_train_names_the_twist_stop_the_teaching_never_reached():
    _, q = dipped_teaching()
    summary = summarize(RigidMap(twist=True, seed=0).fit(q), q)
    assert summary.unsupported_twist, "the dip's stop was never taught, yet nothing is listed"
    text = "\n".join(summary.lines())
    assert "twist unsupported" in text
    first = next(w for w in summary.unsupported_twist if "upper (positive) twist stop" in w)
    pan = float(first.split("near pan ")[1].split(",")[0])
    tilt = float(first.split("tilt ")[1].split(" ")[0])
    assert abs(pan - DIP_AT[0]) < 16 and abs(tilt - DIP_AT[1]) < 16
    assert f"  {first}" in summary.lines()
