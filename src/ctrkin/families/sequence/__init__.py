"""The paper's sequence models (Fig. 4, 5; Tables II, III): the LSTM-MLP with its input buffer and
Δα0, its structures S1–S5 and the Δα0 ablation, and the baselines it was compared with (MLP, LSTM,
CNN, TCN, ResNet), for FK and IK. They learn by the paper's recipe (ctrkin.models.recipe.WindowRecipe)
and predict through the shared FK predictor (ctrkin.models.fk_predictor) or the direct IK here.

    conv.py, resnet.py   the CNN, TCN and ResNet baselines (the LSTM-MLP, LSTM and MLP are
                         structures of ctrkin.models.seqnet.SeqNet)
    ik.py                the direct IK in use: network, workspace check, jump flags
"""

from __future__ import annotations

from collections.abc import Callable

from ctrkin.families.sequence.conv import CNN, TCN
from ctrkin.families.sequence.ik import DirectIK
from ctrkin.families.sequence.resnet import ResNet
from ctrkin.models.base import KinematicsNet
from ctrkin.models.fk_predictor import FKPredictor
from ctrkin.models.predictor import Family, ModelEntry, Opened, Predictor
from ctrkin.models.recipe import WindowRecipe
from ctrkin.models.seqnet import SeqNet


def _seq(structure: str, pooling: str) -> Callable[..., KinematicsNet]:
    def build(n_inputs: int, n_outputs: int, ib: int, output_activation: str,
              structure: str = structure) -> KinematicsNet:
        return SeqNet(n_inputs, n_outputs, ib, structure, pooling, output_activation)
    return build


def _conv(cls: type[CNN] | type[TCN]) -> Callable[..., KinematicsNet]:
    def build(n_inputs: int, n_outputs: int, ib: int, output_activation: str,
              channels: int = 64) -> KinematicsNet:
        return cls(n_inputs, n_outputs, ib, int(channels), output_activation)
    return build


def _resnet(n_inputs: int, n_outputs: int, ib: int, output_activation: str, width: int = 128,
            blocks: int = 3) -> KinematicsNet:
    return ResNet(n_inputs, n_outputs, ib, int(width), int(blocks), output_activation)


def _load(opened: Opened) -> Predictor:
    bundle = opened.bundle
    seqnet = bundle.net if isinstance(bundle.net, SeqNet) else None     # else torch on windows
    if bundle.layout.task == "fk":
        return FKPredictor(bundle, seqnet, opened.fused)
    return DirectIK(bundle, opened.workspace, seqnet)


FAMILY = Family(
    name="sequence",
    title="paper sequence model",
    entries=(
        ModelEntry("lstm_mlp", "paper LSTM-MLP (Fig. 4): LSTM -> flatten -> Dense ReLU -> out; "
                   "structure: paper | S1..S5 | spec", _seq("paper", "flatten"), {"structure": "paper"}),
        ModelEntry("lstm_mlp_no_delta", "ablation of Fig. 5b: LSTM-MLP without the directional feature",
                   _seq("paper", "flatten"), {"structure": "paper"}, {"delta": False}),
        ModelEntry("mlp", "baseline: MLP on the flattened buffer, Dense 128, 64 ReLU",
                   _seq("|D128,D64", "flatten"), {"structure": "|D128,D64"}),
        ModelEntry("lstm", "baseline: LSTM(128), last step -> out", _seq("L128|", "last"),
                   {"structure": "L128|"}),
        ModelEntry("cnn", "baseline: 2 causal Conv1d + Dense 64", _conv(CNN), {"channels": 64}),
        ModelEntry("tcn", "baseline: TCN, 2 dilated residual blocks", _conv(TCN), {"channels": 64}),
        ModelEntry("resnet", "baseline: residual Dense blocks", _resnet, {"width": 128, "blocks": 3}),
    ),
    load=_load,
    recipe=WindowRecipe,
    predictors=(FKPredictor, DirectIK),
)
