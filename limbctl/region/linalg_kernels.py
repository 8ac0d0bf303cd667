"""``np.linalg.det`` and ``np.linalg.solve`` of small float64 systems, for kernels: numba's
LAPACK calls (``dgetrf``, ``dgesv``) bit for bit, without seconds of compiling per caller."""

from __future__ import annotations

import numpy as np
from numba.core import types
from numba.np import linalg

from limbctl.geometry.jit import njit

linalg.ensure_lapack()
_GETRF = linalg._LAPACK().numba_xxgetrf(types.float64)
_GESV = linalg._LAPACK().numba_xgesv(types.float64)
#: LAPACK's type letter for float64 (``d``), as numba's bindings take it.
_KIND = ord("d")


@njit
def _fortran_copy(a):
    """A copy (n, n) of ``a`` (n, n) whose memory is ``a`` in column-major order."""
    n = a.shape[0]
    out = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            if not np.isfinite(a[i, j]):
                raise np.linalg.LinAlgError("Array must not contain infs or NaNs.")
            out[j, i] = a[i, j]
    return out


@njit
def det(a) -> float:
    """Determinant of ``a`` (n, n) float64, as numba's ``np.linalg.det``: the sign of the LU
    pivots times ``exp`` of the sum of the logs of the LU diagonal's magnitudes."""
    n = a.shape[0]
    lu = _fortran_copy(a)
    ipiv = np.empty(n, dtype=np.int32)
    if _GETRF(_KIND, n, n, lu.ctypes, n, ipiv.ctypes) > 0:
        return 0.0  # singular: numba's (0, -inf) gives 0.0 * exp(-inf)
    sgn = 1
    for k in range(n):
        sgn = sgn + (ipiv[k] != (k + 1))
    sgn = sgn & 1
    if sgn == 0:
        sgn = -1
    acc = 0.0
    for k in range(n):
        v = lu[k, k]  # lu holds the factors column-major: its [k, k] is the diagonal either way
        if v < 0.0:
            sgn = -sgn
            v = -v
        acc = acc + np.log(v)
    return (sgn + 0.0) * np.exp(acc)


@njit
def solve(a, b):
    """Solution (n,) of ``a x = b`` for ``a`` (n, n), ``b`` (n,) float64, as numba's
    ``np.linalg.solve`` (LAPACK ``dgesv``, one right-hand side)."""
    n = a.shape[0]
    lu = _fortran_copy(a)
    x = np.empty(n)
    for i in range(n):
        if not np.isfinite(b[i]):
            raise np.linalg.LinAlgError("Array must not contain infs or NaNs.")
        x[i] = b[i]
    ipiv = np.empty(n, dtype=np.int32)
    if _GESV(_KIND, n, 1, lu.ctypes, n, ipiv.ctypes, x.ctypes, n) != 0:
        raise np.linalg.LinAlgError("Matrix is singular to machine precision.")
    return x
