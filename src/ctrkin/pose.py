"""Tip pose conventions: the old import path of ctrkin.geometry (kept for users' code)."""

from ctrkin.geometry import (
    POSE_COLUMNS,
    Registration,
    RigidTransform,
    position_error,
    quat_from_tangent,
    quaternion_angle,
    tangent_angle_error,
    tangent_from_quat,
    tip_azimuth,
    tip_pose,
)

__all__ = ["POSE_COLUMNS", "Registration", "RigidTransform", "position_error", "quat_from_tangent",
           "quaternion_angle", "tangent_angle_error", "tangent_from_quat", "tip_azimuth", "tip_pose"]
