"""Convolutional baselines of paper Fig. 5a: a CNN and a TCN over the input buffer.

Both read x: (B, IB, F) normalised features and return (B, O). The paper gives no layer sizes for its
baselines; these are small, conventional choices (documented in docs/learned_kinematics.md).
"""

from __future__ import annotations

import torch
from torch import nn

from ctrkin.models.base import KinematicsNet


class CNN(KinematicsNet):
    """Two causal Conv1d (kernel min(2, IB)) + ReLU over the buffer -> flatten -> Dense(64) ReLU -> out."""

    def __init__(self, n_inputs: int, n_outputs: int, ib: int, channels: int = 64,
                 output_activation: str = "relu") -> None:
        super().__init__(n_inputs, n_outputs, ib, output_activation)
        k = min(2, ib)
        self.k = k
        self.conv1 = nn.Conv1d(n_inputs, channels, k)
        self.conv2 = nn.Conv1d(channels, channels, k)
        self.dense = nn.Linear(channels * ib, 64)
        self.out = nn.Linear(64, n_outputs)

    def _causal(self, conv: nn.Conv1d, h: torch.Tensor) -> torch.Tensor:
        return conv(nn.functional.pad(h, (self.k - 1, 0)))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        h = x.transpose(1, 2)                                # (B, F, IB)
        h = torch.relu(self._causal(self.conv1, h))
        h = torch.relu(self._causal(self.conv2, h))
        h = torch.relu(self.dense(h.flatten(1)))
        return self.finish(self.out(h))


class _TemporalBlock(nn.Module):
    """Dilated causal conv -> ReLU -> dilated causal conv -> ReLU, plus a 1x1 residual (Bai et al. 2018)."""

    def __init__(self, c_in: int, c_out: int, dilation: int, k: int = 2) -> None:
        super().__init__()
        self.pad = (k - 1) * dilation
        self.conv1 = nn.Conv1d(c_in, c_out, k, dilation=dilation)
        self.conv2 = nn.Conv1d(c_out, c_out, k, dilation=dilation)
        self.skip = nn.Conv1d(c_in, c_out, 1) if c_in != c_out else nn.Identity()

    def forward(self, h: torch.Tensor) -> torch.Tensor:
        y = torch.relu(self.conv1(nn.functional.pad(h, (self.pad, 0))))
        y = torch.relu(self.conv2(nn.functional.pad(y, (self.pad, 0))))
        return torch.relu(y + self.skip(h))


class TCN(KinematicsNet):
    """Temporal blocks with dilations 1, 2 (receptive field 7 steps >= IB 5) -> last step -> out."""

    def __init__(self, n_inputs: int, n_outputs: int, ib: int, channels: int = 64,
                 output_activation: str = "relu") -> None:
        super().__init__(n_inputs, n_outputs, ib, output_activation)
        self.blocks = nn.Sequential(_TemporalBlock(n_inputs, channels, 1),
                                    _TemporalBlock(channels, channels, 2))
        self.out = nn.Linear(channels, n_outputs)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        h = self.blocks(x.transpose(1, 2))                   # (B, C, IB)
        return self.finish(self.out(h[:, :, -1]))
