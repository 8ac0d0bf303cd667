"""Numba kernels of the direction-space region: lookup grid, containment and nearest projection. The
grid's ``n_theta x n_phi`` polar cells about ``axis`` each hold ``cell_inside``, ``cell_deep`` and
candidate arcs (CSR ``cell_start``/``cell_edges``, sorted by ``cell_keys``). A query finds its cell;
deep is inside; else the nearest widened arc (``min_e angle(p, e) - margin_e``) over the candidates
and the loops' parity along centre -> point. No fastmath: NaN fails every comparison."""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from limbctl.geometry.jit import njit

#: Slack (rad) of contains(): the projection's rounding, far below a tick (0.088 deg).
CONTAIN_TOLERANCE = 1e-9


@njit
def _dot(a, b) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit
def _det(a, b, c) -> float:
    # det(a, b, c) = a . (b x c)
    return (
        a[0] * (b[1] * c[2] - b[2] * c[1])
        + a[1] * (b[2] * c[0] - b[0] * c[2])
        + a[2] * (b[0] * c[1] - b[1] * c[0])
    )


@njit
def _angle(a, b) -> float:
    # atan2(|a x b|, a . b): accurate near 0 and pi
    cx = a[1] * b[2] - a[2] * b[1]
    cy = a[2] * b[0] - a[0] * b[2]
    cz = a[0] * b[1] - a[1] * b[0]
    return math.atan2(math.sqrt(cx * cx + cy * cy + cz * cz), _dot(a, b))


@njit
def nearest_on_arc(p, a, b, out) -> float:
    """Nearest point ``out`` (3,) on the short great-circle arc a-b to ``p``; returns its angle."""
    angle, out[0], out[1], out[2] = _foot(p[0], p[1], p[2], a[0], a[1], a[2], b[0], b[1], b[2])
    return angle


@njit
def _angle3(ax, ay, az, bx, by, bz) -> float:
    """:func:`_angle` of ``a = (ax, ay, az)`` and ``b = (bx, by, bz)``: the same arithmetic."""
    # atan2(|a x b|, a . b)
    cx = ay * bz - az * by
    cy = az * bx - ax * bz
    cz = ax * by - ay * bx
    return math.atan2(math.sqrt(cx * cx + cy * cy + cz * cz), ax * bx + ay * by + az * bz)


@njit
def edge_foot(p, vertices, edges, e):
    """:func:`nearest_on_arc` of ``p`` (3,) and arc ``e`` on scalars: (angle (rad), x, y, z)."""
    i, j = edges[e, 0], edges[e, 1]
    a0, a1, a2 = vertices[i, 0], vertices[i, 1], vertices[i, 2]
    return _foot(p[0], p[1], p[2], a0, a1, a2, vertices[j, 0], vertices[j, 1], vertices[j, 2])


@njit
def _foot(px, py, pz, ax, ay, az, bx, by, bz):
    """Nearest point of the short great-circle arc a-b to p, on scalars: (angle, x, y, z)."""
    nx = ay * bz - az * by
    ny = az * bx - ax * bz
    nz = ax * by - ay * bx
    nn = math.sqrt(nx * nx + ny * ny + nz * nz)
    if nn > 0.0:
        nx /= nn
        ny /= nn
        nz /= nn
        # foot of p on the arc's great circle: p - (p.n) n, normalised
        pn = px * nx + py * ny + pz * nz
        fx = px - pn * nx
        fy = py - pn * ny
        fz = pz - pn * nz
        fn = math.sqrt(fx * fx + fy * fy + fz * fz)
        if fn > 0.0:
            fx /= fn
            fy /= fn
            fz /= fn
            # within the arc: (n x a) . f >= 0 and (b x n) . f >= 0
            s1 = (ny * az - nz * ay) * fx + (nz * ax - nx * az) * fy + (nx * ay - ny * ax) * fz
            s2 = (by * nz - bz * ny) * fx + (bz * nx - bx * nz) * fy + (bx * ny - by * nx) * fz
            if s1 >= 0.0 and s2 >= 0.0:
                return _angle3(px, py, pz, fx, fy, fz), fx, fy, fz
    da = _angle3(px, py, pz, ax, ay, az)
    db = _angle3(px, py, pz, bx, by, bz)
    if da <= db:
        return da, ax, ay, az
    return db, bx, by, bz


@njit
def slerp_into(p, d, angle, margin, out) -> None:
    """Write into ``out`` (3,) the direction ``margin`` (rad) from ``p`` toward ``d``, ``angle``
    apart (``p`` itself when either is 0)."""
    c = _dot(d, p)
    ux = d[0] - c * p[0]
    uy = d[1] - c * p[1]
    uz = d[2] - c * p[2]
    un = math.sqrt(ux * ux + uy * uy + uz * uz)
    if not (margin > 0.0 and angle > 0.0 and un > 0.0):
        out[0] = p[0]
        out[1] = p[1]
        out[2] = p[2]
        return
    cm = math.cos(margin)
    sm = math.sin(margin)
    x = cm * p[0] + sm * ux / un
    y = cm * p[1] + sm * uy / un
    z = cm * p[2] + sm * uz / un
    n = math.sqrt(x * x + y * y + z * z)
    out[0] = x / n
    out[1] = y / n
    out[2] = z / n


@njit
def slerp_dir(p, d, angle, margin) -> np.ndarray:
    """:func:`slerp_into` returning a new (3,) array."""
    out = np.empty(3)
    slerp_into(p, d, angle, margin, out)
    return out


@njit
def frame_into(axis, work) -> None:
    """Write the grid frame's u, v (see :func:`_frame`) into rows 0 and 1 of ``work``."""
    u, v = _frame(axis)
    for k in range(3):
        work[0, k] = u[k]
        work[1, k] = v[k]


@njit
def _frame(axis):
    """Unit u, v completing ``axis`` to a right-handed frame (same rule as synthetic)."""
    if abs(axis[2]) < 0.9:
        h0, h1, h2 = 0.0, 0.0, 1.0
    else:
        h0, h1, h2 = 0.0, 1.0, 0.0
    # u = h x axis, v = axis x u, written out (np.cross compiles for seconds)
    u = np.empty(3)
    u[0] = h1 * axis[2] - h2 * axis[1]
    u[1] = h2 * axis[0] - h0 * axis[2]
    u[2] = h0 * axis[1] - h1 * axis[0]
    norm = math.sqrt(_dot(u, u))
    u[0] /= norm
    u[1] /= norm
    u[2] /= norm
    v = np.empty(3)
    v[0] = axis[1] * u[2] - axis[2] * u[1]
    v[1] = axis[2] * u[0] - axis[0] * u[2]
    v[2] = axis[0] * u[1] - axis[1] * u[0]
    return u, v


@njit
def _cell_of(p, axis, u, v, n_theta, n_phi) -> int:
    theta = _angle(p, axis)
    phi = math.atan2(_dot(p, v), _dot(p, u))
    i = int(theta / math.pi * n_theta)
    j = int((phi + math.pi) / (2.0 * math.pi) * n_phi)
    # NaN never reaches here (inputs are checked); clamp rounding at the ends
    i = min(max(i, 0), n_theta - 1)
    j = min(max(j, 0), n_phi - 1)
    return i * n_phi + j


@njit
def _polar_point(theta, phi, axis, u, v):
    st = math.sin(theta)
    return math.cos(theta) * axis + st * (math.cos(phi) * u + math.sin(phi) * v)


#: Scratch rows of the query kernels: frame u, v, cell centre, a temporary and the best point.
WORK_ROWS = 5


@njit(inline="always")
def query(
    p, vertices, edges, margins, axis, grid_shape, inside, deep, start, cell_edges, keys, out, work
):
    """Whether direction ``p`` is in the region; ``out`` gets its projection (p itself inside).
    ``work`` (>= WORK_ROWS, 3) is scratch, the frame in rows 0, 1 (:func:`frame_into`). The
    candidates are visited by increasing key until the keys bound the rest away."""
    n_theta = grid_shape[0]
    n_phi = grid_shape[1]
    u = work[0]
    v = work[1]
    cell = _cell_of(p, axis, u, v, n_theta, n_phi)
    out[0] = p[0]
    out[1] = p[1]
    out[2] = p[2]
    if deep[cell]:
        return True
    i = cell // n_phi
    j = cell % n_phi
    theta = (i + 0.5) * math.pi / n_theta
    phi = -math.pi + (j + 0.5) * 2.0 * math.pi / n_phi
    st = math.sin(theta)
    cp = math.cos(phi)
    sp = math.sin(phi)
    centre = work[2]
    tmp = work[3]
    best_point = work[4]
    for c in range(3):
        centre[c] = math.cos(theta) * axis[c] + st * (cp * u[c] + sp * v[c])
    travel = _angle(centre, p)
    crossings = 0
    best = np.inf
    best_dist = np.inf
    best_margin = 0.0
    for k in range(start[cell], start[cell + 1]):
        if keys[k] > travel and keys[k] - travel > best:
            break
        e = cell_edges[k]
        a = vertices[edges[e, 0]]
        b = vertices[edges[e, 1]]
        dist = nearest_on_arc(p, a, b, tmp)
        if dist - margins[e] < best:
            best = dist - margins[e]
            best_dist = dist
            best_margin = margins[e]
            best_point[0] = tmp[0]
            best_point[1] = tmp[1]
            best_point[2] = tmp[2]
        # does arc centre -> p cross arc a -> b? (half-open sign rule; same hemisphere)
        # Not when the arc lies farther than `travel`, as all of the path centre -> p does.
        if keys[k] + margins[e] > travel:
            continue
        sa = _det(centre, p, a) > 0.0
        sb = _det(centre, p, b) > 0.0
        sc = _det(a, b, centre) > 0.0
        sq = _det(a, b, p) > 0.0
        if (
            sa != sb
            and sc != sq
            and _dot(a, centre) + _dot(b, centre) + _dot(a, p) + _dot(b, p) > 0.0
        ):
            crossings += 1
    in_mesh = inside[cell] != (crossings % 2 == 1)
    if in_mesh or best <= CONTAIN_TOLERANCE:
        return True
    slerp_into(best_point, p, best_dist, best_margin, out)
    return False


@njit(inline="always")
def query_mesh(p, mesh, out, work):
    """:func:`query` with the mesh's kernel arguments (``DirectionMesh.kernel_args``) as a tuple."""
    # vertices, edges, margins, axis, grid_shape, inside, deep, start, cell_edges, keys
    ve, ed, ma, ax, gs, ins, dp, st, ce, ke = mesh
    return query(p, ve, ed, ma, ax, gs, ins, dp, st, ce, ke, out, work)


@njit(inline="always")
def limb_into(w, x, y, z, d) -> None:
    """Write into ``d`` (3,) the unit limb direction of canonical quaternion ``(w, x, y, z)``."""
    d[0] = w * w + x * x - y * y - z * z
    d[1] = 2.0 * (x * y + w * z)
    d[2] = 2.0 * (x * z - w * y)
    dn = math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
    for k in range(3):
        d[k] /= dn


@njit(inline="always")
def swing_of(p):
    """The swing from +x to unit ``p`` (3,): ``normalise(1 + p_x, 0, -p_z, p_y)`` as (w, y, z)."""
    sw = 1.0 + p[0]
    sy = -p[2]
    sz = p[1]
    sn = math.sqrt(sw * sw + sy * sy + sz * sz)
    if sn < 1e-12:
        sw, sy, sz, sn = 0.0, 0.0, 1.0, 1.0
    sw /= sn
    sy /= sn
    sz /= sn
    return sw, sy, sz


#: Rows per chunk of a batch: scratch is allocated once per chunk, not per row.
CHUNK = 512


@njit(parallel=True)
def contains_batch(vertices, edges, margins, axis, grid_shape, inside, deep, start, arcs, keys, d):
    """(N,) bool for directions ``d`` (N, 3)."""
    mesh = (vertices, edges, margins, axis, grid_shape, inside, deep, start, arcs, keys)
    n = d.shape[0]
    res = np.empty(n, dtype=np.bool_)
    for chunk in nb.prange((n + CHUNK - 1) // CHUNK):
        work = np.empty((WORK_ROWS, 3))
        frame_into(axis, work)
        out = np.empty(3)
        for j in range(chunk * CHUNK, min(n, (chunk + 1) * CHUNK)):
            res[j] = query_mesh(d[j], mesh, out, work)
    return res


@njit(parallel=True)
def project_batch(vertices, edges, margins, axis, grid_shape, inside, deep, start, arcs, keys, d):
    """Projection (N, 3) of directions ``d`` (N, 3): themselves inside, nearest region point out."""
    mesh = (vertices, edges, margins, axis, grid_shape, inside, deep, start, arcs, keys)
    n = d.shape[0]
    res = np.empty((n, 3))
    for chunk in nb.prange((n + CHUNK - 1) // CHUNK):
        work = np.empty((WORK_ROWS, 3))
        frame_into(axis, work)
        for j in range(chunk * CHUNK, min(n, (chunk + 1) * CHUNK)):
            query_mesh(d[j], mesh, res[j], work)
    return res
