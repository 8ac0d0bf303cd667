import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from limbctl.envelope.base import Envelope
from limbctl.envelope.cone import Cone
from limbctl.errors import ConfigError, FileFormatError, InvalidInputError
from limbctl.geometry import quat
from limbctl.geometry.twist import decompose
from tests.geometry.test_quat import random_unit
from tests.region.support import circle

Z = np.array([0.0, 0.0, 1.0])
X = np.array([1.0, 0.0, 0.0])


def test_hand_cases_move_the_swing_to_the_circle_keep_the_twist_and_keep_inside_bits():
    cone = Cone(half_angle_deg=45)
    q = quat.from_axis_angle(Z, np.pi / 2)
    assert not cone.contains(q)
    out = cone.correct(q)
    assert out.shape == (4,)
    np.testing.assert_allclose(out, quat.from_axis_angle(Z, np.pi / 4), atol=1e-15)
    assert cone.contains(out), "90 deg about z in a 45 deg cone: 45 deg about z"
    cone = Cone(np.radians(60))
    q = quat.swing_from_direction(quat.normalize(np.array([[1.0, 0.3, -0.2], [1.0, 0.0, 0.5]])))
    assert cone.contains(q).all()
    out = cone.correct(q)
    assert out.tobytes() == q.tobytes() and out is not q, "inside: a copy, bit for bit"
    cone = Cone(np.radians(30))
    q = quat.canonical(
        quat.multiply(quat.from_axis_angle(Z, np.radians(100)), quat.from_axis_angle(X, 1.1))
    )
    d_out, tau_out = decompose(cone.correct(q))
    assert float(tau_out) == pytest.approx(1.1, abs=1e-12), "the twist is kept"
    np.testing.assert_allclose(
        d_out, quat.rotate(quat.from_axis_angle(Z, np.radians(30)), X), atol=1e-14
    )
    assert quat.swing_angle(cone.correct(q)) == pytest.approx(np.radians(30), abs=1e-12)
    # a half turn about (0, .6, .8): the limb along -x has no twist and is still corrected
    cone = Cone(half_angle_deg=90)
    out = cone.correct(np.array([0.0, 0.0, 0.6, 0.8]))
    assert quat.swing_angle(out) == pytest.approx(np.pi / 2) and cone.contains(out)


def test_twist_free_input_goes_to_the_nearest_direction_on_the_circle():
    rng = np.random.default_rng(4)
    R = np.radians(50)
    cone = Cone(R)
    d = quat.normalize(rng.normal(size=(500, 3)))
    q = quat.swing_from_direction(d)
    out = cone.correct(q)
    d_out = quat.limb_direction(out)
    outside = quat.direction_angle(d, X) > R
    # on the circle of angle R about +x ...
    np.testing.assert_allclose(quat.direction_angle(d_out[outside], X), R, atol=1e-12)
    # ... at the point nearest the input (same azimuth about +x): dense search over the circle
    ring = circle(50.0, 20000)
    for di, do in zip(d[outside][:50], d_out[outside][:50], strict=True):
        best = quat.direction_angle(ring, di).min()
        assert quat.direction_angle(do, di) == pytest.approx(best, abs=1e-6)
    np.testing.assert_allclose(out[:, 1], 0.0, atol=1e-15, err_msg="twist-free in, twist-free out")


@settings(max_examples=200, deadline=None)
@given(
    q=st.lists(st.floats(-1, 1, allow_nan=False), min_size=4, max_size=4).filter(
        lambda v: np.linalg.norm(v) > 1e-3
    ),
    r_deg=st.floats(1.0, 179.0),
)
@example(q=[2.2250738585e-313, 2.2250738585e-313, 0.0, 1.0], r_deg=1.0)  # subnormal twist
@example(q=[0.0, 5e-324, 0.0, 1.0], r_deg=1.0)
def test_correct_lands_on_boundary_and_is_idempotent(q, r_deg):
    q = quat.canonical(quat.normalize(np.array(q)))
    cone = Cone(half_angle_deg=r_deg)
    out = cone.correct(q)
    assert cone.contains(out)
    np.testing.assert_allclose(np.linalg.norm(out), 1.0, atol=1e-14)
    assert out[0] >= 0
    np.testing.assert_array_equal(cone.correct(out), out)
    if not cone.contains(q):
        assert quat.swing_angle(out) == pytest.approx(np.radians(r_deg), abs=1e-7)


def test_correction_is_the_nearest_boundary_point_in_r4_and_contains_the_swing_angle():
    cone = Cone(np.radians(40))
    q = random_unit(300, seed=5)
    out = cone.correct(q[~cone.contains(q)])
    # sample the boundary densely: (c cos a, c sin a, s cos b, s sin b)
    c, s = np.cos(np.radians(20)), np.sin(np.radians(20))
    a, b = np.meshgrid(np.linspace(0, 2 * np.pi, 400), np.linspace(0, 2 * np.pi, 400))
    boundary = np.stack([c * np.cos(a), c * np.sin(a), s * np.cos(b), s * np.sin(b)], -1)
    boundary = boundary.reshape(-1, 4)
    for qi, oi in zip(q[~cone.contains(q)][:20], out[:20], strict=True):
        best = np.min(np.linalg.norm(boundary - qi, axis=1))
        assert np.linalg.norm(oi - qi) <= best + 1e-9
    # contains is the swing angle's test
    q = random_unit(2000, seed=6)
    for r_deg in (10, 90, 170):
        cone = Cone(half_angle_deg=r_deg)
        inside = cone.contains(q)
        np.testing.assert_array_equal(inside, quat.swing_angle(q) <= np.radians(r_deg))
    assert Cone(np.pi).contains(q).all()


def test_bad_input_options_and_half_angles_are_refused():
    cone = Cone(np.radians(35))
    q = random_unit(50, seed=7)
    np.testing.assert_array_equal(cone.respond(q, interpolation="geometric", k=3), cone.correct(q))
    with pytest.raises(ConfigError, match="unknown interpolation 'cubic'.*none, idw"):
        cone.respond(q, interpolation="cubic")
    with pytest.raises(ConfigError, match="integer >= 1"):
        cone.respond(q, k=0)
    q = random_unit(5)
    q[3, 2] = np.nan
    with pytest.raises(InvalidInputError, match="row 3"):
        cone.correct(q)
    with pytest.raises(ValueError, match="row 0 has norm"):
        cone.contains(np.array([[1.0, 1.0, 0.0, 0.0]]))
    with pytest.raises(ConfigError, match=r"\[0, pi\]"):
        Cone(4.0)
    with pytest.raises(ConfigError, match="not both"):
        Cone(1.0, half_angle_deg=30)
    with pytest.raises(ConfigError, match="finite"):
        Cone(half_angle_deg=float("nan"))
    assert Cone(half_angle_deg=90).half_angle == pytest.approx(np.pi / 2)


def test_fit_without_half_angle_learns_the_max_swing_and_saved_weights_are_empty(tmp_path):
    rng = np.random.default_rng(8)
    d = quat.normalize(rng.normal(size=(400, 3)))
    d = d[quat.direction_angle(d, X) < np.radians(70)]
    q = quat.swing_from_direction(d)
    cone = Cone().fit(q)
    assert cone.half_angle == pytest.approx(quat.swing_angle(q).max())
    assert cone.contains(q).all()
    with pytest.raises(ConfigError, match="no half angle yet"):
        Cone().contains(q)
    fixed = Cone(0.3)
    assert fixed.fit(q) is fixed and fixed.half_angle == 0.3
    with pytest.raises(ConfigError, match="empty"):
        Cone().fit(np.empty((0, 4)))
    # no weights; the half angle saved and loaded
    cone = Cone(half_angle_deg=42.5)
    assert cone.weights.shape == (0, 4)
    path = cone.save(tmp_path / "cone.npz")
    back = Cone.load(path)
    assert isinstance(back, Cone) and back.half_angle == cone.half_angle
    assert isinstance(Envelope.load(path), Cone)
    q = random_unit(100, seed=9)
    np.testing.assert_array_equal(back.correct(q), cone.correct(q))
    path.write_bytes(path.read_bytes()[:40])
    with pytest.raises(FileFormatError):
        Cone.load(path)
