"""The servo layer (the only one that knows ticks): the Dynamixel bus and the rig on top of it."""
