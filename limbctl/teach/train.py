"""Dataset -> model file: fit an envelope to recorded valid orientations and summarise it."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from limbctl.errors import ConfigError
from limbctl.geometry.gimbal import direction_to_pan_tilt, pan_tilt_to_direction
from limbctl.geometry.quat import direction_angle, limb_direction, swing_from_direction
from limbctl.geometry.twist import decompose, wrap
from limbctl.region.evidence import SETTLED_DEG


@dataclass(frozen=True)
class TrainSummary:
    """What a training run produced, in degrees: the ``samples`` and ``nodes``, the samples' and
    the learned region's (:func:`_region_extent`) pan and tilt extent, the samples' spread from
    their mean direction, the share of them the model holds, a Rigid Map gate's ``edge``
    (:data:`EDGE_MEANING`) and why it refused the others, whether the calibration was recorded;
    with twist, the band's lowest and highest limit, the samples left out (direction outside,
    or twist past the band, by a median and largest ``twist_excess_deg``), and one request per
    stretch of edge or band limit the teaching does not support, and the settled stretches."""

    samples: int
    pan_range_deg: tuple[float, float]
    tilt_range_deg: tuple[float, float]
    spread_deg: float
    boundary_pan_range_deg: tuple[float, float]
    boundary_tilt_range_deg: tuple[float, float]
    contained_fraction: float
    nodes: int
    edge: str = ""
    calibration_recorded: bool = True
    edge_refusals: tuple[str, ...] = ()
    twist_range_deg: tuple[float, float] | None = None
    outside_direction: int = 0
    outside_twist: int = 0
    twist_excess_deg: tuple[float, float] | None = None
    unsupported_edge: tuple[str, ...] = ()
    settled_edge: tuple[str, ...] = ()
    unsupported_twist: tuple[str, ...] = ()

    def _inside_line(self) -> str:
        line = f"samples inside     {100 * self.contained_fraction:.2f} %"
        if self.twist_range_deg is None:
            return line
        # what a three-servo region counts, and why the rest are out
        line += (
            " (direction in the region and twist in the band there)\n  out: "
            f"{self.outside_direction} directions past the region's edge, "
            f"{self.outside_twist} twists past the band's limits"
        )
        if self.twist_excess_deg is not None:
            line += (
                f" by {self.twist_excess_deg[0]:.2f} deg median, {self.twist_excess_deg[1]:.2f}"
                " at most (the limits run through the samples pressed against the twist stops)"
            )
        return line

    def lines(self) -> list[str]:
        """Human-readable summary lines."""
        lines = [
            f"samples            {self.samples}",
            f"pan range          {self.pan_range_deg[0]:+.1f} .. {self.pan_range_deg[1]:+.1f} deg",
            f"tilt range         {self.tilt_range_deg[0]:+.1f} .. "
            f"{self.tilt_range_deg[1]:+.1f} deg",
            f"angular spread     {self.spread_deg:.1f} deg from the mean direction",
            f"learned boundary   pan {self.boundary_pan_range_deg[0]:+.1f} .. "
            f"{self.boundary_pan_range_deg[1]:+.1f} deg, tilt "
            f"{self.boundary_tilt_range_deg[0]:+.1f} .. {self.boundary_tilt_range_deg[1]:+.1f} deg",
            *(
                []
                if self.twist_range_deg is None
                else [
                    f"learned twist      {self.twist_range_deg[0]:+.1f} .. "
                    f"{self.twist_range_deg[1]:+.1f} deg over the whole region (the band's limits)"
                ]
            ),
            *self._inside_line().split("\n"),
            f"nodes              {self.nodes}",
        ] + (
            [f"edge               {self.edge} ({EDGE_MEANING[self.edge]})"]
            + [f"  {line}" for line in self.edge_refusals]
            if self.edge in EDGE_MEANING
            else []
        )
        if not self.calibration_recorded:
            lines.append(
                "calibration        NOT RECORDED: the dataset predates recorded calibrations, "
                "so teleop will refuse this model; record again with this limbctl"
            )
        if self.unsupported_edge:
            lines.append(
                f"edge unsupported   {len(self.unsupported_edge)} stretches of the learned edge "
                "the taught samples do not reach (where held, the region stops at the evidence, "
                "short of where the edge may run, until they are taught):"
            )
            lines += [f"  {request}" for request in self.unsupported_edge]
        if self.settled_edge:
            lines.append(
                f"edge held          {len(self.settled_edge)} stretches where the learned edge "
                f"stood up to {SETTLED_DEG:g} deg past the taught samples or their outline (a "
                "traced notch it bridged), held at them (as near as a traced stop leaves the "
                "samples; nothing more to teach there):"
            )
            lines += [f"  {where}" for where in self.settled_edge]
        if self.unsupported_twist:
            lines.append(
                f"twist unsupported  {len(self.unsupported_twist)} stretches of the band the "
                "teaching could not support (held short of the reading there): record again "
                "and"
            )
            lines += [f"  {request}" for request in self.unsupported_twist]
        return lines


#: What each Rigid Map edge means, for the summary.
EDGE_MEANING = {
    "smooth": "fitted to where the samples end; the data agreed with it",
    "traced": "walked out to where the samples end, station by station; the data agreed",
    "supported": "through the outermost taught samples; corners and bays kept as taught",
}


def _range_deg(values: np.ndarray) -> tuple[float, float]:
    return (math.degrees(float(values.min())), math.degrees(float(values.max())))


def summarize(model: Any, q: np.ndarray) -> TrainSummary:
    """Describe a fitted model (an Envelope) and the training orientations ``q`` (N, 4)."""
    directions = limb_direction(q)
    pan, tilt = direction_to_pan_tilt(directions)
    mean = directions.mean(axis=0)
    mean /= np.linalg.norm(mean)
    spread = math.degrees(float(direction_angle(directions, mean).max()))
    # without the gate's kernels where a model can: ~2 s of a first train (decisions/first_run.md)
    contains = getattr(model, "contains_from_arcs", model.contains)
    inside = np.asarray(contains(q), dtype=bool)
    holds = holds_direction(model)
    b_pan, b_tilt = _region_extent(holds, pan, tilt)
    band = twist_band(model)
    stretches = getattr(swing_region(model), "unsupported_edge", ())
    twist: dict[str, Any] = {"outside_direction": int((~inside).sum())}
    if band is not None:
        direction_in = np.asarray(holds(swing_from_direction(directions)), dtype=bool)
        twist_out = ~inside & direction_in
        c, h = band.at(pan_tilt_to_direction(b_pan, b_tilt))
        # the band's limits c -+ h over every direction of the region, its centre read within
        # half a turn of its circular mean (the band keeps it unwrapped); a free band: any twist
        mean = math.atan2(float(np.sin(c).mean()), float(np.cos(c).mean()))
        c = mean + wrap(c - mean)
        low, high = (c - h).min(), (c + h).max()
        free = bool((h >= math.pi).any()) or high - low >= 2.0 * math.pi
        twist["twist_range_deg"] = (-180.0, 180.0) if free else _range_deg(np.array([low, high]))
        twist["outside_direction"] = int((~direction_in).sum())
        twist["outside_twist"] = int(twist_out.sum())
        if twist_out.any():
            d_out, tau_out = decompose(q[twist_out])
            c_out, h_out = band.at(d_out)
            excess = np.degrees(np.abs(wrap(tau_out - c_out)) - h_out)
            twist["twist_excess_deg"] = (float(np.median(excess)), float(excess.max()))
    return TrainSummary(
        samples=len(q),
        pan_range_deg=_range_deg(pan),
        tilt_range_deg=_range_deg(tilt),
        spread_deg=spread,
        boundary_pan_range_deg=_range_deg(b_pan),
        boundary_tilt_range_deg=_range_deg(b_tilt),
        contained_fraction=float(inside.mean()),
        nodes=len(model.weights),
        edge=str(getattr(model, "edge", "")),
        edge_refusals=tuple(
            f"{v.strategy} refused: {v.reasons[0]}"
            for v in getattr(getattr(model, "region", None), "verdicts", ())
            if not v.accepted
        ),
        unsupported_edge=tuple(
            f"trace the edge {stretch.line()}" for stretch in stretches if not stretch.settled
        ),
        settled_edge=tuple(stretch.line() for stretch in stretches if stretch.settled),
        unsupported_twist=tuple(
            place.words() for place in getattr(getattr(model, "region", None), "unsupported", ())
        ),
        **twist,
    )


def swing_region(model: Any) -> Any:
    """The model's swing region (a three-servo region's ``swing``), or None."""
    region = getattr(model, "region", None)
    return getattr(region, "swing", region)


def twist_band(model: Any) -> Any:
    """A three-servo region's twist band, or None for a model without twist."""
    return getattr(getattr(model, "region", None), "band", None)


def holds_direction(model: Any) -> Callable[[np.ndarray], np.ndarray]:
    """Which twist-free orientations' (N, 4) directions the region holds at some twist, (N,)."""
    swing = getattr(getattr(model, "region", None), "swing", None)
    if twist_band(model) is not None and swing is not None:
        return getattr(swing, "contains_from_arcs", swing.contains)
    return getattr(model, "contains_from_arcs", model.contains)


def _region_extent(
    holds: Callable[[np.ndarray], np.ndarray],
    pan: np.ndarray,
    tilt: np.ndarray,
    margin_deg: float = 20.0,
    step_deg: float = 0.5,
) -> tuple[np.ndarray, np.ndarray]:
    """Joint angles (rad) of the grid over the samples' extent whose direction the region holds."""
    from limbctl.geometry.gimbal import pan_tilt_to_quat

    margin, step = math.radians(margin_deg), math.radians(step_deg)
    pans = np.arange(max(pan.min() - margin, -math.pi), min(pan.max() + margin, math.pi), step)
    tilts = np.arange(
        max(tilt.min() - margin, -math.pi / 2), min(tilt.max() + margin, math.pi / 2), step
    )
    grid_pan, grid_tilt = (a.ravel() for a in np.meshgrid(pans, tilts))
    inside = np.asarray(holds(pan_tilt_to_quat(grid_pan, grid_tilt)), dtype=bool)
    if not inside.any():
        return pan, tilt
    return grid_pan[inside], grid_tilt[inside]


#: Fewest samples a model is fitted to: fewer cannot outline a region (seconds of recording).
MIN_SAMPLES = 10

#: The stages :func:`train` reports to its ``progress`` callback, in order.
STAGES = ("load dataset", "fit model", "save model", "summarise")


def learns_twist(kind: str, calibration: Any) -> bool:
    """Whether :func:`train` fits swing and twist: a Rigid Map of a three-servo recording."""
    return kind == "rigidmap" and calibration is not None and calibration.twists


def train(
    data_path: str | Path,
    out_path: str | Path,
    kind: str = "rigidmap",
    options: dict[str, Any] | None = None,
    progress: Callable[[str], None] | None = None,
) -> TrainSummary:
    """Fit a model of ``kind`` (constructor ``options``) to a recorded dataset, save it to
    ``out_path`` and summarise it; ``progress`` is called with each of :data:`STAGES` as it ends.
    ConfigError when the dataset holds fewer than :data:`MIN_SAMPLES` samples."""
    from limbctl.envelope import build_model
    from limbctl.teach.dataset import load_dataset

    done = progress or (lambda stage: None)
    data = load_dataset(data_path)
    q = data.quaternions
    done(STAGES[0])
    if len(q) < MIN_SAMPLES:
        raise ConfigError(
            f"{data_path}: only {len(q)} samples; record longer (at least a few seconds "
            "of moving the limb through its whole range)"
        )
    options = dict(options or {})
    if learns_twist(kind, data.header.calibration):
        options.setdefault("twist", True)
    model = build_model(kind, **options)
    model.fit(q)
    done(STAGES[1])
    metadata: dict[str, Any] = {
        "rig": data.header.rig,
        "dataset": str(data_path),
        "samples": len(q),
    }
    if data.header.calibration is not None:
        # the calibration the samples were read under; teleop refuses a rig with another one
        metadata["calibration"] = data.header.calibration.to_dict()
    model.save(out_path, metadata=metadata)
    done(STAGES[2])
    summary = summarize(model, q)
    done(STAGES[3])
    return dataclasses.replace(summary, calibration_recorded=data.header.calibration is not None)
