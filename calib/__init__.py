"""Rig profiles: the data both the controller and its tools read (see calib.profile)."""

from calib.profile import (
    SIM_RIGS,
    Calibration,
    JointCalibration,
    JointProfile,
    ProfileError,
    RigProfile,
    calibration_from_dict,
    default_sim_profile,
    load_profile,
    profile_from_dict,
    save_profile,
)

__all__ = [
    "SIM_RIGS",
    "Calibration",
    "JointCalibration",
    "JointProfile",
    "ProfileError",
    "RigProfile",
    "calibration_from_dict",
    "default_sim_profile",
    "load_profile",
    "profile_from_dict",
    "save_profile",
]
