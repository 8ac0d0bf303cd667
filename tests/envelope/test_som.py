import numpy as np
import pytest

from limbctl.envelope import SOM, Cone, Envelope
from limbctl.envelope.som import table_i_schedule
from limbctl.errors import ConfigError, FileFormatError, InvalidInputError
from limbctl.geometry import quat

X = np.array([1.0, 0.0, 0.0])


def cone_patterns(n, half_angle, seed):
    rng = np.random.default_rng(seed)
    d = quat.normalize(rng.normal(size=(8 * n, 3)))
    d = d[quat.direction_angle(d, X) <= half_angle][:n]
    return quat.swing_from_direction(d)


def sphere_directions(n, seed):
    rng = np.random.default_rng(seed)
    return quat.normalize(rng.normal(size=(n, 3)))


@pytest.fixture(scope="module")
def small_som():
    # Table I's constant sizes: 100 output nodes, 500 training patterns, 90 degree cone
    patterns = cone_patterns(500, np.pi / 2, seed=1)
    return SOM(rows=10, cols=10, seed=2).fit(patterns), patterns


def test_table_i_schedule():
    lr, radii = table_i_schedule(60)
    steps = [0, 9, 10, 20, 30, 40, 59]
    np.testing.assert_array_equal(lr[steps], [1.0, 1.0, 0.5, 0.25, 0.125, 0.0625, 0.0625])
    np.testing.assert_array_equal(radii[steps], [4.0, 4.0, 2.0, 1.0, 0.5, 0.25, 0.25])
    assert len(lr) == len(radii) == 60
    assert SOM().schedule()[0].shape == (10_000,)
    # floors hold when the periods run on
    lr, radii = table_i_schedule(200, periods=20)
    assert lr.min() == 0.02 and radii.min() == pytest.approx(4.0 * 0.5**19)


def test_fit_is_seeded_and_table_i_first_step_overwrites_the_initial_weights():
    patterns = cone_patterns(200, np.radians(60), seed=3)
    a = SOM(rows=6, cols=6, seed=7, lr0=0.8).fit(patterns).weights
    np.testing.assert_array_equal(a, SOM(rows=6, cols=6, seed=7, lr0=0.8).fit(patterns).weights)
    assert not np.array_equal(a, SOM(rows=6, cols=6, seed=8, lr0=0.8).fit(patterns).weights)
    g = SOM(rows=6, cols=6, seed=np.random.default_rng(7), lr0=0.8).fit(patterns).weights
    np.testing.assert_array_equal(a, g)
    # lr(0) = 1 copies each pattern onto its neighbourhood: the initial weights no longer matter
    a = SOM(rows=6, cols=6, seed=7).fit(patterns).weights
    np.testing.assert_array_equal(a, SOM(rows=6, cols=6, seed=8).fit(patterns).weights)


def test_fit_converges_and_the_map_responds_contains_and_corrects(small_som):
    som, patterns = small_som
    assert som.weights.shape == (100, 4)
    assert som.converged and 40 < som.steps < som.max_steps
    # every training pattern is close to some node, and nodes sit on the data (not at init)
    nodes = som.respond(patterns)
    assert np.max(np.linalg.norm(nodes - patterns, axis=1)) == pytest.approx(som.threshold)
    assert np.min(np.linalg.norm(som.weights, axis=1)) > 0.5
    assert som.contains(patterns).all()
    q = quat.swing_from_direction(sphere_directions(300, seed=4))
    out = som.respond(q)
    d2 = np.sum((q[:, None, :] - som.weights[None]) ** 2, axis=2)
    winner = som.weights[np.argmin(d2, axis=1)]
    np.testing.assert_allclose(out, quat.canonical(quat.normalize(winner)), atol=1e-15)
    assert som.respond(q[0]).shape == (4,)
    # node (2, 3) = 23: its 4 edge neighbours on the 10 x 10 grid
    assert sorted(som._grid_topology(4)[23]) == [13, 22, 24, 33]
    q = quat.swing_from_direction(sphere_directions(2000, seed=8))
    inside = som.contains(q)
    # the simple threshold gate agrees with the true cone on most directions
    assert np.mean(inside == Cone(np.pi / 2).contains(q)) > 0.9
    out = som.correct(q)
    assert out[inside].tobytes() == q[inside].tobytes()
    np.testing.assert_allclose(out[~inside], som.respond(q[~inside]), atol=0)
    assert som.contains(out).all()
    assert isinstance(som.contains(q[0]), bool)
    # every interpolation answers unit and canonical (the kernel's own test: tests/envelope/
    # test_interpolation.py)
    for mode in ("idw", "geometric", "geometric-winner", "topological"):
        out = som.respond(q[:200], interpolation=mode, k=4)
        np.testing.assert_allclose(np.linalg.norm(out, axis=1), 1.0, atol=1e-14)
        assert (out[:, 0] >= 0).all()


def test_bad_input_options_and_an_untrained_map_are_refused(small_som):
    som, _ = small_som
    q = quat.swing_from_direction(sphere_directions(4, seed=9))
    q[2, 0] = np.inf
    with pytest.raises(InvalidInputError, match="row 2"):
        som.correct(q)
    with pytest.raises(ConfigError, match="unknown interpolation 'spline'.*geometric"):
        som.respond(q[:1], interpolation="spline")
    with pytest.raises(ConfigError, match="integer >= 1"):
        som.respond(q[:1], interpolation="idw", k=0)
    with pytest.raises(ConfigError, match="empty"):
        SOM().fit(np.empty((0, 4)))
    for call in (SOM(rows=3, cols=3).respond, SOM(rows=3, cols=3).contains):
        with pytest.raises(ConfigError, match="not trained"):
            call(np.array([1.0, 0, 0, 0]))
    with pytest.raises(ConfigError, match="rows must be an integer"):
        SOM(rows=0)
    with pytest.raises(ConfigError, match="lr0 must be"):
        SOM(lr0=float("nan"))
    with pytest.raises(ConfigError, match="above 1"):
        SOM(lr0=1.5)


def test_save_load_round_trip(small_som, tmp_path):
    som, _ = small_som
    path = som.save(tmp_path / "som.npz", metadata={"rig": "sim"})
    back = SOM.load(path)
    assert isinstance(Envelope.load(path), SOM)
    np.testing.assert_array_equal(back.weights, som.weights)
    for name in ("rows", "cols", "threshold", "steps", "converged"):
        assert getattr(back, name) == getattr(som, name), name
    q = quat.swing_from_direction(sphere_directions(100, seed=10))
    np.testing.assert_array_equal(back.correct(q), som.correct(q))
    np.testing.assert_array_equal(back.respond(q, "topological"), som.respond(q, "topological"))
    with pytest.raises(FileFormatError, match="holds a som model, not a cone"):
        Cone.load(path)
    with pytest.raises(ConfigError, match="not trained"):
        SOM().save(tmp_path / "untrained.npz")
