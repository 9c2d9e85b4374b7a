"""Export a trained model to ONNX, normalisation included.

    from ctrkin.inference import Kinematics, export_onnx
    export_onnx(Kinematics.load("models/fk"), "fk.onnx")

The ONNX graph maps "window": (B, IB, F) float32 raw features (Kinematics.feature_windows: the
layout's input_names, un-normalised, oldest step first) to "output": (B, O) float32 in user units
(FK: tip pose with unit quaternion; IK: joints). Metadata props record the task, IB, feature and output
names and the robot fingerprint.
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import torch
from torch import nn

from ctrkin.errors import ModelError
from ctrkin.inference.kinematics import Kinematics
from ctrkin.util.files import atomic_path


class ExportWrapper(nn.Module):
    """normalise -> network -> denormalise (-> unit quaternion for FK), all in float32."""

    def __init__(self, kin: Kinematics) -> None:
        super().__init__()
        self.net = kin.net
        f32 = lambda a: torch.tensor(a, dtype=torch.float32)  # noqa: E731
        self.xlo: torch.Tensor
        self.xspan: torch.Tensor
        self.ylo: torch.Tensor
        self.yspan: torch.Tensor
        self.register_buffer("xlo", f32(kin.bundle.x_norm.lo))
        self.register_buffer("xspan", f32(kin.bundle.x_norm.span))
        self.register_buffer("ylo", f32(kin.bundle.y_norm.lo))
        self.register_buffer("yspan", f32(kin.bundle.y_norm.span))
        self.fk = kin.task == "fk"

    def forward(self, window: torch.Tensor) -> torch.Tensor:
        y = self.net((window - self.xlo) / self.xspan) * self.yspan + self.ylo
        if self.fk:
            q = y[:, 3:6]
            norm = torch.linalg.vector_norm(q, dim=1, keepdim=True).clamp_min(1e-12)
            y = torch.cat([y[:, :3], q / norm], 1)
        return y


def export_onnx(kin: Kinematics, path: str | Path, opset: int = 17) -> Path:
    """Write `kin` as an ONNX file (dynamic batch size); returns the path."""
    import onnx

    wrapper = ExportWrapper(kin).eval()
    example = torch.zeros(2, kin.ib, kin.layout.n_inputs)
    out = Path(path)
    with atomic_path(out) as tmp:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")   # legacy-exporter deprecation, tracer and LSTM notes
                torch.onnx.export(wrapper, (example,), str(tmp), input_names=["window"],
                                  output_names=["output"], opset_version=opset, dynamo=False,
                                  dynamic_axes={"window": {0: "batch"}, "output": {0: "batch"}})
        except Exception as e:  # the exporter raises many types
            raise ModelError(f"ONNX export failed for model {kin.config['model']!r}: {e}") from None
        model = onnx.load(str(tmp))
        meta = {"task": kin.task, "ib": str(kin.ib), "input_names": json.dumps(list(kin.layout.input_names)),
                "output_names": json.dumps(list(kin.layout.output_names)),
                "robot_fingerprint": kin.robot.fingerprint(), "model": kin.config["model"]}
        for k, v in meta.items():
            p = model.metadata_props.add()
            p.key, p.value = f"ctrkin.{k}", v
        onnx.save(model, str(tmp))
    return out
