"""Training of learned kinematics (paper IV.A): configuration, the split, the generic engine that runs
every family's recipe (ctrkin.models.recipe); errors are computed by ctrkin.metrics.

    from ctrkin.training import TrainConfig, train
    train(dataset, TrainConfig(task="fk", model="lstm_mlp", ib=2), "models/fk")
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ctrkin.util.lazy import lazy_attributes

__all__ = ["TrainConfig", "TrainResult", "train"]

if TYPE_CHECKING:   # imported on first use instead (ctrkin.util.lazy)
    from ctrkin.training.config import TrainConfig
    from ctrkin.training.engine import TrainResult, train

__getattr__, __dir__ = lazy_attributes(__name__, __file__)
