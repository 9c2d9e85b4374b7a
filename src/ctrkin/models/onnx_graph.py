"""A trained network as an ONNX graph, normalisation included (`ctrkin export`,
ctrkin.inference.export_onnx; each family's predictor calls `write_onnx`).

The graph maps "window": (B, IB, F) float32 raw features (Kinematics.feature_windows: the
layout's input_names, un-normalised, oldest step first; a layout with play lags holds them among its
columns, computed along the path by the caller as ctrkin.models.play_lags does) to "output": (B, O)
float32 in user units
(FK: tip pose with unit quaternion; IK: joints). Metadata props record the task, IB, feature and output
names and the robot fingerprint. A network that carries a state (`stateful`: the snap-aware model,
whose net has `forward_state`) has a second input "state": (B,) float32, the previous state (0.5 at
a sequence start), and a second output "state_out": the new one, to be fed back at the next step.
The graph holds its learned gate: it predicts as `Kinematics.predict(..., gate="learned")`; a fold
gate (ctrkin.families.snap_aware.fold_gate) is not exported.
A model whose outer frame has a transmission lag (ctrkin.models.frame, outer_lag) has one more input
"outer_lag_deg": (B,) float32, λ(β)·m_N: how far the outer tube lags its command (deg; 0 at rest,
λ after a forward turn of the outer motor, −λ after a backward one); metadata "ctrkin.outer_lag_deg"
holds (a, b) of λ = a + b·curved_overlap(β) (ctrkin.robots.overlap). A model that learned with
lagged inputs (OuterFrame.lagged_inputs, every such model trained since) has no such input: its
window's αN column is already the outer tube's angle αN − λ(β)·m_N (Kinematics.feature_windows), and
"ctrkin.outer_lag_deg" holds (a, b) so that a caller can compute it; "ctrkin.lagged_inputs" says so.

Inputs the torch path refuses give no answer here either: a row whose inputs are not all finite
(NaN, ±inf; window, state or lag) gives NaN outputs (ONNX Runtime's ReLU and LSTM would turn a NaN
window into a finite pose), and so does an IK row with a target whose quaternion is not unit within
QUAT_NORM_TOL (ctrkin.models.guards.check_poses). An empty batch gives empty outputs, as
`Kinematics.predict` does: the graph runs one padding row after the batch and drops it (ONNX
Runtime's LSTM aborts the process on a batch of 0 rows).
"""

from __future__ import annotations

import json
import math
import warnings
from pathlib import Path
from typing import Any

import torch
from torch import nn

from ctrkin.data.schema import QUAT_NORM_TOL
from ctrkin.errors import ModelError
from ctrkin.models.frame import OuterFrame
from ctrkin.models.joint_field import FieldLayer
from ctrkin.models.store import ModelBundle
from ctrkin.util.files import atomic_path


class ExportWrapper(nn.Module):
    """normalise -> network -> denormalise (-> unit quaternion, tracker frame for FK), in float32."""

    def __init__(self, bundle: ModelBundle, net: nn.Module, frame: OuterFrame | None, stateful: bool) -> None:
        super().__init__()
        self.net: Any = net
        f32 = lambda a: torch.tensor(a, dtype=torch.float32)  # noqa: E731
        self.x_norm, self.y_norm = bundle.x_norm.torch(), bundle.y_norm.torch()
        layout = bundle.layout
        self.fk = layout.task == "fk"
        self.stateful = stateful
        self.frame = frame is not None
        # a lagged frame needs λ(β)·m_N as an input, unless the window's αN already is the frame's angle
        self.lag = frame is not None and frame.has_lag and not frame.lags_inputs
        self.rot: torch.Tensor
        self.trans: torch.Tensor
        reg = frame.registration if frame is not None else None
        self.register_buffer("rot", f32(reg.rotation if reg is not None else torch.eye(3).numpy()))
        self.register_buffer("trans", f32(reg.translation if reg is not None else torch.zeros(3).numpy()))
        # the frame's position field (ctrkin.models.field), added to the tracker-frame position
        self.field = None if frame is None or frame.field is None else FieldLayer.from_field(frame.field)
        n = layout.n_tubes
        self.window_shape = (layout.ib, layout.n_inputs)
        self.alpha_col = 2 * (n - 1) if layout.angle_encoding == "sincos" else n - 1
        self.sincos = layout.angle_encoding == "sincos"

    def forward(self, window: torch.Tensor, *extra: torch.Tensor
                ) -> torch.Tensor | tuple[torch.Tensor, torch.Tensor]:
        """extra: the state (B,) of a net that carries one, then the outer lag λ(β)·m_N (B,) deg of a
        frame with a lag (ctrkin.models.frame), in this order. Rows with a non-finite input give NaN;
        an empty batch an empty output (module docstring)."""
        bad = ~torch.isfinite(window).flatten(1).all(dim=1)
        if not self.fk:             # IK: every target of the window has a unit quaternion (q0, qx, qy)
            norm = torch.linalg.vector_norm(window[:, :, 3:6], dim=2)
            bad = bad | ((norm - 1.0).abs() > QUAT_NORM_TOL).any(dim=1)
        for e in extra:
            bad = bad | ~torch.isfinite(e)
        # one padding row (a sequence start: state 0.5, no lag), dropped below
        window = torch.cat([window, window.new_zeros((1, *self.window_shape))])
        extra = tuple(torch.cat([e, e.new_full((1,), 0.5 if k == 0 and self.stateful else 0.0)])
                      for k, e in enumerate(extra))
        x = self.x_norm.transform(window)
        lag = extra[-1] if self.lag else None
        nan = torch.full((1,), math.nan)
        if self.stateful:
            yn, new_state = self.net.forward_state(x, extra[0])
            y = self._finish(yn, window, lag)[:-1]
            return torch.where(bad[:, None], nan, y), torch.where(bad, nan, new_state[:-1])
        return torch.where(bad[:, None], nan, self._finish(self.net(x), window, lag)[:-1])

    def _finish(self, yn: torch.Tensor, window: torch.Tensor, lag: torch.Tensor | None = None
                ) -> torch.Tensor:
        y = self.y_norm.inverse(yn)
        if self.fk:
            q = y[:, 3:6]
            q = q / torch.linalg.vector_norm(q, dim=1, keepdim=True).clamp_min(1e-12)
            if self.frame:      # outer-tube frame -> tracker frame (ctrkin.models.frame)
                last = window[:, -1]
                a = torch.atan2(last[:, self.alpha_col], last[:, self.alpha_col + 1]) if self.sincos \
                    else last[:, self.alpha_col] * (math.pi / 180.0)
                if lag is not None:
                    a = a - lag * (math.pi / 180.0)
                c, s = torch.cos(a), torch.sin(a)
                w, qx, qy = q[:, 0], q[:, 1], q[:, 2]
                tan = torch.stack([2 * w * qy, -2 * w * qx, 1 - 2 * (qx * qx + qy * qy)], 1)
                pos, tan = (torch.stack([c * v[:, 0] - s * v[:, 1], s * v[:, 0] + c * v[:, 1], v[:, 2]], 1)
                            for v in (y[:, :3], tan))
                pos, tan = pos @ self.rot.T + self.trans, tan @ self.rot.T
                if self.field is not None:
                    pos = self.field(pos)
                q = torch.stack([1.0 + tan[:, 2], -tan[:, 1], tan[:, 0]], 1)   # geometry.quat_from_tangent
                q = q / torch.linalg.vector_norm(q, dim=1, keepdim=True).clamp_min(1e-12)
                return torch.cat([pos, q], 1)
            y = torch.cat([y[:, :3], q], 1)
        return y



def write_onnx(bundle: ModelBundle, net: nn.Module, path: str | Path, opset: int = 17,
               frame: OuterFrame | None = None, stateful: bool = False) -> Path:
    """Write `net` of `bundle` (its outer frame `frame`; `stateful`: a state input and output) as an
    ONNX file with a dynamic batch size; returns the path."""
    import onnx

    layout, robot, config = bundle.layout, bundle.robot, bundle.config
    wrapper = ExportWrapper(bundle, net, frame, stateful).eval()
    example: tuple[torch.Tensor, ...] = (torch.zeros(2, layout.ib, layout.n_inputs),)
    names, outputs = ["window"], ["output"]
    axes = {"window": {0: "batch"}, "output": {0: "batch"}}
    if stateful:
        example += (torch.full((2,), 0.5),)
        names.append("state")
        outputs.append("state_out")
        axes.update({"state": {0: "batch"}, "state_out": {0: "batch"}})
    if wrapper.lag:
        example += (torch.zeros(2),)
        names.append("outer_lag_deg")
        axes["outer_lag_deg"] = {0: "batch"}
    out = Path(path)
    with atomic_path(out) as tmp:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")   # legacy-exporter deprecation, tracer and LSTM notes
                torch.onnx.export(wrapper, example, str(tmp), input_names=names, output_names=outputs,
                                  opset_version=opset, dynamo=False, dynamic_axes=axes)
        except Exception as e:  # the exporter raises many types
            raise ModelError(f"ONNX export failed for model {config.model!r}: {e}") from None
        model = onnx.load(str(tmp))
        meta = {"task": layout.task, "ib": str(layout.ib),
                "input_names": json.dumps(list(layout.input_names)),
                "output_names": json.dumps(list(layout.output_names)),
                "robot_fingerprint": robot.fingerprint(), "model": config.model}
        if frame is not None and frame.has_lag:
            meta["outer_lag_deg"] = json.dumps(list(frame.lag))   # λ = a + b·overlap(β), deg
            meta["lagged_inputs"] = json.dumps(frame.lags_inputs)
        for k, v in meta.items():
            p = model.metadata_props.add()
            p.key, p.value = f"ctrkin.{k}", v
        onnx.save(model, str(tmp))
    return out
