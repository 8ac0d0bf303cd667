"""Numba kernels that correct quaternions against the region: inside kept, outside moved, the
twist about the limb kept. No ``fastmath``: NaN must fail every comparison."""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from limbctl.geometry.jit import njit
from limbctl.region import mesh_kernels as bk


@njit(inline="always")
def _correct_one(q, mesh, out, work) -> int:
    """Correct one quaternion into ``out``; returns 1 inside, 0 corrected, -1 bad input.
    Inside: ``out = q`` (canonical). Outside: ``out = swing(d') * twist(q)``, ``d'`` the nearest
    region direction. ``mesh`` is the mesh's kernel arguments; ``work`` (WORK_ROWS + 2, 3) scratch
    with the grid frame in rows 0, 1 (``bk.frame_into``)."""
    norm2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]
    # NaN fails every comparison, so it is refused here
    if not abs(math.sqrt(norm2) - 1.0) <= 1e-6:
        return -1
    sign = -1.0 if q[0] < 0.0 else 1.0
    w = sign * q[0]
    x = sign * q[1]
    y = sign * q[2]
    z = sign * q[3]
    d = work[bk.WORK_ROWS]
    bk.limb_into(w, x, y, z, d)
    p = work[bk.WORK_ROWS + 1]
    if bk.query_mesh(d, mesh, p, work):
        out[0] = w
        out[1] = x
        out[2] = y
        out[3] = z
        return 1
    sw, sy, sz = bk.swing_of(p)
    tn = math.sqrt(w * w + x * x)
    tw, tx = (w / tn, x / tn) if tn > 1e-12 else (1.0, 0.0)
    # (sw, 0, sy, sz) * (tw, tx, 0, 0)
    rw = sw * tw
    rx = sw * tx
    ry = sy * tw + sz * tx
    rz = sz * tw - sy * tx
    s2 = -1.0 if rw < 0.0 else 1.0
    out[0] = s2 * rw
    out[1] = s2 * rx
    out[2] = s2 * ry
    out[3] = s2 * rz
    return 0


@njit(parallel=True)
def correct_batch(
    q, vertices, edges, margins, axis, grid_shape, inside, deep, start, cell_edges, keys
):
    """Correct each row of ``q`` (N, 4) -> (out (N, 4), status (N,) int8: 1 in, 0 fixed, -1 bad)."""
    mesh = (vertices, edges, margins, axis, grid_shape, inside, deep, start, cell_edges, keys)
    n = q.shape[0]
    out = np.empty((n, 4))
    status = np.empty(n, dtype=np.int8)
    for chunk in nb.prange((n + bk.CHUNK - 1) // bk.CHUNK):
        work = np.empty((bk.WORK_ROWS + 2, 3))
        bk.frame_into(axis, work)
        for j in range(chunk * bk.CHUNK, min(n, (chunk + 1) * bk.CHUNK)):
            status[j] = _correct_one(q[j], mesh, out[j], work)
    return out, status


@njit
def correct_single(
    q, vertices, edges, margins, axis, grid_shape, inside, deep, start, cell_edges, keys
):
    """:func:`correct_batch` for one (4,) quaternion, without the thread pool: (out, status)."""
    mesh = (vertices, edges, margins, axis, grid_shape, inside, deep, start, cell_edges, keys)
    out = np.empty(4)
    work = np.empty((bk.WORK_ROWS + 2, 3))
    bk.frame_into(axis, work)
    status = _correct_one(q, mesh, out, work)
    return out, status


@njit
def correct_serial(
    q, vertices, edges, margins, axis, grid_shape, inside, deep, start, cell_edges, keys
):
    """:func:`correct_batch` on one thread: the same answers, row for row."""
    mesh = (vertices, edges, margins, axis, grid_shape, inside, deep, start, cell_edges, keys)
    n = q.shape[0]
    out = np.empty((n, 4))
    status = np.empty(n, dtype=np.int8)
    work = np.empty((bk.WORK_ROWS + 2, 3))
    bk.frame_into(axis, work)
    for j in range(n):
        status[j] = _correct_one(q[j], mesh, out[j], work)
    return out, status


#: Rows up to which a batch goes row by row (:func:`correct_single`): one. From two rows the
#: serial kernel's one call is the cheaper (2 rows: 3.4 against 5.0 us, 8: 8.1 against 20 us).
SINGLE_ROWS = 1
#: Rows up to which a batch runs on one thread (train's ~50,000: ~0.1 s): no pool compile.
PARALLEL_ROWS = 100_000


def correct_rows(q, *args):
    """Correct each row of ``q`` (N, 4) C-contiguous -> (out (N, 4), status (N,) int8), through
    the kernel that suits N: the same answers row for row. ``args``: the mesh's kernel arguments."""
    n = q.shape[0]
    if n > PARALLEL_ROWS:
        return correct_batch(q, *args)
    if n > SINGLE_ROWS:
        return correct_serial(q, *args)
    out = np.empty((n, 4))
    status = np.empty(n, dtype=np.int8)
    for j in range(n):
        row, status[j] = correct_single(q[j], *args)
        out[j] = row
    return out, status
