"""The settings of the taught region (:class:`RegionParams`), one frozen object."""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

from limbctl.errors import ConfigError
from limbctl.region.edge_choice import check_choice

_POSITIVE = ("thin_deg", "alpha_factor", "peel_factor", "min_peel_deg", "surround_deg")
_FLOATS = (*_POSITIVE, "hole_fraction", "max_margin_deg", "max_offset_deg")


@dataclass(frozen=True)
class RegionParams:
    """How the gate's region is built from taught samples (see :mod:`limbctl.region.taught`).

    Attributes
    ----------
    support_nodes : int
        Most thinned samples the shape is built on; the spacing grows until they fit. 3000
        bounds the time of the triangulation and peel, while a 1 deg spacing still covers a
        region of about 3000 deg^2 (55 x 55 deg) in full.
    thin_deg : float
        Smallest spacing (deg) of the thinned samples. 1 deg makes a 125 Hz hand recording
        (samples a fraction of a degree apart along a stroke) look like scattered samples; the
        outermost samples are kept, so the edge loses nothing.
    alpha_factor : float
        The alpha shape's radius in units of the 90th percentile empty-circle radius of the
        gaps the samples enclose. 2 closes the gaps between a hand's strokes while concavities
        wider than those gaps stay open.
    hole_fraction : float
        Holes smaller than this fraction of the region's area are filled: 0.2 fills the
        spaces between strokes, a hole a fifth of the region is taught as a hole.
    peel_factor : float
        An exposed edge longer than this many median sample spacings bridges a gap in the data
        and is peeled away (unless the samples surround it). 8 spacings is far longer than any
        edge between neighbouring samples.
    min_peel_deg : float
        The peel length (deg) is at least this, however dense the samples: a gap narrower than
        4 deg (a few thinned spacings) is never taken for a bridge.
    surround_deg : float
        Radius (deg) of the neighbourhood whose samples must surround a triangle for the peel
        to keep it: 6 deg, several thinned spacings, holds enough samples to tell the middle of
        the data (samples all around) from its edge (samples on one side).
    max_margin_deg : float
        The most (deg) the supported loops are widened beyond the outermost samples: 0.75 deg,
        about the gap the outermost samples leave at a sparsely taught edge.
    max_offset_deg : float
        The most (deg) a learned edge moves out in one step (past the smooth edge's fitted
        curve; past the traced curve in one round): 3 deg, a few sample gaps at a sparse edge.
    edge : str
        Which edge: ``"auto"`` (smooth, else traced, else supported), or one strategy by name
        (:data:`limbctl.region.edge_choice.EDGE_CHOICES`); ``"supported"`` keeps the loops
        through the outermost samples.
    """

    support_nodes: int = 3000
    thin_deg: float = 1.0
    alpha_factor: float = 2.0
    hole_fraction: float = 0.2
    peel_factor: float = 8.0
    min_peel_deg: float = 4.0
    surround_deg: float = 6.0
    max_margin_deg: float = 0.75
    max_offset_deg: float = 3.0
    edge: str = "auto"

    def __post_init__(self) -> None:
        for name, kind in (("support_nodes", int), *((n, float) for n in _FLOATS)):
            object.__setattr__(self, name, kind(getattr(self, name)))
        if self.support_nodes < 3:
            raise ConfigError(f"support_nodes must be >= 3, got {self.support_nodes}")
        for name in _POSITIVE:
            value = getattr(self, name)
            if not value > 0.0:
                raise ConfigError(f"{name} must be > 0, got {value}")
        for name in _FLOATS[len(_POSITIVE) :]:
            value = getattr(self, name)
            if not value >= 0.0:
                raise ConfigError(f"{name} must be >= 0, got {value}")
        check_choice(self.edge)

    def as_dict(self) -> dict[str, Any]:
        """The settings as plain values (for a model file's header)."""
        return asdict(self)

    @classmethod
    def from_dict(cls, values: dict[str, Any]) -> RegionParams:
        """Inverse of :meth:`as_dict`; unknown names are refused with the list of settings."""
        unknown = set(values) - set(cls.__dataclass_fields__)
        if unknown:
            raise ConfigError(
                f"unknown region settings {', '.join(sorted(unknown))}; choose from: "
                f"{', '.join(cls.__dataclass_fields__)}"
            )
        return cls(**values)
