"""The live view: a local web page that shows teaching and teleop as they happen."""

from limbctl.view.server import ViewServer
from limbctl.view.state import (
    Board,
    EdgeLoop,
    GuideFigure,
    HardLimits,
    Live,
    PanTilt,
    Scene,
    TeleopStatus,
    thin_samples,
)

__all__ = [
    "Board",
    "EdgeLoop",
    "GuideFigure",
    "HardLimits",
    "Live",
    "PanTilt",
    "Scene",
    "TeleopStatus",
    "ViewServer",
    "thin_samples",
]
