"""Learned kinematics models: per-step features, input buffers, normalisation and the networks.

    from ctrkin.models import FeatureLayout, build_model
    layout = FeatureLayout(task="fk", n_tubes=2, ib=2)      # (α1, α2, β1, β2, α0, Δα0)
    net = build_model("lstm_mlp", layout.n_inputs, layout.n_outputs, layout.ib)
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ctrkin.util.lazy import lazy_attributes

_WHERE = {
    "KinematicsNet": "ctrkin.models.base", "FeatureLayout": "ctrkin.models.features",
    "sequence_features": "ctrkin.models.features", "step_features": "ctrkin.models.features",
    "windows": "ctrkin.models.features", "MinMax": "ctrkin.models.normalize",
    "MODELS": "ctrkin.models.registry", "build_model": "ctrkin.models.registry",
    "get_entry": "ctrkin.models.registry", "resolve_options": "ctrkin.models.registry",
    "STRUCTURES": "ctrkin.models.seqnet", "SeqNet": "ctrkin.models.seqnet",
    "Structure": "ctrkin.models.seqnet",
}

__all__ = ["MODELS", "STRUCTURES", "FeatureLayout", "KinematicsNet", "MinMax", "SeqNet", "Structure",
           "build_model", "get_entry", "resolve_options", "sequence_features", "step_features",
           "windows"]

__getattr__, __dir__ = lazy_attributes(__name__, _WHERE)

if TYPE_CHECKING:
    from ctrkin.models.base import KinematicsNet
    from ctrkin.models.features import FeatureLayout, sequence_features, step_features, windows
    from ctrkin.models.normalize import MinMax
    from ctrkin.models.registry import MODELS, build_model, get_entry, resolve_options
    from ctrkin.models.seqnet import STRUCTURES, SeqNet, Structure
