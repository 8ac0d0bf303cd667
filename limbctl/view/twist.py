"""A three-servo limb's twist on the live page: a map over the swing plane and a gauge."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from limbctl.geometry.gimbal import pan_tilt_to_direction, pose_quat_scalar
from limbctl.geometry.twist import decompose_one

#: A cell's states: recording, ``turned`` (both ways to the stops), ``short`` (a stop untaught),
#: ``few`` (too few samples); teleop, the learned ``band`` at its centre or ``free``.
CELL_STATES = ("turned", "short", "few", "band", "free")
#: Cell size (deg) of the learned band's picture: ~1200 cells (~30 kB) for a 230 x 125 deg rig.
BAND_CELL_DEG = 5.0
#: A half-width this close to 180 deg (rad) is a free twist: the band's fit stores pi there.
FREE_HALF = math.pi - 1e-9


@dataclass(frozen=True)
class TwistMap:
    """Twist ranges over the swing plane, cell by cell (``of``: ``"taught"`` or ``"band"``).

    Parameters
    ----------
    cell_deg : float
        Cell size, deg; cell ``(i, j)`` covers pan ``[i, i + 1) * cell_deg``, tilt likewise.
    cells : ndarray, shape (M, 4)
        ``(i, j, low_deg, high_deg)`` per cell; ``states`` one of :data:`CELL_STATES` per cell.
    """

    cell_deg: float
    cells: np.ndarray
    states: tuple[str, ...]
    of: str

    def __post_init__(self) -> None:
        cells = np.asarray(self.cells, dtype=np.float64).reshape(-1, 4)
        states = tuple(self.states)
        if len(states) != len(cells):
            raise ValueError(f"a twist map has {len(cells)} cells but {len(states)} states")
        unknown = sorted(set(states) - set(CELL_STATES))
        if unknown:
            raise ValueError(f"unknown cell states {unknown}; choose from {CELL_STATES}")
        object.__setattr__(self, "cells", cells)
        object.__setattr__(self, "states", states)
        index = {(int(c[0]), int(c[1])): k for k, c in enumerate(cells)}
        object.__setattr__(self, "_index", index)

    def at(self, pan_deg: float, tilt_deg: float) -> tuple[float, float, str] | None:
        """The range ``(low_deg, high_deg, state)`` of the cell holding a pose, None if none."""
        key = (math.floor(pan_deg / self.cell_deg), math.floor(tilt_deg / self.cell_deg))
        k = self._index.get(key)  # type: ignore[attr-defined]
        if k is None:
            return None
        return float(self.cells[k, 2]), float(self.cells[k, 3]), self.states[k]

    def to_json(self) -> dict[str, object]:
        rows = [
            [int(c[0]), int(c[1]), round(float(c[2]), 2), round(float(c[3]), 2), s]
            for c, s in zip(self.cells, self.states, strict=True)
        ]
        return {"cell": float(self.cell_deg), "of": self.of, "cells": rows}


@dataclass(frozen=True)
class TwistGauge:
    """The present ``twist_deg`` (deg, in (-180, 180]) against the range ``low_deg`` .. ``high_deg``
    (deg, inside when ``low <= twist_deg + 360 k <= high``; None: unknown) at its place, the
    range's ``of`` in words and the twist last ``written`` (teleop; else None)."""

    twist_deg: float
    low_deg: float | None = None
    high_deg: float | None = None
    of: str = ""
    written_deg: float | None = None

    def to_json(self) -> dict[str, object]:
        def deg(value: float | None) -> float | None:
            return None if value is None else round(float(value), 2)

        return {
            "twist": deg(self.twist_deg),
            "low": deg(self.low_deg),
            "high": deg(self.high_deg),
            "of": self.of,
            "written": deg(self.written_deg),
        }


def pose_twist(pan: float, tilt: float, roll: float) -> float:
    """Twist (rad, (-pi, pi]) of a three-joint pose (rad), as the twist guide and region see it."""
    return decompose_one(pose_quat_scalar(pan, tilt, roll))[1]


def taught_gauge(twist: TwistMap | None, pan: float, tilt: float, roll: float) -> TwistGauge:
    """The gauge while recording: the pose's (rad) twist against its cell's taught range."""
    tau = math.degrees(pose_twist(pan, tilt, roll))
    found = twist.at(math.degrees(pan), math.degrees(tilt)) if twist is not None else None
    if found is None:
        return TwistGauge(tau, of="nothing taught here yet")
    low, high, _ = found
    return TwistGauge(tau, low, high, "taught here")


def band_gauge(band, pose: tuple[float, float, float], written: float | None) -> TwistGauge:
    """The teleop gauge: the pose's (rad) twist against the learned ``band`` at its direction."""
    d, tau = decompose_one(pose_quat_scalar(*pose))
    c, h = band.at(np.asarray(d, dtype=np.float64))
    centre, half = float(c[0]), float(h[0])
    # the band's centre is unwrapped across the plane: the turn of it nearest the twist
    centre -= 2.0 * math.pi * round((centre - tau) / (2.0 * math.pi))
    written_deg = None if written is None else math.degrees(written)
    if half >= FREE_HALF:
        return TwistGauge(math.degrees(tau), of="free here", written_deg=written_deg)
    low, high = math.degrees(centre - half), math.degrees(centre + half)
    return TwistGauge(math.degrees(tau), low, high, "the learned band here", written_deg)


def taught_map(places, cell_deg: float, min_samples: int) -> TwistMap:
    """The twist guide's ``TwistPlace`` cells as a :class:`TwistMap` (few samples: ``few``)."""
    cells = [(p.pan_index, p.tilt_index, p.low_deg, p.high_deg) for p in places]
    states = [
        "few" if p.samples < min_samples else "turned" if p.turned else "short" for p in places
    ]
    return TwistMap(cell_deg, np.asarray(cells, dtype=np.float64), tuple(states), "taught")


def band_map(
    band, mesh, pan_deg: tuple[float, float], tilt_deg: tuple[float, float], cell_deg: float
) -> TwistMap:
    """The learned ``band`` over the ``cell_deg`` cells within the pan and tilt ranges (deg) whose
    centre the swing region ``mesh`` holds: each cell's ``centre -+ half-width`` (``free``: any)."""
    i = np.arange(math.floor(pan_deg[0] / cell_deg), math.ceil(pan_deg[1] / cell_deg))
    j = np.arange(math.floor(tilt_deg[0] / cell_deg), math.ceil(tilt_deg[1] / cell_deg))
    ij = np.stack(np.meshgrid(i, j, indexing="ij"), axis=-1).reshape(-1, 2).astype(np.float64)
    middle = np.radians((ij + 0.5) * cell_deg)
    d = pan_tilt_to_direction(middle[:, 0], middle[:, 1])
    inside = np.asarray(mesh.contains(d), dtype=bool)
    ij, d = ij[inside], d[inside]
    if not len(d):
        return TwistMap(cell_deg, np.zeros((0, 4)), (), "band")
    c, h = band.at(d)
    # centres wrapped into (-180, 180] for reading; the half-width is the band's own
    c = (c + math.pi) % (2.0 * math.pi) - math.pi
    free = h >= FREE_HALF
    low, high = np.degrees(c - h), np.degrees(c + h)
    cells = np.column_stack([ij, low, high])
    return TwistMap(cell_deg, cells, tuple("free" if f else "band" for f in free), "band")


def model_band_map(envelope, pan_deg, tilt_deg, cell_deg: float = BAND_CELL_DEG):
    """:func:`band_map` of a model learned with twist; None for a model without a twist band."""
    region = getattr(envelope, "region", None)
    band = getattr(region, "band", None)
    mesh = getattr(region, "mesh", None)
    if band is None or mesh is None:
        return None
    return band_map(band, mesh, pan_deg, tilt_deg, cell_deg)
