"""Using trained kinematics: batch and streaming prediction, IK workspace check, ONNX export.

    import ctrkin
    fk = ctrkin.Kinematics.load("models/fk")
    poses = fk.predict(Q)            # (T, 2N) -> (T, 6)
    fk.reset(); pose = fk.step(Q[0])
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ctrkin.util.lazy import lazy_attributes

_WHERE = {
    "IKResult": "ctrkin.inference.kinematics", "IKStep": "ctrkin.inference.kinematics",
    "Kinematics": "ctrkin.inference.kinematics", "export_onnx": "ctrkin.inference.onnx_export",
    "Workspace": "ctrkin.inference.workspace",
}

__all__ = ["IKResult", "IKStep", "Kinematics", "Workspace", "export_onnx"]

__getattr__, __dir__ = lazy_attributes(__name__, _WHERE)

if TYPE_CHECKING:
    from ctrkin.inference.kinematics import IKResult, IKStep, Kinematics
    from ctrkin.inference.onnx_export import export_onnx
    from ctrkin.inference.workspace import Workspace
