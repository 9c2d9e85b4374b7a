"""Training configuration: the paper's setup (IV.A) as defaults, validated on construction."""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field, fields
from typing import Any

from ctrkin.errors import ModelError
from ctrkin.models.base import OUTPUT_ACTIVATIONS
from ctrkin.models.features import FeatureLayout
from ctrkin.models.frame import FRAMES
from ctrkin.models.registry import get_entry, resolve_options

SPLITS = ("dataset", "sequence", "random")
POSE_SOURCES = ("measured", "true")
LR_SCHEDULES = ("constant", "cosine")
LOOPS = ("epoch", "batch")
PAPER_BATCH, PAPER_LR = 32, 1e-3


def scaled_lr(batch_size: int, base_lr: float = PAPER_LR, base_batch: int = PAPER_BATCH) -> float:
    """Square-root learning-rate rule for a larger batch: Adam's update noise falls with √batch, so
    lr grows with it (batch 32 -> 1e-3, the paper's; 512 -> 4e-3)."""
    return base_lr * math.sqrt(batch_size / base_batch)


@dataclass(frozen=True)
class TrainConfig:
    """Everything a training run depends on; saved as config.json beside the weights.

    task: "fk" | "ik"; model: registry name (ctrkin.models.MODELS); options: model options
    (e.g. {"structure": "S3"}); ib: input buffer (1..5 in the paper, 2 the final model); delta: the
    directional feature Δα0 (FK) / pose deltas (IK); angle_encoding: "minmax" (paper) | "sincos";
    output_activation: "relu" (paper eq. 7) | "linear"; pose_source: which pose columns are the FK target
    / IK input: "measured" (tracker, as in the paper) or "true" (virtual robot only);
    split: "dataset" (the dataset's saved split, else by sequence), "sequence", or "random" (the paper's
    70:15:15 shuffle); lr, batch_size, max_epochs: Adam 1e-3, 32, 500 (paper); patience: early stopping
    epochs without a val-loss improvement of min_delta; threads: torch CPU threads; drop_outliers:
    rows flagged `outlier` are not used as targets; target_frame: FK poses learned in the "tracker"
    frame (paper) or in the "outer" tube's frame (ctrkin.models.frame); lr_schedule: "constant"
    (paper) or "cosine" (decay to lr/50 over max_epochs); gate_weight, unknown_prob: branch models
    only (ctrkin.models.branch): weight of the gate's cross-entropy beside the MAE loss, and how
    often the previous state is hidden; follow: the follow IK (ctrkin.models.follow, model
    'follow_mlp', trained by ctrkin.training.follow); loop: "epoch" (one gather of the shuffled
    training tensors per epoch, fused Adam: the per-batch work is the network alone) or "batch" (the
    loop up to issue 11: index gathers and a plain Adam step per batch; kept for comparison, same batches and
    same seeds); fused_adam: the "epoch" loop's Adam uses the fused CPU kernel (False: the default
    kernel; the "epoch" loop is then bit-identical to the "batch" loop); val_smoothing: early
    stopping counts epochs without an improvement of the exponential moving average of the val
    loss with this factor (0: the raw val loss, as the paper; the best epoch's weights are still
    chosen by the raw val loss); max_seconds: stop after this much training time (a wall-clock
    budget; None: no limit).
    """

    task: str = "fk"
    model: str = "lstm_mlp"
    options: dict[str, Any] = field(default_factory=dict)
    ib: int = 2
    delta: bool = True
    angle_encoding: str = "minmax"
    output_activation: str = "relu"
    pose_source: str = "measured"
    split: str = "dataset"
    split_seed: int = 0
    lr: float = 1e-3
    batch_size: int = 32
    max_epochs: int = 500
    patience: int = 20
    min_delta: float = 0.0
    seed: int = 0
    threads: int = 2
    drop_outliers: bool = True
    target_frame: str = "tracker"
    lr_schedule: str = "constant"
    gate_weight: float = 0.1
    unknown_prob: float = 0.1
    follow: bool = False
    loop: str = "epoch"
    fused_adam: bool = True
    val_smoothing: float = 0.0
    max_seconds: float | None = None

    def __post_init__(self) -> None:
        if self.task not in ("fk", "ik"):
            raise ModelError(f"task must be 'fk' or 'ik', got {self.task!r}")
        entry = get_entry(self.model)
        object.__setattr__(self, "options", resolve_options(self.model, self.options))
        for key, value in entry.forced.items():
            if key == "task" and self.task != value:
                raise ModelError(f"model {self.model!r} is for task {value!r}, not {self.task!r}")
            object.__setattr__(self, key, value)        # e.g. the ablation entry fixes delta
        if self.output_activation not in OUTPUT_ACTIVATIONS:
            raise ModelError(f"output_activation must be one of {OUTPUT_ACTIVATIONS}")
        if self.pose_source not in POSE_SOURCES:
            raise ModelError(f"pose_source must be one of {POSE_SOURCES}, got {self.pose_source!r}")
        if self.split not in SPLITS:
            raise ModelError(f"split must be one of {SPLITS}, got {self.split!r}")
        for name, lo in (("batch_size", 1), ("max_epochs", 1), ("patience", 1), ("threads", 1)):
            v = getattr(self, name)
            if not isinstance(v, int) or v < lo:
                raise ModelError(f"{name} must be an integer >= {lo}, got {v!r}")
        if not self.lr > 0:
            raise ModelError(f"lr must be positive, got {self.lr}")
        if self.target_frame not in FRAMES:
            raise ModelError(f"target_frame must be one of {FRAMES}, got {self.target_frame!r}")
        if self.follow and (self.task != "ik" or self.target_frame != "outer" or self.ib != 1):
            raise ModelError("follow=True is the follow IK (model 'follow_mlp'): task 'ik', IB 1, targets "
                             "in the outer tube's frame")
        if self.target_frame != "tracker" and self.task != "fk" and not self.follow:
            raise ModelError("target_frame='outer' applies to FK models and the follow IK only")
        if self.lr_schedule not in LR_SCHEDULES:
            raise ModelError(f"lr_schedule must be one of {LR_SCHEDULES}, got {self.lr_schedule!r}")
        if not (self.gate_weight >= 0 and 0 <= self.unknown_prob <= 1):
            raise ModelError("gate_weight must be >= 0 and unknown_prob in [0, 1]")
        if self.loop not in LOOPS:
            raise ModelError(f"loop must be one of {LOOPS}, got {self.loop!r}")
        if not 0 <= self.val_smoothing < 1:
            raise ModelError(f"val_smoothing must be in [0, 1), got {self.val_smoothing}")
        if self.max_seconds is not None and not self.max_seconds > 0:
            raise ModelError(f"max_seconds must be positive or None, got {self.max_seconds}")
        if self.min_delta < 0:
            raise ModelError(f"min_delta must be >= 0, got {self.min_delta}")
        self.layout(2)   # validates ib and angle_encoding

    def layout(self, n_tubes: int) -> FeatureLayout:
        return FeatureLayout(task=self.task, n_tubes=n_tubes, ib=self.ib,  # type: ignore[arg-type]
                             delta=self.delta, angle_encoding=self.angle_encoding,  # type: ignore[arg-type]
                             follow=self.follow)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> TrainConfig:
        names = {f.name for f in fields(cls)}
        unknown = sorted(set(d) - names)   # fields added later take their defaults in older files
        if unknown:
            raise ModelError(f"unknown training config keys {unknown}")
        return cls(**d)

    def differences(self, other: TrainConfig,
                    ignore: tuple[str, ...] = ("max_epochs", "threads", "max_seconds", "loop",
                                               "fused_adam")) -> list[str]:
        """What differs, as 'key: a vs b' (keys that may change on resume are ignored: how, not what,
        is trained)."""
        a, b = self.to_dict(), other.to_dict()
        return [f"{k}: {json.dumps(a[k])} vs {json.dumps(b[k])}" for k in a
                if k not in ignore and a[k] != b[k]]
