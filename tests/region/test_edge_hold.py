"""The kept edge is held to the taught evidence where it stands past it (issue 35, finding 1).

A sparse i.i.d. teaching (1500 samples) of an ellipse with a notch: the edge the fit keeps stands
up to 3 deg from every taught sample, and before the hold the region reached 2.42 deg past the
true outline (teaching seed 1). Held, it stays within ``REACH_DEG`` (plus half a station spacing
between stations) of the truth, keeps every taught sample the unheld region held, and still
names the stretches, now as held.
"""

import numpy as np
import pytest

from limbctl.envelope.synthetic import PolygonRegion, reach_into
from limbctl.region import TaughtRegion
from limbctl.region import taught as taught_module
from limbctl.region.edge_hold import hold_to_evidence
from limbctl.region.evidence import REACH_DEG, STATION_DEG, edge_stations
from tests.region.test_evidence import notched_ellipse

#: The scan's own step (deg): a direction of the region lies within half a diagonal of it.
SCAN_DEG = 0.1


@pytest.fixture(scope="module")
def sparse_notch():
    outline, _ = notched_ellipse(27.2, 23.4, (-5.7, 7.2), 273.0, 9.0, 8.0)
    truth = PolygonRegion(outline)
    taught = truth.sample(1500, np.random.default_rng(1))
    lo, hi = outline.min(axis=0) - 4.0, outline.max(axis=0) + 4.0
    return truth, taught, ((lo[0], hi[0]), (lo[1], hi[1]))


def test_a_sparse_teaching_is_held_to_the_evidence(sparse_notch, monkeypatch):
    truth, taught, box = sparse_notch
    region = TaughtRegion().fit(taught)
    reach = reach_into(region.contains, truth, box, step_deg=SCAN_DEG)
    bound = REACH_DEG + 0.5 * STATION_DEG + np.hypot(SCAN_DEG, SCAN_DEG)
    assert region.held_edge and region.unsupported_edge
    assert reach <= bound, f"the held region reaches {reach:.2f} deg past the truth"
    # the report still names the stretches, now held
    assert all(s.held for s in region.unsupported_edge)
    assert "held at the evidence" in region.unsupported_edge[0].line()
    # unheld (as before the hold), the same teaching's region reached farther than the bound
    # and held every taught sample the held region holds
    monkeypatch.setattr(taught_module, "hold_to_evidence", lambda mesh, data: (mesh, False))
    unheld = TaughtRegion().fit(taught)
    assert reach_into(unheld.contains, truth, box, step_deg=SCAN_DEG) > bound
    d = taught_module.taught_directions(taught)
    assert not np.any(unheld.mesh.contains(d) & ~region.mesh.contains(d))


def test_a_region_with_no_far_station_is_returned_as_it_is(sparse_notch):
    """Every station within reach of a sample (the edge's own stations added to the teaching):
    the very same mesh comes back, so a teaching with no unsupported stretch fits as before."""
    _, taught, _ = sparse_notch
    region = TaughtRegion().fit(taught)
    d = taught_module.taught_directions(taught)
    stations, _ = edge_stations(region.mesh, np.radians(STATION_DEG))
    same, held = hold_to_evidence(region.mesh, np.vstack([d, stations]))
    assert same is region.mesh and not held
    # while the teaching alone leaves stations to hold
    _, held = hold_to_evidence(unheld_mesh(taught), d)
    assert held


def unheld_mesh(taught):
    saved = taught_module.hold_to_evidence
    taught_module.hold_to_evidence = lambda mesh, data: (mesh, False)
    try:
        return TaughtRegion().fit(taught).mesh
    finally:
        taught_module.hold_to_evidence = saved
