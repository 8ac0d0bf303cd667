"""Numba kernels of the three-dimensional region: twist band, containment, nearest on SO(3). ``q =
swing(d) * twist(tau)`` (:mod:`limbctl.geometry.twist`) is in the region when ``d`` is in the swing
region (:mod:`limbctl.region.mesh_kernels`) and ``|wrap(tau - c(d))| <= h(d)`` (:func:`band_at`).
Nearest orientation: over a candidate direction ``d`` at angle ``theta`` from ``q``'s, the best
orientation in the band lies ``delta(d)`` in twist from the transported twist, at geodesic angle
``g`` with ``cos(g/2) = cos(theta/2) cos(delta/2)`` (:func:`_score`), maximised by pattern searches
(docs/decisions/twist.md, "The nearest orientation as a search over directions"). No fastmath: NaN
must fail every comparison."""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from limbctl.geometry.jit import njit
from limbctl.region import mesh_kernels as bk

#: Twists this far (rad) outside the band pass: compose/decompose rounding (~1e-15).
TWIST_TOLERANCE = 1e-9
#: First search step (rad): about the seeds' spacing, within one step of a seed's basin.
STEP_START = math.radians(3.0)
#: Last step (rad): 0.03 deg; the score is flat to first order at an optimum.
STEP_MIN = math.radians(0.03)
#: Step (rad) where a further start stops unless it beat the best: 0.25 deg, within ~0.1 of optimum.
STEP_COARSE = STEP_START / 8.0
#: Cap on polls: 7 halvings poll 42 times without a move, ~350 left for moves.
MAX_POLLS = 400
#: Polls per step: six at 60 deg, isotropic enough to follow a curved swing edge.
POLL_DIRECTIONS = 6
#: Seeds nearest the command (by ``|<q, s>|``) the starts are chosen from.
NEAREST_SEEDS = 24
#: Pattern searches per command at most (uneven bands give two local optima).
MAX_STARTS = 2
#: Least angle (rad) between starts: two steps, so a second start does not retrace.
START_APART = STEP_START
#: ``cos(START_APART)``: candidates whose direction's cosine to a start exceeds it are skipped.
COS_APART = math.cos(START_APART)
#: Band nodes this close (rad) to the best optimum are scanned: 8 deg holds the farthest seen (6.8).
SCAN_RADIUS = math.radians(8.0)
#: Scanned nodes searched from, best score first (each skipped within a grid step of a start).
NODE_STARTS = 3
#: Rows of scratch the search needs beyond the direction mesh's (see ``_correct_one``; its search
#: is called, not inlined: inlined, it took 213 s to compile, docs/decisions/first_run.md).
WORK_EXTRA = 9 + MAX_STARTS


@njit(inline="always")
def wrap(a: float) -> float:
    """``a`` (rad) wrapped into (-pi, pi]: ``a - 2 pi ceil((a - pi) / 2 pi)``."""
    return a - 2.0 * math.pi * math.ceil((a - math.pi) / (2.0 * math.pi))


@njit(inline="always")
def plane_xy(d, frame):
    """Azimuthal equidistant coordinates (rad) of unit ``d`` about ``frame[0]`` (u = frame[1],
    v = frame[2]): ``theta (d.u, d.v) / |(d.u, d.v)|``, ``theta = atan2(|(d.u, d.v)|, d.axis)``."""
    ca = d[0] * frame[0, 0] + d[1] * frame[0, 1] + d[2] * frame[0, 2]
    su = d[0] * frame[1, 0] + d[1] * frame[1, 1] + d[2] * frame[1, 2]
    sv = d[0] * frame[2, 0] + d[1] * frame[2, 1] + d[2] * frame[2, 2]
    s = math.sqrt(su * su + sv * sv)
    if s < 1e-15:
        return 0.0, 0.0
    theta = math.atan2(s, ca)
    return theta * su / s, theta * sv / s


@njit(inline="always")
def band_at(d, frame, grid, centre, half):
    """Band centre and half-width (rad) over direction ``d``: bilinear in the plane grid
    ``grid = (x0, y0, step)``, clamped at its edge."""
    x, y = plane_xy(d, frame)
    nx = centre.shape[0]
    ny = centre.shape[1]
    fx = (x - grid[0]) / grid[2]
    fy = (y - grid[1]) / grid[2]
    i = min(max(int(math.floor(fx)), 0), nx - 2)
    j = min(max(int(math.floor(fy)), 0), ny - 2)
    tx = min(max(fx - i, 0.0), 1.0)
    ty = min(max(fy - j, 0.0), 1.0)
    # f = (1-tx)(1-ty) f00 + tx(1-ty) f10 + (1-tx) ty f01 + tx ty f11
    w00 = (1.0 - tx) * (1.0 - ty)
    w10 = tx * (1.0 - ty)
    w01 = (1.0 - tx) * ty
    w11 = tx * ty
    c = w00 * centre[i, j] + w10 * centre[i + 1, j] + w01 * centre[i, j + 1]
    c += w11 * centre[i + 1, j + 1]
    h = w00 * half[i, j] + w10 * half[i + 1, j] + w01 * half[i, j + 1] + w11 * half[i + 1, j + 1]
    return c, h


@njit(inline="always")
def _score(q, dq, d, frame, grid, centre, half):
    """``(F, tau)``: ``F = cos(theta/2) cos(delta/2)`` for candidate direction ``d`` and the best
    twist there; ``q`` canonical (4,), ``dq`` its unit direction."""
    rw = 1.0 + dq[0] * d[0] + dq[1] * d[1] + dq[2] * d[2]
    rx = dq[1] * d[2] - dq[2] * d[1]
    ry = dq[2] * d[0] - dq[0] * d[2]
    rz = dq[0] * d[1] - dq[1] * d[0]
    # w and x parts of r * q
    pw = rw * q[0] - rx * q[1] - ry * q[2] - rz * q[3]
    px = rw * q[1] + q[0] * rx + ry * q[3] - rz * q[2]
    t = 2.0 * math.atan2(px, pw)
    c, h = band_at(d, frame, grid, centre, half)
    e = wrap(t - c)
    ch = math.sqrt(max(0.5 * rw, 0.0))
    if abs(e) <= h:
        return ch, t
    delta = abs(e) - h
    tau = c + h if e > 0.0 else c - h
    return ch * math.cos(0.5 * delta), tau


@njit(inline="always")
def _compose_into(d, tau, out) -> None:
    """``out = swing(d) * twist(tau)`` (w >= 0), as :func:`limbctl.geometry.twist.compose`."""
    sw, sy, sz = bk.swing_of(d)
    half = 0.5 * wrap(tau)
    c = math.cos(half)
    s = math.sin(half)
    # (s_w c, s_w s, s_y c + s_z s, s_z c - s_y s)
    sign = 1.0 if sw * c >= 0.0 else -1.0
    out[0] = sign * sw * c
    out[1] = sign * sw * s
    out[2] = sign * (sy * c + sz * s)
    out[3] = sign * (sz * c - sy * s)


@njit
def _search(qc, dq, cur, best, best_tau, mesh, band, work, step, step_min):
    """Pattern search over swing-region directions from ``cur`` (its score ``best``, twist
    ``best_tau``) for the largest ``F`` (:func:`_score`), its step halving from ``step`` until
    below ``step_min`` (rad): ``cur`` moves to the optimum found; returns its ``(F, tau)``.
    Polls outside the swing region are replaced by their projection. ``work`` rows
    ``WORK_ROWS + 2 .. + 5`` are its scratch."""
    frame, grid, centre, half = band
    base = bk.WORK_ROWS
    trial = work[base + 2]
    proj = work[base + 3]
    e1 = work[base + 4]
    e2 = work[base + 5]
    turn = 0.0
    last = 0
    polls = 0
    while step > step_min and polls < MAX_POLLS:
        # tangent frame at cur as quat.tangent_frame: e1 = normalise(h x cur), helper h = +z
        # (+y near the z axis), e2 = cur x e1; the polls turn a little each halving
        hx = 0.0 if abs(cur[2]) < 0.9 else 1.0
        hz = 1.0 if abs(cur[2]) < 0.9 else 0.0
        e1[0] = hx * cur[2] - hz * cur[1]
        e1[1] = hz * cur[0]
        e1[2] = -hx * cur[0]
        n1 = math.sqrt(e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2])
        for k in range(3):
            e1[k] /= n1
        e2[0] = cur[1] * e1[2] - cur[2] * e1[1]
        e2[1] = cur[2] * e1[0] - cur[0] * e1[2]
        e2[2] = cur[0] * e1[1] - cur[1] * e1[0]
        moved = False
        cs = math.cos(step)
        sn = math.sin(step)
        for m in range(POLL_DIRECTIONS):
            a = turn + 2.0 * math.pi * ((last + m) % POLL_DIRECTIONS) / POLL_DIRECTIONS
            ca = math.cos(a)
            sa = math.sin(a)
            for k in range(3):
                trial[k] = cs * cur[k] + sn * (ca * e1[k] + sa * e2[k])
            polls += 1
            if not bk.query_mesh(trial, mesh, proj, work):
                for k in range(3):
                    trial[k] = proj[k]
            f, t = _score(qc, dq, trial, frame, grid, centre, half)
            if f > best:
                best, best_tau = f, t
                for k in range(3):
                    cur[k] = trial[k]
                last = (last + m) % POLL_DIRECTIONS
                moved = True
                break
        if not moved:
            step *= 0.5
            turn += 0.5 * math.pi / POLL_DIRECTIONS
    return best, best_tau


@njit
def _search_from(qc, dq, alt, best, step, mesh, band, work):
    """A further start at ``alt`` (moved to its optimum): searched from ``step`` (rad) down to
    ``STEP_COARSE``, and on to ``STEP_MIN`` only while it beats ``best``; its ``(F, tau)``."""
    frame, grid, centre, half = band
    f, t = _score(qc, dq, alt, frame, grid, centre, half)
    f, t = _search(qc, dq, alt, f, t, mesh, band, work, step, STEP_COARSE)
    if f > best:
        f, t = _search(qc, dq, alt, f, t, mesh, band, work, STEP_COARSE, STEP_MIN)
    return f, t


@njit
def _correct_one(q, mesh, band, seeds, seed_dirs, out, work) -> int:
    """Correct one quaternion into ``out``: 1 inside (``out = q``), 0 corrected, -1 bad input.
    ``mesh``: the direction mesh's kernel arguments, ``band = (frame, grid, centre, half)``;
    ``work`` (WORK_ROWS + WORK_EXTRA, 3) holds the mesh frame in rows 0, 1."""
    frame, grid, centre, half = band
    norm2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]
    if not abs(math.sqrt(norm2) - 1.0) <= 1e-6:
        return -1
    sign = -1.0 if q[0] < 0.0 else 1.0
    base = bk.WORK_ROWS
    qc = np.empty(4)
    for k in range(4):
        qc[k] = sign * q[k]
    w, x, y, z = qc[0], qc[1], qc[2], qc[3]
    dq = work[base]
    bk.limb_into(w, x, y, z, dq)
    cur = work[base + 1]
    if bk.query_mesh(dq, mesh, cur, work):
        c, h = band_at(dq, frame, grid, centre, half)
        if abs(wrap(2.0 * math.atan2(x, w) - c)) <= h + TWIST_TOLERANCE:
            for k in range(4):
                out[k] = qc[k]
            return 1
    best, best_tau = _score(qc, dq, cur, frame, grid, centre, half)
    # F = cos(theta/2) at the swing projection: no direction scores more (F <= cos(theta/2),
    # theta least at the projection), so it is the nearest orientation
    rw = 1.0 + dq[0] * cur[0] + dq[1] * cur[1] + dq[2] * cur[2]
    if best >= math.sqrt(max(0.5 * rw, 0.0)):
        _compose_into(cur, best_tau, out)
        return 0
    # the NEAREST_SEEDS seeds nearest q on SO(3) (max |<q, s>|), best first
    top = np.empty(NEAREST_SEEDS)
    pick = np.empty(NEAREST_SEEDS, dtype=np.int64)
    for m in range(NEAREST_SEEDS):
        top[m] = -1.0
        pick[m] = -1
    for s in range(seeds.shape[0]):
        dot = abs(w * seeds[s, 0] + x * seeds[s, 1] + y * seeds[s, 2] + z * seeds[s, 3])
        if dot > top[NEAREST_SEEDS - 1]:
            m = NEAREST_SEEDS - 1
            while m > 0 and dot > top[m - 1]:
                top[m] = top[m - 1]
                pick[m] = pick[m - 1]
                m -= 1
            top[m] = dot
            pick[m] = s
    # first start: the better of the swing projection and the nearest seed's direction
    held = work[base + 6]
    for k in range(3):
        held[k] = cur[k]
    if pick[0] >= 0:
        f, t = _score(qc, dq, seed_dirs[pick[0]], frame, grid, centre, half)
        if f > best:
            best, best_tau = f, t
            for k in range(3):
                cur[k] = seed_dirs[pick[0], k]
    # further starts, best score first, each at least START_APART from every start before it
    alt = work[base + 7]
    starts = work[base + 8 : base + 8 + MAX_STARTS]
    for k in range(3):
        starts[0, k] = cur[k]
    best, best_tau = _search(qc, dq, cur, best, best_tau, mesh, band, work, STEP_START, STEP_MIN)
    # candidate scores: rank NEAREST_SEEDS is the swing projection
    score = np.empty(NEAREST_SEEDS + 1)
    for m in range(NEAREST_SEEDS):
        score[m] = (
            _score(qc, dq, seed_dirs[pick[m]], frame, grid, centre, half)[0]
            if pick[m] >= 0
            else -2.0
        )
    score[NEAREST_SEEDS] = _score(qc, dq, held, frame, grid, centre, half)[0]
    n_starts = 1
    while n_starts < MAX_STARTS:
        m = 0
        for r in range(1, NEAREST_SEEDS + 1):
            if score[r] > score[m]:
                m = r
        if score[m] < -1.0:
            break
        score[m] = -2.0
        src = held if m == NEAREST_SEEDS else seed_dirs[pick[m]]
        near = False
        for r in range(n_starts):
            if src[0] * starts[r, 0] + src[1] * starts[r, 1] + src[2] * starts[r, 2] > COS_APART:
                near = True
        if near:
            continue
        for k in range(3):
            starts[n_starts, k] = src[k]
            alt[k] = src[k]
        n_starts += 1
        f, t = _search_from(qc, dq, alt, best, STEP_START, mesh, band, work)
        if f > best:
            best, best_tau = f, t
            for k in range(3):
                cur[k] = alt[k]
    best, best_tau = _scan_nodes(qc, dq, cur, best, best_tau, mesh, band, work)
    _compose_into(cur, best_tau, out)
    return 0


@njit
def _scan_nodes(qc, dq, cur, best, best_tau, mesh, band, work):
    """Search again from the band grid nodes within ``SCAN_RADIUS`` of ``cur`` scoring best: the
    ``NODE_STARTS`` best scoring nodes (each more than a grid step from ``cur`` and from
    each other) start a search at half a grid step; ``cur`` moves to a better optimum found.
    Returns the best ``(F, tau)``. ``work`` rows from ``WORK_ROWS + 9 + MAX_STARTS`` are scratch."""
    frame, grid, centre, half = band
    base = bk.WORK_ROWS + 9 + MAX_STARTS
    node = work[base - 1]
    nx = centre.shape[0]
    ny = centre.shape[1]
    cx, cy = plane_xy(cur, frame)
    reach = int(math.ceil(SCAN_RADIUS / grid[2]))
    i0 = int(math.floor((cx - grid[0]) / grid[2]))
    j0 = int(math.floor((cy - grid[1]) / grid[2]))
    top = np.full(NODE_STARTS, -2.0)
    top_x = np.zeros(NODE_STARTS)
    top_y = np.zeros(NODE_STARTS)
    apart2 = grid[2] * grid[2]
    for i in range(max(i0 - reach, 0), min(i0 + reach + 2, nx)):
        x = grid[0] + i * grid[2]
        for j in range(max(j0 - reach, 0), min(j0 + reach + 2, ny)):
            y = grid[1] + j * grid[2]
            r2 = (x - cx) * (x - cx) + (y - cy) * (y - cy)
            if r2 > SCAN_RADIUS * SCAN_RADIUS or r2 <= apart2:
                continue
            _plane_to_direction_into(x, y, frame, node)
            f = _score(qc, dq, node, frame, grid, centre, half)[0]
            if f <= top[NODE_STARTS - 1]:
                continue
            # skip a node within a grid step of a better one kept; else insert it in rank
            near = False
            for m in range(NODE_STARTS):
                dx = top_x[m] - x
                dy = top_y[m] - y
                if top[m] >= f and dx * dx + dy * dy <= apart2:
                    near = True
            if near:
                continue
            m = NODE_STARTS - 1
            while m > 0 and f > top[m - 1]:
                top[m] = top[m - 1]
                top_x[m] = top_x[m - 1]
                top_y[m] = top_y[m - 1]
                m -= 1
            top[m] = f
            top_x[m] = x
            top_y[m] = y
    alt = work[bk.WORK_ROWS + 7]
    proj = work[bk.WORK_ROWS + 3]
    for m in range(NODE_STARTS):
        if top[m] < -1.0:
            break
        _plane_to_direction_into(top_x[m], top_y[m], frame, alt)
        if not bk.query_mesh(alt, mesh, proj, work):
            for k in range(3):
                alt[k] = proj[k]
        f, t = _search_from(qc, dq, alt, best, 0.5 * grid[2], mesh, band, work)
        if f > best:
            best, best_tau = f, t
            for k in range(3):
                cur[k] = alt[k]
    return best, best_tau


@njit(inline="always")
def _plane_to_direction_into(x, y, frame, out) -> None:
    """Unit direction at azimuthal equidistant coordinates ``(x, y)`` (rad) of ``frame``
    (:func:`plane_xy`'s inverse): ``cos r axis + sin r (x u + y v) / r``, ``r = |(x, y)|``."""
    r = math.sqrt(x * x + y * y)
    c = math.cos(r)
    s = math.sin(r) / r if r > 1e-15 else 1.0
    for k in range(3):
        out[k] = c * frame[0, k] + s * (x * frame[1, k] + y * frame[2, k])


@njit(parallel=True)
def correct_batch(q, mesh, band, seeds, seed_dirs):
    """Correct each row of ``q`` (N, 4) -> (out (N, 4), status (N,) int8: 1 in, 0 moved, -1 bad)."""
    n = q.shape[0]
    out = np.empty((n, 4))
    status = np.empty(n, dtype=np.int8)
    for chunk in nb.prange((n + bk.CHUNK - 1) // bk.CHUNK):
        work = np.empty((bk.WORK_ROWS + WORK_EXTRA, 3))
        bk.frame_into(mesh[3], work)
        for j in range(chunk * bk.CHUNK, min(n, (chunk + 1) * bk.CHUNK)):
            status[j] = _correct_one(q[j], mesh, band, seeds, seed_dirs, out[j], work)
    return out, status


@njit
def correct_single(q, mesh, band, seeds, seed_dirs):
    """:func:`correct_batch` for one (4,) quaternion, without the thread pool: (out, status)."""
    out = np.empty(4)
    work = np.empty((bk.WORK_ROWS + WORK_EXTRA, 3))
    bk.frame_into(mesh[3], work)
    status = _correct_one(q, mesh, band, seeds, seed_dirs, out, work)
    return out, status


@njit(parallel=True)
def contains_batch(q, mesh, band):
    """(N,) int8 for rows of ``q`` (N, 4): 1 inside, 0 outside, -1 bad input."""
    n = q.shape[0]
    res = np.empty(n, dtype=np.int8)
    frame, grid, centre, half = band
    for chunk in nb.prange((n + bk.CHUNK - 1) // bk.CHUNK):
        work = np.empty((bk.WORK_ROWS + 1, 3))
        bk.frame_into(mesh[3], work)
        for j in range(chunk * bk.CHUNK, min(n, (chunk + 1) * bk.CHUNK)):
            res[j] = _contains_one(q[j], mesh, frame, grid, centre, half, work)
    return res


@njit(inline="always")
def _contains_one(q, mesh, frame, grid, centre, half, work) -> int:
    norm2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]
    if not abs(math.sqrt(norm2) - 1.0) <= 1e-6:
        return -1
    sign = -1.0 if q[0] < 0.0 else 1.0
    w, x, y, z = sign * q[0], sign * q[1], sign * q[2], sign * q[3]
    d = work[bk.WORK_ROWS]
    bk.limb_into(w, x, y, z, d)
    out = np.empty(3)
    if not bk.query_mesh(d, mesh, out, work):
        return 0
    c, h = band_at(d, frame, grid, centre, half)
    return 1 if abs(wrap(2.0 * math.atan2(x, w) - c)) <= h + TWIST_TOLERANCE else 0


@njit
def contains_serial(q, mesh, band):
    """:func:`contains_batch` on one thread: the same answers, row for row."""
    n = q.shape[0]
    res = np.empty(n, dtype=np.int8)
    frame, grid, centre, half = band
    work = np.empty((bk.WORK_ROWS + 1, 3))
    bk.frame_into(mesh[3], work)
    for j in range(n):
        res[j] = _contains_one(q[j], mesh, frame, grid, centre, half, work)
    return res


@njit
def correct_serial(q, mesh, band, seeds, seed_dirs):
    """:func:`correct_batch` on one thread: the same answers, row for row."""
    n = q.shape[0]
    out = np.empty((n, 4))
    status = np.empty(n, dtype=np.int8)
    work = np.empty((bk.WORK_ROWS + WORK_EXTRA, 3))
    bk.frame_into(mesh[3], work)
    for j in range(n):
        status[j] = _correct_one(q[j], mesh, band, seeds, seed_dirs, out[j], work)
    return out, status


@njit
def contains_single(q, mesh, band) -> int:
    """:func:`contains_batch` for one (4,) quaternion: 1, 0 or -1."""
    work = np.empty((bk.WORK_ROWS + 1, 3))
    bk.frame_into(mesh[3], work)
    frame, grid, centre, half = band
    return _contains_one(q, mesh, frame, grid, centre, half, work)


@njit
def band_batch(d, frame, grid, centre, half):
    """Band centre and half-width (N,), (N,) over directions ``d`` (N, 3)."""
    n = d.shape[0]
    c = np.empty(n)
    h = np.empty(n)
    for j in range(n):
        c[j], h[j] = band_at(d[j], frame, grid, centre, half)
    return c, h
