"""Constraint models of the valid-orientation region, behind one interface (see base.py)."""

from limbctl.envelope.base import Envelope, load_header, load_model

__all__ = ["Envelope", "load_header", "load_model"]
