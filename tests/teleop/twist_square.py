"""A twist region for the three-servo leader's tests, fitted once per process.

A synthetic teaching (:class:`limbctl.envelope.synthetic_twist.ShoulderRegion`) of a square swing
outline, pan within +-30 deg and tilt within +-25 deg, with a twist band of +-30 deg about 0
everywhere: the learned edge lies near pan 30 deg in swing and near roll 30 deg in twist.
"""

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
