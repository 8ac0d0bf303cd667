"""Error metrics of a constraint model's answers against Lee's ideal corrections: per row of
(N, 4) unit quaternions, reduced by :func:`score` (docs/results.md, "Metrics")."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from limbctl.errors import ConfigError
from limbctl.geometry.quat import direction_angle, geodesic_distance, limb_direction

#: Rotation (rad) within which an answer is "unchanged": far below a servo step, above rounding.
UNCHANGED_TOLERANCE = 1e-6

#: Names of the per-subset numbers :func:`score` returns, in table order.
METRIC_NAMES = tuple(
    "n mse err3d_rms angle_mean_deg angle_p95_deg unchanged_share inside_share "
    "outside_p95_deg".split()
)

#: The input subsets :func:`score` reports.
SUBSETS = ("all", "valid", "invalid")


def _pair(answer: np.ndarray, ideal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    answer = np.asarray(answer, dtype=np.float64)
    ideal = np.asarray(ideal, dtype=np.float64)
    if answer.shape != ideal.shape or answer.ndim != 2 or answer.shape[1] != 4:
        raise ConfigError(
            f"metrics need two (N, 4) quaternion arrays of one shape, got {answer.shape} "
            f"and {ideal.shape}"
        )
    return answer, ideal


def quaternion_sq_error(answer: np.ndarray, ideal: np.ndarray) -> np.ndarray:
    """Sign-aware squared R^4 distance per row (N,): ``min(|y - y*|^2, |y + y*|^2)``."""
    answer, ideal = _pair(answer, ideal)
    minus = np.sum((answer - ideal) ** 2, axis=1)
    plus = np.sum((answer + ideal) ** 2, axis=1)
    return np.minimum(minus, plus)


def endpoint_error(answer: np.ndarray, ideal: np.ndarray) -> np.ndarray:
    """Distance (N,) ``|d(y) - d(y*)|`` between the end points of a unit limb turned by each."""
    answer, ideal = _pair(answer, ideal)
    return np.linalg.norm(limb_direction(answer) - limb_direction(ideal), axis=1)


def direction_error_deg(answer: np.ndarray, ideal: np.ndarray) -> np.ndarray:
    """Angle (degrees) between the limb directions of answer and ideal, (N,)."""
    answer, ideal = _pair(answer, ideal)
    return np.degrees(direction_angle(limb_direction(answer), limb_direction(ideal)))


def unchanged(
    answer: np.ndarray, q: np.ndarray, tolerance: float = UNCHANGED_TOLERANCE
) -> np.ndarray:
    """Whether each answer is the input itself (rotation angle <= ``tolerance`` rad), (N,) bool."""
    answer, q = _pair(answer, q)
    return geodesic_distance(answer, q) <= tolerance


def score(
    q: np.ndarray,
    answer: np.ndarray,
    ideal: np.ndarray,
    valid: np.ndarray,
    inside: np.ndarray,
    outside_deg: np.ndarray | None = None,
) -> dict[str, dict[str, float]]:
    """All metrics on all inputs, on the valid ones and on the invalid ones.

    Parameters
    ----------
    q, answer, ideal : ndarray, shape (N, 4)
        Test inputs, the model's answers, Lee's ideal answers (the input itself when valid).
    valid, inside : ndarray, shape (N,) bool
        Whether each input, each answer lies in the true region.
    outside_deg : ndarray, shape (N,), optional
        How far each answer lies outside the true region (degrees, 0 inside); NaN if omitted.

    Returns
    -------
    dict
        ``{subset: {metric: value}}`` of :data:`SUBSETS` and :data:`METRIC_NAMES` (empty: NaN).
    """
    sq = quaternion_sq_error(answer, ideal)
    end = endpoint_error(answer, ideal)
    angle = direction_error_deg(answer, ideal)
    same = unchanged(answer, q)
    valid = np.asarray(valid, dtype=bool)
    inside = np.asarray(inside, dtype=bool)
    if outside_deg is None:
        outside_deg = np.full(sq.shape, math.nan)
    outside_deg = np.asarray(outside_deg, dtype=np.float64)
    if valid.shape != sq.shape or inside.shape != sq.shape or outside_deg.shape != sq.shape:
        raise ConfigError(
            f"valid {valid.shape}, inside {inside.shape} and outside_deg {outside_deg.shape} "
            f"must have one entry per row ({sq.shape[0]})"
        )
    masks = {"all": np.ones_like(valid), "valid": valid, "invalid": ~valid}
    out: dict[str, dict[str, float]] = {}
    for subset, mask in masks.items():
        n = int(mask.sum())
        if n == 0:
            out[subset] = {"n": 0.0} | {m: math.nan for m in METRIC_NAMES[1:]}
            continue
        out[subset] = {
            "n": float(n),
            # MSE = mean_i |y_i - y*_i|^2
            "mse": float(sq[mask].mean()),
            # 3D error = sqrt(mean_i |d(y_i) - d(y*_i)|^2)
            "err3d_rms": float(np.sqrt(np.mean(end[mask] ** 2))),
            "angle_mean_deg": float(angle[mask].mean()),
            "angle_p95_deg": float(np.percentile(angle[mask], 95.0)),
            "unchanged_share": float(same[mask].mean()),
            "inside_share": float(inside[mask].mean()),
            "outside_p95_deg": float(np.percentile(outside_deg[mask], 95.0)),
        }
    return out


def mean_and_spread(values: Any) -> tuple[float, float]:
    """Mean and sample standard deviation (ddof=1; 0 for a single value), ignoring NaN."""
    arr = np.asarray(values, dtype=np.float64)
    arr = arr[np.isfinite(arr)]
    if arr.size == 0:
        return math.nan, math.nan
    spread = float(arr.std(ddof=1)) if arr.size > 1 else 0.0
    return float(arr.mean()), spread
