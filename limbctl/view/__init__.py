"""The live view: a local web page that shows teaching and teleop as they happen.

The app publishes plain values (:mod:`limbctl.view.state`) on a :class:`Board`; a
:class:`ViewServer` (:mod:`limbctl.view.server`) serves the page and pushes the newest values to
each browser at its own pace.
"""

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
