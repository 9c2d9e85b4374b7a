"""Every registered model builds, maps (B, IB, F) -> (B, O), and bad names or options are refused."""

from __future__ import annotations

import pytest
import torch

from ctrkin.errors import ModelError
from ctrkin.families.registry import MODELS, build_model
from ctrkin.models import STRUCTURES, Structure
from ctrkin.training import TrainConfig


@pytest.mark.parametrize("name", sorted(MODELS))
@pytest.mark.parametrize("ib", [1, 2, 5])
def test_every_model_maps_windows_to_outputs(name, ib):
    torch.manual_seed(0)
    net = build_model(name, 6, 4, ib)
    y = net(torch.rand(3, ib, 6))
    assert y.shape == (3, 4)
    assert torch.all(y >= 0)                                  # paper eq. 7: ReLU output by default
    lin = build_model(name, 6, 4, ib, output_activation="linear")
    assert lin.output_activation == "linear"


def test_table_iii_structures_and_paper_default():
    assert Structure.parse("paper") == Structure((("lstm", 128),), (64,))
    assert Structure.parse("S3") == Structure((("lstm", 128), ("lstm", 128)), (64,))
    assert Structure.parse("S4").seq == (("lstm", 128), ("dense", 128), ("lstm", 64))
    for s in STRUCTURES:
        net = build_model("lstm_mlp", 6, 6, 3, options={"structure": s})
        assert net(torch.rand(2, 3, 6)).shape == (2, 6)
    default = build_model("lstm_mlp", 6, 6, 2)
    assert default.seq[0].hidden_size == 128 and default.head[0].out_features == 64


def test_unknown_names_and_options_say_what_to_use():
    with pytest.raises(ModelError, match="lstm_mlp"):
        build_model("transformer", 6, 6, 2)
    with pytest.raises(ModelError, match="takes options"):
        build_model("mlp", 6, 6, 2, options={"channels": 3})
    with pytest.raises(ModelError, match=r"SEQ\|HEAD"):
        Structure.parse("S9")
    with pytest.raises(ModelError, match="only Dense"):
        Structure.parse("L8|L8")


def test_ablation_entry_forces_no_delta():
    cfg = TrainConfig(model="lstm_mlp_no_delta")
    assert cfg.delta is False
    assert "delta_alpha_0" not in cfg.layout(2).input_names
