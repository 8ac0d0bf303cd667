"""Training from a dataset file to a checked model file, and pictures of both."""

import math

import numpy as np
import pytest

from limbctl.envelope import Cone, load_header, load_model
from limbctl.errors import ConfigError
from limbctl.jobs import _plot_files
from limbctl.teach.dataset import DatasetWriter
from limbctl.teach.train import build_model, train


def write_cone_dataset(path, n=400, half_angle_deg=30.0, seed=0):
    rng = np.random.default_rng(seed)
    with DatasetWriter(path, rig="sim") as writer:
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


def test_train_rigidmap_contains_its_samples(tmp_path):
    data = write_cone_dataset(tmp_path / "teach.limb", n=300)
    summary = train(data, tmp_path / "rm.npz", kind="rigidmap", options={"nodes": 500})
    assert summary.nodes >= 500
    assert summary.contained_fraction >= 0.95
    # the summary says which edge the gate took, and what that means
    assert summary.edge in ("smooth", "traced", "supported")
    assert any(line.startswith(f"edge               {summary.edge} (") for line in summary.lines())
    png = _plot_files([data, tmp_path / "rm.npz"], tmp_path / "rm.png")
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
