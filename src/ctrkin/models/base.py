"""What every kinematics network shares: input (B, IB, F) normalised features -> (B, O) normalised outputs."""

from __future__ import annotations

import torch
from torch import nn

from ctrkin.errors import ModelError
from ctrkin.models.choices import OUTPUT_ACTIVATIONS


class KinematicsNet(nn.Module):
    """Base class. Subclasses set the layers and implement `forward(x: (B, IB, F)) -> (B, O)`.

    output_activation: "relu" (paper eq. 7: the output layer is ReLU, targets are min-max in [0, 1])
    or "linear" (an option: no clipping at 0).
    """

    def __init__(self, n_inputs: int, n_outputs: int, ib: int, output_activation: str = "relu") -> None:
        super().__init__()
        if output_activation not in OUTPUT_ACTIVATIONS:
            raise ModelError(f"output_activation must be one of {OUTPUT_ACTIVATIONS}, "
                             f"got {output_activation!r}")
        self.n_inputs, self.n_outputs, self.ib = n_inputs, n_outputs, ib
        self.output_activation = output_activation

    def init_output_bias(self) -> None:
        """Start every output unit at the middle of the normalised target range [0, 1] (bias 0.5).
        Under the paper's final ReLU (eq. 7) a unit whose pre-activation starts negative for all
        inputs gets no gradient and stays dead, predicting the minimum of its target for ever (seen on
        the quick reproduction: a constant quaternion component, 60° orientation RMSE)."""
        out = getattr(self, "out", None)
        if isinstance(out, nn.Linear) and out.bias is not None:
            with torch.no_grad():
                out.bias.fill_(0.5)

    def finish(self, y: torch.Tensor) -> torch.Tensor:
        return torch.relu(y) if self.output_activation == "relu" else y
