"""A live picture of teaching coverage in the terminal: where in pan/tilt samples have landed."""

from __future__ import annotations

import math

import numpy as np

#: Characters for increasing sample counts per cell (empty, few, some, many).
SHADES = " .:*#"


class CoverageMap:
    """Counts samples on a pan/tilt grid and draws it as text.

    Parameters
    ----------
    pan_range_deg, tilt_range_deg : tuple of float
        Extent of the picture (degrees).
    cols, rows : int
        Size of the picture in characters.
    """

    def __init__(
        self,
        pan_range_deg: tuple[float, float] = (-180.0, 180.0),
        tilt_range_deg: tuple[float, float] = (-90.0, 90.0),
        cols: int = 48,
        rows: int = 12,
    ) -> None:
        self.pan_range = pan_range_deg
        self.tilt_range = tilt_range_deg
        self.counts = np.zeros((rows, cols), dtype=np.int64)
        self.samples = 0
        self._sum = np.zeros(3)
        self._directions: list[np.ndarray] = []

    def add(self, pan_rad: float, tilt_rad: float) -> None:
        """Count one sample (joint angles in radians)."""
        rows, cols = self.counts.shape
        pan, tilt = math.degrees(pan_rad), math.degrees(tilt_rad)
        # cell = floor((value - lo) / (hi - lo) * cells), clipped to the picture
        c = int((pan - self.pan_range[0]) / (self.pan_range[1] - self.pan_range[0]) * cols)
        r = int((self.tilt_range[1] - tilt) / (self.tilt_range[1] - self.tilt_range[0]) * rows)
        self.counts[min(max(r, 0), rows - 1), min(max(c, 0), cols - 1)] += 1
        self.samples += 1
        d = np.array(
            [
                math.cos(tilt_rad) * math.cos(pan_rad),
                math.cos(tilt_rad) * math.sin(pan_rad),
                math.sin(tilt_rad),
            ]
        )
        self._sum += d
        self._directions.append(d)

    def spread_deg(self) -> float:
        """Largest angle between a sample and the samples' mean direction (degrees)."""
        if not self._directions:
            return 0.0
        mean = self._sum / max(np.linalg.norm(self._sum), 1e-12)
        dots = np.clip(np.asarray(self._directions) @ mean, -1.0, 1.0)
        return math.degrees(float(np.arccos(dots.min())))

    def cells_visited(self) -> int:
        return int((self.counts > 0).sum())

    def render(self) -> list[str]:
        """The picture as lines, tilt up, pan to the left (as seen from behind the limb)."""
        peak = max(int(self.counts.max()), 1)
        lines = []
        top = f"tilt {self.tilt_range[1]:+.0f}"
        lines.append(top)
        for row in self.counts:
            # shade index = ceil(count / peak * (levels - 1)), so one sample is visible
            idx = np.ceil(row[::-1] / peak * (len(SHADES) - 1)).astype(int)
            lines.append("|" + "".join(SHADES[i] for i in idx) + "|")
        lines.append(
            f"tilt {self.tilt_range[0]:+.0f}   pan {self.pan_range[1]:+.0f} (left) .. "
            f"{self.pan_range[0]:+.0f} (right)"
        )
        return lines
