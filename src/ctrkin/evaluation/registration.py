"""Rigid registration between the robot base frame and the tracker frame (paper IV.A: "the
transformation matrix was used to map the coordinates between the TCM and the learning-based model").
The type lives in ctrkin.pose (learned models use it too); this module keeps its old import path.
"""

from ctrkin.pose import Registration

__all__ = ["Registration"]
