"""Teleoperation: command sources, the gate every pose passes, and the control loop.

Imports the layers below (envelope, region, servo, geometry); never teach or the app.
"""
