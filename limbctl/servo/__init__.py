"""The servo layer: the Dynamixel bus through the real dynamixel-sdk, and the rig on top of it.

Only this layer knows servo ticks; it imports :mod:`limbctl.errors` and :mod:`calib`, nothing
above.
"""
