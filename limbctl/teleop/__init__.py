"""Teleoperation: command sources, the gate every pose passes, and the control loop."""
