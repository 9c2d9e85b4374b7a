"""Training of learned kinematics (paper IV.A): configuration, data preparation, the loop; errors
are computed by ctrkin.metrics.

    from ctrkin.training import TrainConfig, train
    train(dataset, TrainConfig(task="fk", model="lstm_mlp", ib=2), "models/fk")
"""

from ctrkin.training.config import TrainConfig
from ctrkin.training.loop import TrainResult, train

__all__ = ["TrainConfig", "TrainResult", "train"]
