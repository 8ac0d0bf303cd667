"""The servo layer: the Dynamixel bus through the real dynamixel-sdk, and the rig on top of it.

``control_table`` (typed register names), ``transfers`` (one SDK call each, classified),
``bus`` (retries, alarms, exclusive access), ``setup`` (one-time configuration), ``ticks``
(joint angle <-> encoder tick), ``profiles`` (rig profiles checked against the servos), ``rig``
(a calibrated gimbal: pose in, goal ticks out), ``calibrate`` (find zero ticks and directions).
Only this layer knows servo ticks. It imports :mod:`limbctl.geometry`, :mod:`limbctl.errors`
and :mod:`calib`, nothing above.
"""
