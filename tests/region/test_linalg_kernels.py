import numba
import numpy as np
import pytest

from limbctl.region.linalg_kernels import det, solve


@numba.njit
def _numbas_det(a):
    return np.linalg.det(a)


@numba.njit
def _numbas_solve(a, b):
    return np.linalg.solve(a, b)


def _systems(count):
    """3x3 systems as refine_nodes builds them (weighted sums of (1, x, y) outer products),
    general ones, singular ones and exactly diagonal ones."""
    rng = np.random.default_rng(7)
    for i in range(count):
        rows = np.column_stack([np.ones(5), rng.normal(scale=0.1, size=(5, 2))])
        w = rng.random(5)
        a = (rows * w[:, None]).T @ rows if i % 2 else rng.normal(size=(3, 3))
        if i % 7 == 0:
            a[2] = a[0] - a[1]
        if i % 11 == 0:
            a = np.diag(rng.normal(size=3))
        yield np.ascontiguousarray(a), rng.normal(size=3)


def test_det_and_solve_are_numbas_bit_for_bit_errors_included():
    singular = 0
    for a, b in _systems(3000):
        assert np.float64(det(a)).tobytes() == np.float64(_numbas_det(a)).tobytes()
        try:
            expected = _numbas_solve(a, b)
        except np.linalg.LinAlgError:
            singular += 1
            with pytest.raises(np.linalg.LinAlgError, match="singular"):
                solve(a, b)
            continue
        assert solve(a, b).tobytes() == expected.tobytes()
    assert singular > 0  # the exactly singular systems took the error path
    # non-finite input raises as numba's
    a = np.eye(3)
    a[1, 2] = np.nan
    for call in (lambda: det(a), lambda: solve(a, np.ones(3)), lambda: solve(np.eye(3), a[1])):
        with pytest.raises(np.linalg.LinAlgError, match="infs or NaNs"):
            call()
    with pytest.raises(np.linalg.LinAlgError, match="infs or NaNs"):
        _numbas_det(a)
