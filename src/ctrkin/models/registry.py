"""Models by name, so `ctrkin train --model mlp` just works.

    from ctrkin.models import build_model, MODELS
    net = build_model("lstm_mlp", n_inputs=6, n_outputs=6, ib=2)               # paper default
    net = build_model("lstm_mlp", 6, 6, 3, options={"structure": "S3"})        # Table III grid

Each entry says which options it takes and which training settings it fixes (the Δα0 ablation of
Fig. 5b is the LSTM-MLP without the delta feature; the snap-aware model uses the phase features and
a linear output).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import torch

from ctrkin.errors import ModelError
from ctrkin.models.base import KinematicsNet
from ctrkin.models.branch import BranchNet
from ctrkin.models.conv import CNN, TCN
from ctrkin.models.resnet import ResNet
from ctrkin.models.seqnet import SeqNet

MAX_PARAMETERS = 20_000_000     # 80 MB of float32 weights: 200x the largest model ctrkin trains


@dataclass(frozen=True)
class ModelEntry:
    name: str
    description: str
    build: Callable[..., KinematicsNet]
    options: dict[str, Any]                      # option -> default
    forced: dict[str, Any] = field(default_factory=dict)   # TrainConfig fields the entry fixes
    stateful: bool = False                                  # carries a branch state (BranchNet)


def _seq(structure: str, pooling: str) -> Callable[..., KinematicsNet]:
    def build(n_inputs: int, n_outputs: int, ib: int, output_activation: str,
              structure: str = structure) -> KinematicsNet:
        return SeqNet(n_inputs, n_outputs, ib, structure, pooling, output_activation)
    return build


def _branch(n_inputs: int, n_outputs: int, ib: int, output_activation: str, structure: str = "paper",
            gate_units: int = 32) -> KinematicsNet:
    return BranchNet(n_inputs, n_outputs, ib, structure, output_activation, int(gate_units))


def _conv(cls: type[CNN] | type[TCN]) -> Callable[..., KinematicsNet]:
    def build(n_inputs: int, n_outputs: int, ib: int, output_activation: str,
              channels: int = 64) -> KinematicsNet:
        return cls(n_inputs, n_outputs, ib, int(channels), output_activation)
    return build


def _resnet(n_inputs: int, n_outputs: int, ib: int, output_activation: str, width: int = 128,
            blocks: int = 3) -> KinematicsNet:
    return ResNet(n_inputs, n_outputs, ib, int(width), int(blocks), output_activation)


MODELS: dict[str, ModelEntry] = {e.name: e for e in [
    ModelEntry("lstm_mlp", "paper LSTM-MLP (Fig. 4): LSTM -> flatten -> Dense ReLU -> out; "
               "structure: paper | S1..S5 | spec", _seq("paper", "flatten"), {"structure": "paper"}),
    ModelEntry("lstm_mlp_no_delta", "ablation of Fig. 5b: LSTM-MLP without the directional feature",
               _seq("paper", "flatten"), {"structure": "paper"}, {"delta": False}),
    ModelEntry("lstm_mlp_branch", "snap-aware LSTM-MLP: a learned branch state (hysteron) selects "
               "one of two heads, so snaps are sharp (ctrkin.models.branch); FK only, sin/cos α0 "
               "inputs, poses learned in the outer tube's frame (ctrkin.models.frame)",
               _branch, {"structure": "paper", "gate_units": 32},
               {"angle_encoding": "phase", "output_activation": "linear", "task": "fk",
                "target_frame": "outer"}, stateful=True),
    ModelEntry("follow_mlp", "follow IK: the joint change from the current joints to the next target, "
               "target in the outer tube's frame, trained from perturbed joints (ctrkin.models.follow); "
               "IK only, MLP Dense 256 x 3", _seq("|D256,D256,D256", "flatten"),
               {"structure": "|D256,D256,D256"},
               {"task": "ik", "ib": 1, "output_activation": "linear", "target_frame": "outer",
                "follow": True, "delta": True}),
    ModelEntry("mlp", "baseline: MLP on the flattened buffer, Dense 128, 64 ReLU",
               _seq("|D128,D64", "flatten"), {"structure": "|D128,D64"}),
    ModelEntry("lstm", "baseline: LSTM(128), last step -> out", _seq("L128|", "last"),
               {"structure": "L128|"}),
    ModelEntry("cnn", "baseline: 2 causal Conv1d + Dense 64", _conv(CNN), {"channels": 64}),
    ModelEntry("tcn", "baseline: TCN, 2 dilated residual blocks", _conv(TCN), {"channels": 64}),
    ModelEntry("resnet", "baseline: residual Dense blocks", _resnet, {"width": 128, "blocks": 3}),
]}


def get_entry(name: str) -> ModelEntry:
    if name not in MODELS:
        raise ModelError(f"unknown model {name!r}; choose one of {sorted(MODELS)}")
    return MODELS[name]


def resolve_options(name: str, options: dict[str, Any] | None) -> dict[str, Any]:
    """The entry's defaults updated by `options`; unknown options are an error naming the valid ones."""
    entry = get_entry(name)
    options = dict(options or {})
    unknown = sorted(set(options) - set(entry.options))
    if unknown:
        raise ModelError(f"model {name!r} takes options {sorted(entry.options)}, not {unknown}")
    return {**entry.options, **options}


def build_model(name: str, n_inputs: int, n_outputs: int, ib: int, output_activation: str = "relu",
                options: dict[str, Any] | None = None) -> KinematicsNet:
    """A fresh (randomly initialised, seed it with torch.manual_seed) network by registry name.

    The network is first built on torch's meta device (shapes only, no memory) and refused if it
    would hold more than MAX_PARAMETERS weights: a configuration or a model folder's config.json
    cannot make ctrkin allocate without bound (LSTM units, layers, widths, channels)."""
    entry = get_entry(name)
    opts = resolve_options(name, options)
    with torch.device("meta"):
        size = sum(p.numel() for p in entry.build(n_inputs, n_outputs, ib, output_activation,
                                                   **opts).parameters())
    if size > MAX_PARAMETERS:
        raise ModelError(f"model {name!r} with options {opts} would have {size:,} parameters, more than "
                         f"ctrkin's bound of {MAX_PARAMETERS:,} (the paper's LSTM-MLP has ~86,000); "
                         "choose smaller layers")
    net = entry.build(n_inputs, n_outputs, ib, output_activation, **opts)
    net.init_output_bias()
    return net
