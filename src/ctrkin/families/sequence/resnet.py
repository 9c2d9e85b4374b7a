"""ResNet baseline of paper Fig. 5a: residual Dense blocks on the flattened input buffer.

x: (B, IB, F) -> (B, O). The paper notes its ResNet was accurate but large; three 128-wide blocks.
"""

from __future__ import annotations

import torch
from torch import nn

from ctrkin.models.base import KinematicsNet


class _ResBlock(nn.Module):
    def __init__(self, width: int) -> None:
        super().__init__()
        self.fc1 = nn.Linear(width, width)
        self.fc2 = nn.Linear(width, width)

    def forward(self, h: torch.Tensor) -> torch.Tensor:
        return torch.relu(h + self.fc2(torch.relu(self.fc1(h))))


class ResNet(KinematicsNet):
    """Dense(width) ReLU -> `blocks` residual blocks -> Dense(O) -> output activation."""

    def __init__(self, n_inputs: int, n_outputs: int, ib: int, width: int = 128, blocks: int = 3,
                 output_activation: str = "relu") -> None:
        super().__init__(n_inputs, n_outputs, ib, output_activation)
        self.inp = nn.Linear(n_inputs * ib, width)
        self.blocks = nn.Sequential(*[_ResBlock(width) for _ in range(blocks)])
        self.out = nn.Linear(width, n_outputs)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        h = self.blocks(torch.relu(self.inp(x.flatten(1))))
        return self.finish(self.out(h))
