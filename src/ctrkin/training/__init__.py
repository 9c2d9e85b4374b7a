"""Training of learned kinematics (paper IV.A): configuration, data preparation, loop, metrics.

    from ctrkin.training import TrainConfig, train
    train(dataset, TrainConfig(task="fk", model="lstm_mlp", ib=2), "models/fk")
"""

from ctrkin.training.config import TrainConfig
from ctrkin.training.loop import TrainResult, train
from ctrkin.training.metrics import joint_errors, pose_errors

__all__ = ["TrainConfig", "TrainResult", "joint_errors", "pose_errors", "train"]
