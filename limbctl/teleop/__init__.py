"""Teleoperation: command sources, the gate every pose passes, and the control loop.

May import only the layers below it (envelope, region, servo, geometry, errors, calib); never
teach, view or the app. The gate takes any model with ``contains`` and ``correct``.
"""
