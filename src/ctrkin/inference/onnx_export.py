"""Export a trained model to ONNX, normalisation included (the graph: ctrkin.models.onnx_graph).

    from ctrkin.inference import Kinematics, export_onnx
    export_onnx(Kinematics.load("models/fk"), "fk.onnx")

Each family says what its graph holds (a snap-aware model's state input, an outer lag input) or why
it has none (the follow IK's joint state loops outside its network).
"""

from __future__ import annotations

from pathlib import Path

from ctrkin.inference.kinematics import Kinematics


def export_onnx(kin: Kinematics, path: str | Path, opset: int = 17) -> Path:
    """Write `kin` as an ONNX file (dynamic batch size); returns the path."""
    out = Path(path)
    kin.predictor.export_onnx(out, opset)
    return out
