"""Pictures of a dataset or a model: the pan/tilt plane (deg), the region shaded by the model's
``contains`` on a grid, and the unit sphere of limb directions."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from limbctl.geometry.gimbal import direction_to_pan_tilt, pan_tilt_to_direction
from limbctl.geometry.quat import limb_direction, swing_from_direction


def _pan_tilt_deg(directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pan and tilt (deg), (N,) each, of directions (N, 3)."""
    pan, tilt = direction_to_pan_tilt(directions)
    return np.degrees(pan), np.degrees(tilt)


def region_grid(
    model: Any, pan_deg: tuple[float, float], tilt_deg: tuple[float, float], n: int = 200
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(P, T, inside) (n, n) each: the pan/tilt grid (deg) and the directions the region holds."""
    from limbctl.teach.train import holds_direction

    pans = np.linspace(*pan_deg, n)
    tilts = np.linspace(*tilt_deg, n)
    grid_pan, grid_tilt = np.meshgrid(pans, tilts)
    directions = pan_tilt_to_direction(np.radians(grid_pan), np.radians(grid_tilt)).reshape(-1, 3)
    inside = np.asarray(holds_direction(model)(swing_from_direction(directions)), dtype=bool)
    return grid_pan, grid_tilt, inside.reshape(grid_pan.shape)


def plot(
    out: str | Path,
    samples: np.ndarray | None = None,
    model: Any = None,
    title: str = "",
    extra: dict[str, np.ndarray] | None = None,
    outlines: dict[str, np.ndarray] | None = None,
) -> Path:
    """Draw samples and/or a model to the PNG file ``out`` (under ``title``); returns its path.

    Parameters
    ----------
    samples : ndarray, shape (N, 4), optional
        Recorded orientations.
    model : Envelope, optional
        A fitted model; its region is shaded and its node weights near the data drawn.
    extra : dict of name -> (M, 3) directions, optional
        More point sets to draw (e.g. commanded and corrected poses).
    outlines : dict of name -> (M, 2) pan/tilt in degrees, optional
        Closed outlines drawn on the plane and the sphere (e.g. the hand's true region).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(12, 5.5))
    ax_plane = fig.add_subplot(1, 2, 1)
    ax_sphere = fig.add_subplot(1, 2, 2, projection="3d")

    pan_lim, tilt_lim = (-180.0, 180.0), (-90.0, 90.0)
    if samples is not None and len(samples):
        sp, st = _pan_tilt_deg(limb_direction(samples))
        margin = 25.0  # degrees around the samples: room to see the region's edge beyond them
        pan_lim = (max(-180.0, sp.min() - margin), min(180.0, sp.max() + margin))
        tilt_lim = (max(-90.0, st.min() - margin), min(90.0, st.max() + margin))
    for outline in (outlines or {}).values():
        # an outline is drawn whole, with a little room around it
        pan_lim = (max(-180.0, min(pan_lim[0], outline[:, 0].min() - 5.0)), pan_lim[1])
        pan_lim = (pan_lim[0], min(180.0, max(pan_lim[1], outline[:, 0].max() + 5.0)))
        tilt_lim = (max(-90.0, min(tilt_lim[0], outline[:, 1].min() - 5.0)), tilt_lim[1])
        tilt_lim = (tilt_lim[0], min(90.0, max(tilt_lim[1], outline[:, 1].max() + 5.0)))

    if model is not None:
        grid_pan, grid_tilt, inside = region_grid(model, pan_lim, tilt_lim)
        ax_plane.contourf(
            grid_pan, grid_tilt, inside.astype(float), levels=[0.5, 1.5], colors=["#cfe8cf"]
        )
        ax_plane.contour(
            grid_pan, grid_tilt, inside.astype(float), levels=[0.5], colors="green", linewidths=1
        )
        weights = np.asarray(model.weights)
        if len(weights):
            wd = limb_direction(weights)
            wp, wt = _pan_tilt_deg(wd)
            near = (
                (wp >= pan_lim[0]) & (wp <= pan_lim[1]) & (wt >= tilt_lim[0]) & (wt <= tilt_lim[1])
            )
            ax_plane.scatter(wp[near], wt[near], s=3, c="0.45", label="node weights")
            ax_sphere.scatter(*wd[near].T, s=2, c="0.45")
    if samples is not None and len(samples):
        sd = limb_direction(samples)
        sp, st = _pan_tilt_deg(sd)
        ax_plane.scatter(sp, st, s=1, c="tab:blue", alpha=0.3, label=f"samples ({len(sp)})")
        ax_sphere.scatter(*sd.T, s=1, c="tab:blue", alpha=0.3)
    for (name, outline), color in zip((outlines or {}).items(), ("tab:orange", "tab:brown")):
        closed = np.vstack([outline, outline[:1]])
        ax_plane.plot(closed[:, 0], closed[:, 1], color=color, lw=1.5, ls="--", label=name)
        od = pan_tilt_to_direction(np.radians(closed[:, 0]), np.radians(closed[:, 1]))
        ax_sphere.plot(*od.T, color=color, lw=1.2, ls="--")
    styles = [("tab:red", "x", 10), ("k", ".", 4), ("tab:purple", "+", 10)]
    for (name, directions), (color, marker, size) in zip((extra or {}).items(), styles):
        ep, et = _pan_tilt_deg(np.asarray(directions))
        ax_plane.scatter(ep, et, s=size, c=color, marker=marker, linewidths=0.6, label=name)
        ax_sphere.scatter(*np.asarray(directions).T, s=size / 2, c=color, marker=marker)

    ax_plane.set_xlim(*pan_lim)
    ax_plane.set_ylim(*tilt_lim)
    ax_plane.set_xlabel("pan (deg)")
    ax_plane.set_ylabel("tilt (deg)")
    ax_plane.set_aspect("equal")
    ax_plane.grid(alpha=0.3)
    ax_plane.legend(loc="upper right", fontsize=8, markerscale=3)
    ax_plane.set_title("pan/tilt plane (shaded: learned region)")

    # wireframe unit sphere for orientation
    u, v = np.meshgrid(np.linspace(0, 2 * math.pi, 25), np.linspace(0, math.pi, 13))
    ax_sphere.plot_wireframe(
        np.cos(u) * np.sin(v), np.sin(u) * np.sin(v), np.cos(v), color="0.85", lw=0.4
    )
    ax_sphere.quiver(0, 0, 0, 1.2, 0, 0, color="k", lw=1)
    ax_sphere.text(1.25, 0, 0, "rest (+x)")
    ax_sphere.set_box_aspect((1, 1, 1))
    ax_sphere.view_init(elev=20, azim=-30)
    ax_sphere.set_title("limb directions on the unit sphere")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    out = Path(out)
    fig.savefig(out, dpi=110)  # 1320 x 605 pixels: the whole figure on one screen
    plt.close(fig)
    return out


def plot_leader(path: Path, t: np.ndarray, leader: np.ndarray, follower: np.ndarray, torque):
    """The demo's leader run to PNG ``path``: leader versus follower pose, and the leader's push.

    Parameters
    ----------
    t, torque : ndarray (N,)
        Cycle times (s); the leader's push (N m; 0 inside the region).
    leader, follower : ndarray (N, 2) or (N, 3)
        Pan, tilt (deg) of the leader and the follower; a third column, the twist (deg).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    twist = leader.shape[1] == 3
    fig, axes = plt.subplots(3 if twist else 2, 1, figsize=(10, 8 if twist else 6), sharex=True)
    ax_pose, ax_force = axes[0], axes[-1]
    for k, name in enumerate(("pan", "tilt")):
        ax_pose.plot(t, leader[:, k], label=f"leader {name} (the operator's hand)")
        ax_pose.plot(t, follower[:, k], "--", label=f"follower {name} (gated)")
    ax_pose.set_ylabel("deg")
    ax_pose.legend(loc="best", fontsize=8)
    ax_pose.set_title("leader vs follower: the follower stops at the edge, the leader is pushed")
    if twist:
        axes[1].plot(t, leader[:, 2], label="leader twist (the operator's hand)")
        axes[1].plot(t, follower[:, 2], "--", label="follower twist (gated)")
        axes[1].set_ylabel("twist (deg)")
        axes[1].legend(loc="best", fontsize=8)
    ax_force.plot(t, torque, color="crimson")
    ax_force.set_ylabel("leader push (N m)" + (", largest joint" if twist else ""))
    ax_force.set_xlabel("s")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
