"""Rigid registration between the robot base frame and the tracker frame (paper IV.A: "the
transformation matrix was used to map the coordinates between the TCM and the learning-based model").
The type is ctrkin.geometry.RigidTransform (learned models and the virtual tracker use it too); this
module keeps its old import path.
"""

from ctrkin.geometry import Registration

__all__ = ["Registration"]
