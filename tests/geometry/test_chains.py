"""The chains' geometries: the SO(3) step and distance, and the registry by joint count."""

from __future__ import annotations

import math

import numpy as np
import pytest

from limbctl.errors import ConfigError
from limbctl.geometry import scalar
from limbctl.geometry.chains import Directions, Rotations, chain_geometry, geodesic, toward, turn_by
from limbctl.geometry.gimbal import pose_quat_scalar


def test_the_steps_turn_along_the_shortest_rotation_and_geodesic_measures_it():
    a = pose_quat_scalar(0.0, 0.0, 0.0)
    b = pose_quat_scalar(0.0, 0.0, math.radians(90))
    half = toward(a, b, math.radians(30))
    assert geodesic(a, half) == pytest.approx(math.radians(30), abs=1e-12)
    assert geodesic(half, b) == pytest.approx(math.radians(60), abs=1e-12)
    assert np.array_equal(toward(a, b, math.radians(100)), b)
    past = turn_by(a, b, math.radians(120))  # on past b, along the same rotation
    assert geodesic(a, past) == pytest.approx(math.radians(120), abs=1e-12)
    assert geodesic(b, past) == pytest.approx(math.radians(30), abs=1e-12)
    # the distance is the rotation angle, accurate near 0, either sign of q
    a = pose_quat_scalar(0.3, -0.2, 0.1)
    b = pose_quat_scalar(0.3, -0.2, 0.1 + 1e-9)
    assert geodesic(a, b) == pytest.approx(1e-9, rel=1e-6)  # accurate near 0
    assert geodesic(a, -b) == geodesic(a, b)
    # the directions' step: the great circle, or the target when nearer
    a, b = scalar.direction(0.0, 0.0), scalar.direction(math.radians(50), 0.0)
    assert Directions.toward(a, b, math.radians(60)) is b
    step = Directions.toward(a, b, math.radians(20))
    assert scalar.angle(a, step) == pytest.approx(math.radians(20), abs=1e-12)


def test_the_chain_is_picked_by_its_joint_count():
    assert chain_geometry(2) is Directions and chain_geometry(3) is Rotations
    for joints in (1, 4):
        with pytest.raises(ConfigError, match="2 or 3 joints"):
            chain_geometry(joints)
