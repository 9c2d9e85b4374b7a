"""Using trained kinematics: batch and streaming prediction, IK workspace check, ONNX export.

    import ctrkin
    fk = ctrkin.Kinematics.load("models/fk")
    poses = fk.predict(Q)            # (T, 2N) -> (T, 6)
    fk.reset(); pose = fk.step(Q[0])
"""

from ctrkin.inference.kinematics import IKResult, IKStep, Kinematics
from ctrkin.inference.onnx_export import export_onnx
from ctrkin.inference.workspace import Workspace

__all__ = ["IKResult", "IKStep", "Kinematics", "Workspace", "export_onnx"]
