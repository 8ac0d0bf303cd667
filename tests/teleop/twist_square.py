"""The three-servo leader tests' twist region, fitted once per process from a synthetic square
(pan +-30, tilt +-25 deg) with a +-30 deg twist band: edges near pan 30 and roll 30 deg."""

from __future__ import annotations

import functools

import numpy as np

from limbctl.envelope.synthetic_twist import ShoulderRegion
from limbctl.region.twist_region import TwistRegion

SQUARE = np.array([[-30.0, -25.0], [30.0, -25.0], [30.0, 25.0], [-30.0, 25.0]])


@functools.cache
def square_region() -> TwistRegion:
    """The fitted region (about 20 s on a quiet machine, kernels compiled or cached)."""
    truth = ShoulderRegion(SQUARE, 30.0, 30.0, 0.0, 0.0, 0.0)
    return TwistRegion().fit(truth.teaching(1500, 1000, 1800, np.random.default_rng(0)))
