"""The tracker's position field learned with the FK, not after it (TrainConfig.joint_field;
docs/learned_kinematics.md: A position field learned with the FK).

ctrkin.models.field fits a field w(p) of the tip's tracker-frame position to the residuals of an FK
that has finished training. A network with the absolute angles among its inputs has by then learned
most of the field as a function of the joints, which it interpolates badly at outer angles no
training turn had. Here w is a layer of the training itself: the network's position outputs in the
outer tube's frame (ctrkin.models.frame) are taken to the tracker frame inside the loss, w is added,
and the MAE is of tracker-frame positions:

    p̂ = u + w(u),   u = R · Rz(θ) · (p_local + p_prior) + t,   w(u) = Σ_k c_k · ((u − centre) / scale)^k

(monomials of total degree ≤ DEGREE, as ctrkin.models.field; θ the frame's outer angle; p_prior the
calibrated TCM's position where the network learns its residual). The gradient then decides what
belongs to the joints (the network) and what to the place in space (w); nothing about the field's
physics is assumed beyond smoothness over the workspace. After training w goes into the frame
(OuterFrame.field), so every prediction path applies it as it applies a field fitted after
training, but only where it lowers the validation rows' position error (field_if_it_helps): an
optical tracker has no field to learn, and on a small set the layer would only fit the training
rows' noise.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from torch import nn

from ctrkin.models.field import PositionField, exponents
from ctrkin.models.normalize import MinMax

# Total degree of w: 20 monomials per axis. Not tuned: the post-hoc field's cross-validation
# (ctrkin.models.field.DEGREES) picks degrees up to 4 on the virtual robots' data; 3 keeps the
# layer's terms in step with the network's on the few outer angles of a training set.
DEGREE = 3


class FieldLayer(nn.Module):
    """p -> p + w(p) in torch (module docstring), coefficients c (M, 3) mm learned, starting at 0."""

    def __init__(self, centre: np.ndarray, scale: float, degree: int = DEGREE) -> None:
        super().__init__()
        exps = exponents(degree)
        self.centre: torch.Tensor
        self.exps: torch.Tensor
        self.register_buffer("centre", torch.as_tensor(np.asarray(centre, np.float32)))
        self.register_buffer("exps", torch.as_tensor(exps.astype(np.float32)))
        self.scale = float(scale)
        self.coef = nn.Parameter(torch.zeros(len(exps), 3))

    @classmethod
    def from_field(cls, field: PositionField) -> FieldLayer:
        """The layer of a PositionField (float32; the ONNX graph's, ctrkin.models.onnx_graph)."""
        layer = cls(field.centre, field.scale)
        layer.exps = torch.as_tensor(np.asarray(field.exps, np.float32))
        layer.coef = nn.Parameter(torch.as_tensor(np.asarray(field.coef, np.float32)), requires_grad=False)
        return layer

    def forward(self, p: torch.Tensor) -> torch.Tensor:
        u = (p - self.centre) / self.scale
        return p + torch.prod(u[:, None, :] ** self.exps[None], dim=2) @ self.coef

    def position_field(self, rms_with: float, rms_without: float) -> PositionField:
        """The learned w as a PositionField (float64), with the validation rows' position RMS with
        and without it in place of a cross-validated figure."""
        exps = self.exps.numpy().astype(np.int64)
        return PositionField(self.centre.numpy().astype(np.float64), self.scale, exps,
                             self.coef.detach().numpy().astype(np.float64), 0.0, rms_with, rms_without)


@dataclass(eq=False)
class TrackerLoss:
    """The MAE with positions in the tracker frame through a FieldLayer (module docstring). Per
    dataset row: cos / sin of the frame's angle θ (T,), the prior's local positions (T, 3) or None,
    and the tracker-frame positions learned from (T, 3); `span` (3,) their training range, by which
    position errors are divided so that they weigh as the normalised outputs' do."""

    lo: torch.Tensor              # (3,) the position outputs' min-max lo and span (y_norm)
    y_span: torch.Tensor
    cos: torch.Tensor
    sin: torch.Tensor
    prior: torch.Tensor | None
    target: torch.Tensor
    rotation: torch.Tensor        # the frame's registration R (3, 3), t (3,)
    translation: torch.Tensor
    span: torch.Tensor

    @classmethod
    def build(cls, y_norm: MinMax, outer_deg: np.ndarray, prior_local: np.ndarray | None,
              target: np.ndarray, rotation: np.ndarray, translation: np.ndarray, train: np.ndarray
              ) -> TrackerLoss:
        def f32(a: np.ndarray) -> torch.Tensor:
            return torch.as_tensor(np.ascontiguousarray(a, dtype=np.float32))

        a = np.radians(np.asarray(outer_deg, float))
        span = MinMax.fit(target[train, :3]).span
        return cls(f32(y_norm.lo[:3]), f32(y_norm.span[:3]), f32(np.cos(a)), f32(np.sin(a)),
                   None if prior_local is None else f32(prior_local[:, :3]), f32(target[:, :3]),
                   f32(rotation), f32(translation), f32(span))

    def unfielded(self, y_hat: torch.Tensor, rows: torch.Tensor) -> torch.Tensor:
        """(B, 3) tracker-frame positions u of normalised outputs y_hat (B, O) at dataset rows."""
        dev = y_hat.device
        p = self.lo.to(dev) + y_hat[:, :3] * self.y_span.to(dev)
        if self.prior is not None:
            p = p + self.prior[rows].to(dev)
        c, s = self.cos[rows].to(dev), self.sin[rows].to(dev)
        turned = torch.stack([c * p[:, 0] - s * p[:, 1], s * p[:, 0] + c * p[:, 1], p[:, 2]], dim=1)
        return turned @ self.rotation.to(dev).T + self.translation.to(dev)

    def loss(self, field: FieldLayer, y_hat: torch.Tensor, y: torch.Tensor, rows: torch.Tensor
             ) -> torch.Tensor:
        """The MAE over all outputs: positions |p̂ − p| / span in the tracker frame, the rest
        normalised as the network gives them (paper IV.A's loss, its positions moved)."""
        dev = y_hat.device
        pos = (field(self.unfielded(y_hat, rows)) - self.target[rows].to(dev)).abs() / self.span.to(dev)
        return torch.cat([pos, (y_hat[:, 3:] - y[:, 3:]).abs()], dim=1).mean()


def field_if_it_helps(layer: FieldLayer, predicted: np.ndarray, measured: np.ndarray
                      ) -> tuple[PositionField | None, float, float]:
    """The layer's field where it lowers the position RMS of held-out rows (predicted (T, 3): the
    network's tracker-frame positions without it; measured (T, 3)), else None (a tracker with no
    field to learn, an optical one, where the layer can only fit the training rows' noise); and the
    two RMS figures (mm), with and without it."""
    with torch.no_grad():
        fielded = layer(torch.from_numpy(np.asarray(predicted, np.float32))).numpy().astype(np.float64)
    rms = [float(np.sqrt(np.nanmean(np.sum((measured - p) ** 2, axis=1)))) for p in (fielded, predicted)]
    return (layer.position_field(*rms) if rms[0] < rms[1] else None), rms[0], rms[1]


def field_layer(net: nn.Module) -> FieldLayer:
    """The FieldLayer that training attached to `net` (WindowRecipe.attach)."""
    layer = getattr(net, "joint_field", None)
    if not isinstance(layer, FieldLayer):
        raise TypeError("the network carries no joint field layer")
    return layer
