"""The taught region the gate enforces: its shape, its edge and the mesh that answers queries. Built
from taught samples (positions of real poses), not from any network's weights (``docs/region.md``).
Imports :mod:`limbctl.geometry` and :mod:`limbctl.errors` only."""

from limbctl.region.params import RegionParams
from limbctl.region.taught import TaughtRegion

__all__ = ["RegionParams", "TaughtRegion"]
