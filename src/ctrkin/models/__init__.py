"""Learned kinematics models: per-step features, input buffers, normalisation and the networks.

    from ctrkin.models import FeatureLayout, build_model
    layout = FeatureLayout(task="fk", n_tubes=2, ib=2)      # (α1, α2, β1, β2, α0, Δα0)
    net = build_model("lstm_mlp", layout.n_inputs, layout.n_outputs, layout.ib)
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ctrkin.util.lazy import lazy_attributes

__all__ = ["MODELS", "STRUCTURES", "FeatureLayout", "KinematicsNet", "MinMax", "SeqNet", "Structure",
           "build_model", "get_entry", "resolve_options", "sequence_features", "step_features",
           "windows"]

if TYPE_CHECKING:   # imported on first use instead (ctrkin.util.lazy)
    from ctrkin.models.base import KinematicsNet
    from ctrkin.models.features import FeatureLayout, sequence_features, step_features, windows
    from ctrkin.models.normalize import MinMax
    from ctrkin.models.registry import MODELS, build_model, get_entry, resolve_options
    from ctrkin.models.seqnet import STRUCTURES, SeqNet, Structure

__getattr__, __dir__ = lazy_attributes(__name__, __file__)
