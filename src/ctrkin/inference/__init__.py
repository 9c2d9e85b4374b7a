"""Using trained kinematics: batch and streaming prediction, IK workspace check, ONNX export.

    import ctrkin
    fk = ctrkin.Kinematics.load("models/fk")
    poses = fk.predict(Q)            # (T, 2N) -> (T, 6)
    fk.reset(); pose = fk.step(Q[0])
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ctrkin.util.lazy import lazy_attributes

__all__ = ["IKResult", "IKStep", "Kinematics", "Workspace", "export_onnx"]

if TYPE_CHECKING:   # imported on first use instead (ctrkin.util.lazy)
    from ctrkin.inference.kinematics import IKResult, IKStep, Kinematics
    from ctrkin.inference.onnx_export import export_onnx
    from ctrkin.models.workspace import Workspace

__getattr__, __dir__ = lazy_attributes(__name__, __file__)
