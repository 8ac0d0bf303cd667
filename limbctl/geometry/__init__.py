"""Geometry: unit quaternions (scalar first, canonical w >= 0) and the gimbal's kinematics;
radians, the limb resting along +x. Imports only :mod:`limbctl.errors`."""
