"""Where the twist range is still untaught, on a three-servo rig (docs/teaching.md): cells of the
swing plane each keep the least and greatest twist taught there; once every cell is turned to
both stops, the band learned from the samples names the stops it cannot support.
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass

import numpy as np

from limbctl.geometry import jit
from limbctl.geometry.gimbal import direction_to_pan_tilt
from limbctl.geometry.twist import decompose
from limbctl.region.twist_band import TwistBand
from limbctl.region.twist_evidence import UnsupportedPlace, band_unsupported

#: Cell size (deg of pan and tilt): a shoulder's band changes under 10 deg across one, and a
#: minute's teaching fills each with hundreds of samples.
CELL_DEG = 15.0
#: Samples before a cell is judged: a quarter second at 125 Hz passing through.
MIN_CELL_SAMPLES = 30
#: The widest spans: this quantile of the judged cells' spans.
WIDE_QUANTILE = 0.9
#: Share of the wide span that counts as turned to both stops: the band narrows by up to a half.
TURNED_FRACTION = 0.5
#: Seconds between support checks while recording: a ~0.5 s band fit, a tenth of the time at most.
SUPPORT_EVERY_S = 5.0


@dataclass(frozen=True)
class TwistPlace:
    """One cell of the swing plane: pan in ``[pan_index, pan_index + 1) * CELL_DEG`` (deg), tilt
    likewise; the least and greatest twist (deg) of its ``samples``; whether judged and turned;
    where its samples lie (their mean pan and tilt, deg: inside the region, where a cell the
    edge cuts has its centre outside)."""

    pan_index: int
    tilt_index: int
    low_deg: float
    high_deg: float
    samples: int
    turned: bool
    pan_deg: float = math.nan
    tilt_deg: float = math.nan


@dataclass(frozen=True)
class TwistGuidance:
    """How much of the twist range has been taught: ``cells`` judged (MIN_CELL_SAMPLES or more),
    of those ``turned`` to both stops (span at least TURNED_FRACTION of ``wide_span_deg``, the
    WIDE_QUANTILE of the judged spans), the cell turned ``least`` (its samples' mean pan and tilt,
    and its span, deg; None when none is judged), every cell visited (``places``), and where the
    last support check (run once every place was turned) found a stop missing (``unsupported``)."""

    cells: int
    turned: int
    wide_span_deg: float
    least: tuple[float, float, float] | None
    places: tuple[TwistPlace, ...] = ()
    unsupported: tuple[UnsupportedPlace, ...] = ()
    support_checked: bool = False

    @property
    def complete(self) -> bool:
        """Every place turned both ways and the band's support checked, nothing missing."""
        return (
            self.cells > 0
            and self.turned == self.cells
            and self.support_checked
            and not self.unsupported
        )

    def line(self) -> str:
        """One line of words and figures for the progress line and the summary."""
        if self.cells == 0 or self.least is None:
            return "twist: not yet taught; turn the limb both ways to its stop as you go"
        pan, tilt, span = self.least
        head = (
            f"twist: {self.turned} of {self.cells} places turned both ways "
            f"(widest {self.wide_span_deg:.0f} deg)"
        )
        if self.turned == self.cells and self.unsupported:
            return f"{head}; {len(self.unsupported)} stretches unsupported: " + (
                self.unsupported[0].words()
            )
        if self.turned == self.cells:
            checked = "" if self.support_checked else " (checking the band's support)"
            return head + "; every place visited was turned both ways" + checked
        return (
            f"{head}; least at pan {pan:+.0f}, tilt {tilt:+.0f}: {span:.0f} deg -> turn the "
            "limb both ways to its stop there"
        )

    def short(self) -> str:
        """The line's figures and place in a few words (the recorder's terminal line)."""
        if self.cells == 0 or self.least is None:
            return "twist: turn both ways to the stops"
        head = f"twist {self.turned}/{self.cells} turned"
        if self.turned == self.cells and self.unsupported:
            place = self.unsupported[0]
            return f"{head}, {place.side} stop at ({place.pan_deg:+.0f}, {place.tilt_deg:+.0f})"
        if self.turned == self.cells:
            return head
        pan, tilt, span = self.least
        return f"{head}, least {span:.0f} deg at ({pan:+.0f}, {tilt:+.0f})"


class TwistGuide:
    """Collects full orientations and says where the twist is untaught (module docstring)."""

    def __init__(self) -> None:
        self._cells: dict[tuple[int, int], list[float]] = {}
        self.samples = 0
        self._q: list[np.ndarray] = []
        self._support: tuple[UnsupportedPlace, ...] | None = None
        self._checking: threading.Thread | None = None
        self._checked_at = -math.inf

    def add(self, q: np.ndarray) -> None:
        """One sample's full orientation (4,)."""
        self.samples += 1
        self._q.append(np.asarray(q, dtype=np.float64))
        d, tau = decompose(np.asarray(q, dtype=np.float64))
        pan, tilt = direction_to_pan_tilt(d)
        key = (
            math.floor(math.degrees(float(pan)) / CELL_DEG),
            math.floor(math.degrees(float(tilt)) / CELL_DEG),
        )
        twist = math.degrees(float(tau))
        pan_deg, tilt_deg = math.degrees(float(pan)), math.degrees(float(tilt))
        cell = self._cells.get(key)
        if cell is None:
            # least, greatest twist, count, first twist, sums of pan and tilt
            self._cells[key] = [twist, twist, 1.0, twist, pan_deg, tilt_deg]
        else:
            # the turn of the twist nearest the cell's first: first + wrap(twist - first)
            twist = cell[3] + (twist - cell[3] + 180.0) % 360.0 - 180.0
            cell[0], cell[1], cell[2] = min(cell[0], twist), max(cell[1], twist), cell[2] + 1.0
            cell[4] += pan_deg
            cell[5] += tilt_deg

    def assess(self) -> TwistGuidance:
        """The guidance from the samples so far."""
        judged = [(key, c) for key, c in self._cells.items() if c[2] >= MIN_CELL_SAMPLES]
        if not judged:
            return TwistGuidance(0, 0, 0.0, None, self._places(math.inf))
        spans = np.array([c[1] - c[0] for _, c in judged])
        wide = float(np.quantile(spans, WIDE_QUANTILE))
        turned = int(np.sum(spans >= TURNED_FRACTION * wide))
        k = int(np.argmin(spans))
        _, c = judged[k]
        # where its samples lie: a cell the edge cuts has its centre outside the region
        centre = (c[4] / c[2], c[5] / c[2], float(spans[k]))
        places = self._places(TURNED_FRACTION * wide)
        if turned == len(judged):
            self._check_later()
        support = () if self._support is None else self._support
        return TwistGuidance(
            len(judged), turned, wide, centre, places, support, self._support is not None
        )

    def check_support(self) -> tuple[UnsupportedPlace, ...]:
        """Learn the band from every sample so far; the places it could not support. Blocks."""
        if self._checking is not None:
            self._checking.join()
        self._support = _unsupported(np.array(self._q))
        return self._support

    def _check_later(self) -> None:
        """Start a support check in a thread, at most every SUPPORT_EVERY_S."""
        now = time.monotonic()
        busy = self._checking is not None and self._checking.is_alive()
        if busy or now - self._checked_at < SUPPORT_EVERY_S:
            return
        self._checked_at = now
        # a fit before the warm-up cached the kernels would compile for seconds in the recorder
        if not jit.prepared(jit.stage("train", True)):
            return
        q = np.array(self._q)

        def run() -> None:
            self._support = _unsupported(q)

        self._checking = threading.Thread(target=run, name="twist-support", daemon=True)
        self._checking.start()

    def _places(self, turned_span: float) -> tuple[TwistPlace, ...]:
        """Every cell visited; judged cells whose span reaches ``turned_span`` (deg) turned."""
        return tuple(
            TwistPlace(
                *(i, j, c[0], c[1], int(c[2])),
                c[2] >= MIN_CELL_SAMPLES and c[1] - c[0] >= turned_span,
                c[4] / c[2],
                c[5] / c[2],
            )
            for (i, j), c in self._cells.items()
        )


def _unsupported(q: np.ndarray) -> tuple[UnsupportedPlace, ...]:
    """The places a band learned from orientations ``q`` (N, 4) could not support, or none."""
    if q.shape[0] < 3:
        return ()
    d, tau = decompose(q)
    axis = d.mean(axis=0)
    try:
        band = TwistBand.fit(d, tau, axis / np.linalg.norm(axis), 0.0)
    except ValueError:
        return ()
    return band_unsupported(band, d)
