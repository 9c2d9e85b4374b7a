"""A GRU variant of the paper's model (issue 25's newcomer test): GRU on the input buffer ->
flatten -> Dense ReLU -> out, FK, trained by the paper's recipe and streamed by the shared FK
predictor on windows."""

from __future__ import annotations

import torch
from torch import nn

from ctrkin.models.base import KinematicsNet
from ctrkin.models.fk_predictor import FKPredictor
from ctrkin.models.predictor import Family, ModelEntry, Opened, Predictor
from ctrkin.models.recipe import WindowRecipe


class GRUNet(KinematicsNet):
    """x: (B, IB, F) -> GRU(units) on the window -> flatten -> Dense(units, ReLU) -> (B, O)."""

    def __init__(self, n_inputs: int, n_outputs: int, ib: int, output_activation: str,
                 units: int = 64) -> None:
        super().__init__(n_inputs, n_outputs, ib, output_activation)
        self.gru = nn.GRU(n_inputs, int(units), batch_first=True)
        self.hidden = nn.Linear(int(units) * ib, int(units))
        self.out = nn.Linear(int(units), n_outputs)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        h, _ = self.gru(x)
        return self.finish(self.out(torch.relu(self.hidden(h.flatten(1)))))


def _load(opened: Opened) -> Predictor:
    return FKPredictor(opened.bundle, None, opened.fused)


FAMILY = Family(name="gru", title="GRU sequence model",
                entries=(ModelEntry("gru_mlp", "GRU -> flatten -> Dense ReLU -> out (FK)", GRUNet,
                                    {"units": 64}, {"task": "fk"}),),
                load=_load, recipe=WindowRecipe, predictors=(FKPredictor,))
