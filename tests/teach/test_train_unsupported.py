"""train lists the stretches of the swing edge the taught samples surround but do not reach
(issue 35, finding 1): a region whose shape bridges a notch it cannot carve away says where."""

import numpy as np

from limbctl.envelope import RigidMap
from limbctl.envelope.synthetic import PolygonRegion, to_quaternions
from limbctl.region import RegionParams, taught
from limbctl.teach.train import summarize


def notched_rectangle():
    """A 40 x 30 deg rectangle with a 12 x 12 deg notch in its top edge (pan, tilt deg)."""
    return np.array(
        [[-20, -15], [20, -15], [20, 15], [6, 15], [6, 3], [-6, 3], [-6, 15], [-20, 15]],
        dtype=float,
    )


def test_train_names_where_the_edge_bridges_what_the_samples_surround(monkeypatch):
    truth = PolygonRegion(notched_rectangle())
    q = to_quaternions(truth.sample(8000, np.random.default_rng(0)))
    # a coarse alpha shape bridges the notch; with no carving round the bridge stays, as where
    # carving would drop taught samples, and train must say where
    monkeypatch.setattr(taught, "CARVE_ROUNDS", 0)
    model = RigidMap(nodes=200, seed=0, region=RegionParams(edge="supported", alpha_factor=8.0))
    model.fit(q)
    stretches = model.region.unsupported_edge
    lines = summarize(model, q).lines()
    assert stretches, "the bridged notch must be found"
    assert any(line.startswith("edge unsupported") for line in lines), lines
    named = [line for line in lines if line.strip().startswith("trace the edge near pan")]
    assert len(named) == len(stretches)
    # the farthest stretch lies over the notch (pan -6..6, tilt 3..15)
    assert -8 <= stretches[0].pan_deg <= 8 and 1 <= stretches[0].tilt_deg <= 17
