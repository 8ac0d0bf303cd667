"""Geometry: unit quaternions (scalar first, canonical w >= 0) and the gimbal's kinematics.

Angles are radians here; the limb rests along +x. Imports only :mod:`limbctl.errors`.
"""
