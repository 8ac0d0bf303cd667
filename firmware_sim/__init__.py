"""A byte-level simulated Dynamixel X-series bus (Protocol 2.0) on a pseudo-terminal; it never
imports limbctl (the controller and the simulator meet only on the wire)."""

from firmware_sim.bus import SimulatedBus

__all__ = ["SimulatedBus"]
