"""Lee's analytic swing cone: the ground truth of the papers' experiments and a hand-written limit.
Inside: swing ``2 acos(sqrt(w^2 + x^2)) <= R``, any twist; the ideal correction keeps twist and
swing axis (also the nearest boundary point in R^4)."""

from __future__ import annotations

from typing import Any

import numpy as np

from limbctl.envelope import interpolation as ip
from limbctl.envelope.base import Envelope
from limbctl.errors import ConfigError
from limbctl.geometry.quat import as_quaternions, swing_angle

#: Slack of ``contains`` (w^2 + x^2 >= cos^2(R/2) - tol) so ``correct``'s rounded boundary points
#: count as inside: 2e-12 / sin(R) rad at most, far below a servo step.
CONTAINS_TOLERANCE = 1e-12


class Cone(Envelope):
    """Swing cone of half-angle R about +x, any twist (Lee). Exact and analytic. R is
    ``half_angle`` (rad, 0 <= R <= pi) or ``half_angle_deg`` (deg, keyword only); with neither,
    :meth:`fit` learns R as the largest swing angle in the training data."""

    kind = "cone"

    def __init__(
        self, half_angle: float | None = None, *, half_angle_deg: float | None = None
    ) -> None:
        if half_angle is not None and half_angle_deg is not None:
            raise ConfigError("Cone: give half_angle (rad) or half_angle_deg, not both")
        if half_angle_deg is not None:
            half_angle = np.radians(_check_number(half_angle_deg, "half_angle_deg"))
        self._half_angle = None if half_angle is None else _check_half_angle(half_angle)

    @property
    def half_angle(self) -> float:
        """R in radians."""
        if self._half_angle is None:
            raise ConfigError("Cone has no half angle yet: give half_angle= or call fit(q_train)")
        return self._half_angle

    @property
    def half_angle_deg(self) -> float:
        """R in degrees."""
        return float(np.degrees(self.half_angle))

    def fit(self, q_train: np.ndarray) -> Cone:
        """Check valid orientations ``q_train`` (N, 4), N >= 1 (R learned if unset); self."""
        q, _ = as_quaternions(q_train)
        if len(q) == 0:
            raise ConfigError("Cone.fit: q_train is empty; give at least one orientation")
        if self._half_angle is None:
            self._half_angle = _check_half_angle(float(np.max(swing_angle(q))))
        return self

    def respond(self, q: np.ndarray, interpolation: str = "none", k: int = 8) -> np.ndarray:
        """Lee's ideal answer, :meth:`correct` (``interpolation`` and ``k`` checked, not used)."""
        ip.interpolation_code(interpolation)
        ip.check_k(k)
        return self.correct(q)

    @property
    def weights(self) -> np.ndarray:
        """No nodes: an empty (0, 4) array."""
        return np.empty((0, 4), dtype=np.float64)

    def _inside(self, q: np.ndarray) -> np.ndarray:
        limit = np.cos(0.5 * self.half_angle) ** 2
        # valid iff w^2 + x^2 >= cos^2(R/2)   (tolerance: see CONTAINS_TOLERANCE)
        return q[:, 0] ** 2 + q[:, 1] ** 2 >= limit - CONTAINS_TOLERANCE

    def _to_boundary(self, q: np.ndarray) -> np.ndarray:
        """Lee's correction to swing angle R."""
        c = np.cos(0.5 * self.half_angle)
        s = np.sin(0.5 * self.half_angle)
        out = np.empty_like(q)
        # (w, x) -> c (w, x) / n, n = sqrt(w^2 + x^2): keep the twist; n = 0 -> the identity twist
        tw, tx, no_twist = _unit_pair(q[:, 0], q[:, 1])
        out[:, 0] = np.where(no_twist, c, c * tw)
        out[:, 1] = np.where(no_twist, 0.0, c * tx)
        # (y, z) -> s (y, z) / m, m = sqrt(y^2 + z^2): keep the swing axis (m > 0 outside)
        sy, sz, _ = _unit_pair(q[:, 2], q[:, 3])
        out[:, 2] = s * sy
        out[:, 3] = s * sz
        return out

    def _params(self) -> dict[str, Any]:
        return {"half_angle": self._half_angle}

    def _arrays(self) -> dict[str, np.ndarray]:
        return {}

    @classmethod
    def _restore(cls, params: dict[str, Any], arrays: dict[str, np.ndarray]) -> Cone:
        return cls(params["half_angle"])

    def __repr__(self) -> str:
        if self._half_angle is None:
            return "Cone(half_angle=None)"
        return f"Cone(half_angle_deg={self.half_angle_deg:.6g})"


def _unit_pair(u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(u, v) / hypot(u, v) (N,) each, exact for subnormal pairs; 0 where both are zero, and the
    (N,) mask of those."""
    big = np.maximum(np.abs(u), np.abs(v))
    zero = big == 0.0
    big = np.where(zero, 1.0, big)
    u, v = u / big, v / big
    norm = np.hypot(u, v)
    norm = np.where(zero, 1.0, norm)
    return u / norm, v / norm, zero


def _check_number(value: object, name: str) -> float:
    if isinstance(value, bool):
        raise ConfigError(f"Cone: {name} must be a number, got {value!r}")
    try:
        number = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise ConfigError(f"Cone: {name} must be a number, got {value!r}") from None
    if not np.isfinite(number):
        raise ConfigError(f"Cone: {name} must be finite, got {value!r}")
    return number


def _check_half_angle(value: object) -> float:
    r = _check_number(value, "half_angle")
    if not 0.0 <= r <= np.pi:
        raise ConfigError(
            f"Cone: half_angle must lie in [0, pi] rad (0..180 deg), got {r!r} rad; "
            f"use half_angle_deg= for degrees"
        )
    return r
