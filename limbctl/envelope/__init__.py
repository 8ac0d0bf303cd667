"""Constraint models of the valid-orientation region, behind one interface (see base.py)."""

from limbctl.envelope.base import Envelope, load_header, load_model
from limbctl.envelope.cone import Cone
from limbctl.envelope.layouts import LAYOUTS, make_layout
from limbctl.envelope.som import SOM

__all__ = ["Envelope", "load_header", "load_model"]
__all__ += ["Cone", "LAYOUTS", "make_layout"]
__all__ += ["SOM"]
from limbctl.envelope.rigidmap import RigidMap  # noqa: E402

__all__ += ["RigidMap"]
