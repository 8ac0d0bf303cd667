"""Training from a dataset file to a checked model file, and pictures of both."""

import math

import numpy as np
import pytest

from calib.profile import default_sim_profile
from limbctl.envelope import Cone, build_model, load_header, load_model
from limbctl.errors import ConfigError
from limbctl.file_jobs import plot_files
from limbctl.teach.dataset import DatasetWriter
from limbctl.teach.train import train


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


def test_train_cone_from_a_dataset_and_read_it_back(tmp_path):
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


def test_the_model_carries_the_recordings_calibration(tmp_path):
    calibration = default_sim_profile().calibration
    data = write_cone_dataset(tmp_path / "teach.limb", n=50, calibration=calibration)
    summary = train(data, tmp_path / "cone.npz", kind="cone")
    metadata = load_header(tmp_path / "cone.npz")["metadata"]
    assert metadata["calibration"] == calibration.to_dict()
    assert summary.calibration_recorded
    assert not any("calibration" in line for line in summary.lines())

    older = write_cone_dataset(tmp_path / "older.limb", n=50)  # no calibration recorded
    summary = train(older, tmp_path / "older.npz", kind="cone")
    assert "calibration" not in load_header(tmp_path / "older.npz")["metadata"]
    assert not summary.calibration_recorded
    assert summary.lines()[-1].startswith("calibration        NOT RECORDED")


def test_train_rigidmap_contains_its_samples(tmp_path):
    data = write_cone_dataset(tmp_path / "teach.limb", n=300)
    summary = train(data, tmp_path / "rm.npz", kind="rigidmap", options={"nodes": 500})
    assert summary.nodes >= 500
    assert summary.contained_fraction >= 0.95
    # the summary says which edge the gate took, and what that means
    assert summary.edge in ("smooth", "traced", "supported")
    assert any(line.startswith(f"edge               {summary.edge} (") for line in summary.lines())
    png = plot_files([data, tmp_path / "rm.npz"], tmp_path / "rm.png")
    assert png.stat().st_size > 20_000
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_too_few_samples_and_unknown_kinds_are_refused(tmp_path):
    data = write_cone_dataset(tmp_path / "few.limb", n=5)
    with pytest.raises(ConfigError, match="only 5 samples"):
        train(data, tmp_path / "m.npz")
    with pytest.raises(ConfigError, match="choose one of"):
        build_model("kmeans")
    with pytest.raises(ConfigError, match="bad options"):
        build_model("cone", nodes=3)


def test_model_kinds_come_from_one_registry():
    from limbctl.cli import build_parser
    from limbctl.envelope import MODEL_KINDS, RigidMap, model_class
    from limbctl.eval.experiments import build_model as eval_build_model
    from limbctl.eval.grids import ModelSpec
    from limbctl.file_jobs import model_options

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
    with pytest.raises(ConfigError, match="rigidmap, som, cone"):
        eval_build_model(
            ModelSpec(label="k", kind="kmeans", options=(), answers=()), seed=0, range_deg=30.0
        )
    assert isinstance(
        eval_build_model(ModelSpec(label="c", kind="cone", options=(), answers=()), 0, 30.0), Cone
    )
