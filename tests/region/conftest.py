"""The region tests' shared teaching: a 20 deg cone and the region of its supported loop."""

import numpy as np
import pytest

from limbctl.envelope.synthetic import ConeRegion
from limbctl.region.mesh import DirectionMesh
from tests.region.support import circle


@pytest.fixture(scope="session")
def cone20():
    """A supported loop 0.5 deg inside a 20 deg cone, 1000 samples of it and its region."""
    data = ConeRegion(np.radians(20.0)).sample(1000, np.random.default_rng(0))
    loops = [circle(19.5, 120)]
    return loops, data, DirectionMesh.from_loops(loops, np.radians(0.5))
