"""Constraint models of the valid-orientation region, behind one interface (see base.py); each
kind registers by name when its class is defined, in the order :data:`MODEL_KINDS` lists them."""

from limbctl.envelope.base import (
    Envelope,
    build_model,
    load_header,
    load_model,
    model_class,
    model_kinds,
)

# isort: off
# the kinds register in this order, which MODEL_KINDS keeps
from limbctl.envelope.rigidmap import RigidMap
from limbctl.envelope.som import SOM
from limbctl.envelope.cone import Cone

# isort: on

#: Every model kind by name: rigidmap, som, cone.
MODEL_KINDS = model_kinds()

__all__ = ["Envelope", "build_model", "load_header", "load_model", "model_class", "model_kinds"]
__all__ += ["MODEL_KINDS", "RigidMap", "SOM", "Cone"]
