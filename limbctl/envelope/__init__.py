"""Constraint models of the valid-orientation region, behind one interface (see base.py).

Every model kind registers itself by name when its class is defined; :func:`build_model`,
:func:`model_kinds` and :func:`load_model` use that one registry. The kinds are imported here in
the order :data:`MODEL_KINDS` lists them (the first is the default of ``limbctl train``).
"""

from limbctl.envelope.base import (
    Envelope,
    build_model,
    load_header,
    load_model,
    model_class,
    model_kinds,
)
from limbctl.envelope.layouts import LAYOUTS, make_layout

# isort: off
# the kinds register in this order, which MODEL_KINDS keeps
from limbctl.envelope.rigidmap import RigidMap
from limbctl.envelope.som import SOM
from limbctl.envelope.cone import Cone

# isort: on

#: Every model kind by name: rigidmap, som, cone.
MODEL_KINDS = model_kinds()

__all__ = ["Envelope", "build_model", "load_header", "load_model", "model_class", "model_kinds"]
__all__ += ["MODEL_KINDS", "RigidMap", "SOM", "Cone", "LAYOUTS", "make_layout"]
