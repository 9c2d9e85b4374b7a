"""The learned side's shared parts: per-step features and input buffers, normalisation, the
layer-list network the families build on and its numba streaming engine, the model folder, the
outer-tube frame, and the interface every model family implements (docs/design.md: Model families).

    from ctrkin.models import FeatureLayout, SeqNet
    layout = FeatureLayout(task="fk", n_tubes=2, ib=2)      # (α1, α2, β1, β2, α0, Δα0)
    net = SeqNet(layout.n_inputs, layout.n_outputs, layout.ib, "paper")

Networks by registry name: ctrkin.families (`build_model`, `MODELS`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ctrkin.util.lazy import lazy_attributes

__all__ = ["STRUCTURES", "Family", "FeatureLayout", "KinematicsNet", "MinMax", "ModelEntry", "Predictor",
           "Recipe", "SeqNet", "Structure", "sequence_features", "step_features", "windows"]

if TYPE_CHECKING:   # imported on first use instead (ctrkin.util.lazy)
    from ctrkin.models.base import KinematicsNet
    from ctrkin.models.features import FeatureLayout, sequence_features, step_features, windows
    from ctrkin.models.normalize import MinMax
    from ctrkin.models.predictor import Family, ModelEntry, Predictor
    from ctrkin.models.recipe import Recipe
    from ctrkin.models.seqnet import STRUCTURES, SeqNet, Structure

__getattr__, __dir__ = lazy_attributes(__name__, __file__)
