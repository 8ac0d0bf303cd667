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
        Most thinned samples the shape is built on: 3000 bounds the triangulation's time and
        still covers 55 x 55 deg at 1 deg.
    thin_deg : float
        Smallest spacing (deg) of the thinned samples: 1 deg makes a 125 Hz recording look like
        scattered samples.
    alpha_factor : float
        Alpha radius in 90th-percentile enclosed-gap radii: 2 closes gaps between strokes.
    hole_fraction : float
        Holes smaller than this share of the area are filled: 0.2, the spaces between strokes.
    peel_factor : float
        Exposed edges longer than this many median spacings are peeled: 8, far past neighbours.
    min_peel_deg : float
        Least peel length (deg): 4, a few thinned spacings, never taken for a bridge.
    surround_deg : float
        Surround neighbourhood (deg) for the peel: 6, several spacings, tells middle from edge.
    max_margin_deg : float
        Most (deg) the supported loops widen: 0.75, the outermost samples' gap at a sparse edge.
    max_offset_deg : float
        Most (deg) a learned edge moves out in one step: 3, a few gaps at a sparse edge.
    edge : str
        ``"auto"`` (smooth, else traced, else supported) or one strategy by name
        (:data:`limbctl.region.edge_choice.EDGE_CHOICES`).
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
