"""The three-servo demo's stream, judgement and picture (``limbctl demo --rig sim3``)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from limbctl.geometry.gimbal import direction_to_pan_tilt
from limbctl.geometry.twist import decompose


def write_twist_stream(path: Path, seconds: float = 12.0, rate_hz: float = 50.0) -> int:
    """A replay file sweeping far outside in swing and twist, bad lines mixed in; valid lines."""
    n = int(seconds * rate_hz)
    t = np.arange(n) / rate_hz
    pan = 110.0 * np.sin(2 * math.pi * t / seconds)
    tilt = 10.0 + 60.0 * np.sin(4 * math.pi * t / seconds + 0.6)
    roll = 150.0 * np.sin(6 * math.pi * t / seconds + 1.0)
    bad = [
        '{"pan": 10, "tilt": 0, "roll": NaN}',
        '{"dir": [1, 0, 0], "twist": 400}',
        '{"q": [1, 0, 0, 0], "twist": 5}',
        "not json at all",
    ]
    rows = [
        {"t": round(float(t[i]), 4), "pan": pan[i], "tilt": tilt[i], "roll": roll[i]}
        for i in range(n)
    ]
    return write_stream(path, rows, bad)


def write_stream(path: Path, rows: list[dict], bad: list[str]) -> int:
    """Write ``rows`` as JSON lines with the ``bad`` lines spread evenly among them; the rows."""
    n = len(rows)
    with open(path, "w", encoding="utf-8") as fh:
        for i, row in enumerate(rows):
            fh.write(json.dumps(row) + "\n")
            if i % (n // len(bad)) == n // (2 * len(bad)):
                fh.write(bad[(i * len(bad)) // n] + "\n")
    return n


def logged_packets(goal_log: Path, key: str, width: int) -> np.ndarray:
    """What each goal packet of the simulator's goal log commanded, (M, ``width``): the last
    ``key`` of each ``t`` (a sync write's lines share it; earlier ones mix old and new goals)."""
    with open(goal_log, encoding="utf-8") as fh:
        rows = [json.loads(line) for line in fh if line.strip()]
    by_time = {row["t"]: row[key] for row in rows}  # the last line of each t
    return np.asarray(list(by_time.values()), dtype=np.float64).reshape(-1, width)


def logged_orientations(goal_log: Path) -> np.ndarray:
    """The full orientation (M, 4) each goal packet commanded (its ``limb_q``)."""
    return logged_packets(goal_log, "limb_q", 4)


def rotation_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Rotation angle (deg) ``2 acos |a . b|`` between rows of unit quaternions, exact near 0."""
    # 4 atan2(|a - s b|, |a + s b|), s = sign(a . b)
    s = np.where(np.sum(a * b, axis=-1) < 0.0, -1.0, 1.0)[..., None]
    near = np.linalg.norm(a - s * b, axis=-1)
    far = np.linalg.norm(a + s * b, axis=-1)
    return np.degrees(4.0 * np.arctan2(near, far))


def twist_excursions(
    goal_log: Path, model: object, written: np.ndarray | None = None
) -> np.ndarray:
    """Rotation (deg) by which each logged goal lies outside ``model``'s region, at most; 0 inside.
    ``written`` (M, 4): the orientations the gate wrote, which bound the distance too."""
    q = logged_orientations(goal_log)
    if not len(q):
        return np.zeros(0)
    outside = ~np.asarray(model.contains(q), dtype=bool)
    bound = rotation_deg(q, model.correct(q))
    if written is not None and len(written):
        # region points near the goals: the written poses the region contains, and for the
        # others (within the gate's tolerance of it) their corrections
        held = np.asarray(model.contains(written), dtype=bool)
        inside = np.concatenate([written[held], model.correct(written[~held])])
        inside = inside[np.asarray(model.contains(inside), dtype=bool)]
        for k in np.flatnonzero(outside):
            if len(inside):
                nearest = rotation_deg(np.broadcast_to(q[k], inside.shape), inside).min()
                bound[k] = min(bound[k], nearest)
    for k in np.flatnonzero(outside & (bound > REFINE_ABOVE_DEG)):
        bound[k] = min(bound[k], nearest_held_nearby_deg(model, q[k], bound[k], seed=int(k)))
    return np.where(outside, bound, 0.0)


#: Bound (deg) above which a goal is measured again by sampling (``correct`` may stop short).
REFINE_ABOVE_DEG = 0.05
#: Orientations sampled around such a goal: the nearest held one within thousandths of a degree.
REFINE_SAMPLES = 20000


def nearest_held_nearby_deg(model: object, q: np.ndarray, radius_deg: float, seed: int) -> float:
    """Rotation (deg) from ``q`` (4,) to the nearest of REFINE_SAMPLES random orientations within
    ``radius_deg`` that ``model`` contains (``radius_deg`` when none): an upper bound."""
    from limbctl.geometry.quat import canonical, from_axis_angle, multiply

    rng = np.random.default_rng(seed)
    axis = rng.normal(size=(REFINE_SAMPLES, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    # uniform in a ball of rotation vectors: angle = r u^(1/3)
    angle = math.radians(radius_deg) * rng.uniform(0.0, 1.0, REFINE_SAMPLES) ** (1.0 / 3.0)
    near = canonical(
        multiply(np.broadcast_to(q, (REFINE_SAMPLES, 4)), from_axis_angle(axis, angle))
    )
    held = np.asarray(model.contains(near), dtype=bool)
    if not held.any():
        return radius_deg
    return float(rotation_deg(np.broadcast_to(q, near[held].shape), near[held]).min())


def written_orientations(telemetry: Path) -> np.ndarray:
    """The orientations (M, 4) the gate wrote, from a three-servo session's telemetry."""
    from limbctl.geometry.gimbal import pan_tilt_roll_to_quat

    with open(telemetry, encoding="utf-8") as fh:
        cycles = [json.loads(line) for line in fh]
    rows = [
        c["out"] for c in cycles if c["written"] and c["out"] is not None and len(c["out"]) == 3
    ]
    if not rows:
        return np.zeros((0, 4))
    a = np.radians(np.asarray(rows, dtype=np.float64))
    return pan_tilt_roll_to_quat(a[:, 0], a[:, 1], a[:, 2])


def coverage(model: object, probes: np.ndarray) -> float:
    """Share of the orientations ``probes`` (N, 4) that ``model`` contains."""
    if not len(probes):
        return 0.0
    return float(np.mean(np.asarray(model.contains(probes), dtype=bool)))


def twist_picture(
    path: Path,
    samples: np.ndarray,
    goals: np.ndarray,
    band_tilt_deg: np.ndarray,
    band_deg,
    model: object | None = None,
    band_pan_deg: float = 0.0,
) -> None:
    """The taught samples over (pan, tilt) coloured by twist; twist against tilt of the samples
    and of the goals written with the true band's ``band_deg`` (low, high) limits at
    ``band_tilt_deg`` (at pan ``band_pan_deg``); a twist ``model``'s learned band too."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    def pose(q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        d, tau = decompose(q)
        pan, tilt = direction_to_pan_tilt(d)
        return np.degrees(pan), np.degrees(tilt), np.degrees(tau)

    region = getattr(model, "region", None)
    learned = getattr(region, "band", None) is not None and region.mesh is not None
    fig, axes = plt.subplots(1, 3 if learned else 2, figsize=(18 if learned else 12, 5))
    left, right = axes[0], axes[1]
    pan, tilt, tau = pose(samples)
    dots = left.scatter(pan, tilt, c=tau, s=2, cmap="coolwarm")
    fig.colorbar(dots, ax=left, label="twist (deg)")
    left.set(xlabel="pan (deg)", ylabel="tilt (deg)", title="taught samples, coloured by twist")
    right.scatter(tilt, tau, s=1, color="0.7", label="taught")
    if len(goals):
        _, goal_tilt, goal_tau = pose(goals)
        right.scatter(goal_tilt, goal_tau, s=2, color="tab:red", label="goals written (gated)")
    low, high = band_deg
    right.plot(band_tilt_deg, low, "k--", label=f"true band (at pan {band_pan_deg:.0f} deg)")
    right.plot(band_tilt_deg, high, "k--")
    if learned:
        low_l, high_l = learned_band_line(region, band_pan_deg, band_tilt_deg)
        right.plot(band_tilt_deg, low_l, color="tab:blue", label="learned band (same line)")
        right.plot(band_tilt_deg, high_l, color="tab:blue")
        _band_width_panel(fig, axes[2], region, pan, tilt)
    right.set(xlabel="tilt (deg)", ylabel="twist (deg)", title="the twist band over the swing")
    right.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


#: Grid step (deg) of the learned band's width picture: finer would show no more at ~3 px/deg.
WIDTH_STEP_DEG = 2.0


def learned_band_line(
    region: object, pan_deg: float, tilt_deg: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The learned band's limits (deg) along tilts ``tilt_deg`` at ``pan_deg`` (NaN where the
    swing region does not reach), each centre taken on the turn nearest 0."""
    from limbctl.geometry.gimbal import pan_tilt_to_direction

    d = pan_tilt_to_direction(np.full(len(tilt_deg), math.radians(pan_deg)), np.radians(tilt_deg))
    c, h = region.band.at(d)
    c = (c + math.pi) % (2.0 * math.pi) - math.pi
    outside = ~np.asarray(region.mesh.contains(d), dtype=bool)
    low, high = np.degrees(c - h), np.degrees(c + h)
    low[outside] = high[outside] = np.nan
    return low, high


def _band_width_panel(fig, ax, region: object, pan: np.ndarray, tilt: np.ndarray) -> None:
    """The learned band's width (deg) over the swing region, on a grid over the samples' span."""
    from limbctl.geometry.gimbal import pan_tilt_to_direction

    step = WIDTH_STEP_DEG
    gp = np.arange(math.floor(pan.min()) - step, pan.max() + step, step)
    gt = np.arange(math.floor(tilt.min()) - step, tilt.max() + step, step)
    p, t = np.meshgrid(gp, gt, indexing="xy")
    d = pan_tilt_to_direction(np.radians(p.ravel()), np.radians(t.ravel()))
    _, h = region.band.at(d)
    width = np.degrees(2.0 * h)
    width[~np.asarray(region.mesh.contains(d), dtype=bool)] = np.nan
    mesh = ax.pcolormesh(gp, gt, width.reshape(p.shape), cmap="YlGnBu", shading="nearest")
    fig.colorbar(mesh, ax=ax, label="learned band width (deg)")
    ax.set(
        xlabel="pan (deg)",
        ylabel="tilt (deg)",
        title="the learned twist band's width over the swing region",
        aspect="equal",
    )
