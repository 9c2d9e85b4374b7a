"""Training configuration: the paper's setup (IV.A) as defaults, validated on construction."""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field, fields
from typing import TYPE_CHECKING, Any, Literal, get_args

from ctrkin.errors import ModelError
from ctrkin.models.choices import (
    FRAMES,
    OUTPUT_ACTIVATIONS,
    AngleEncoding,
    OutputActivation,
    TargetFrame,
    Task,
)

if TYPE_CHECKING:
    from ctrkin.models.features import FeatureLayout

Split = Literal["dataset", "sequence", "random"]
PoseSource = Literal["measured", "true"]
LrSchedule = Literal["constant", "cosine"]
Loop = Literal["epoch", "batch"]
Device = Literal["auto", "cpu", "cuda"]
SPLITS: tuple[str, ...] = get_args(Split)
POSE_SOURCES: tuple[str, ...] = get_args(PoseSource)
LR_SCHEDULES: tuple[str, ...] = get_args(LrSchedule)
LOOPS: tuple[str, ...] = get_args(Loop)
DEVICES: tuple[str, ...] = get_args(Device)
PAPER_BATCH, PAPER_LR, PAPER_EPOCHS = 32, 1e-3, 500
MIN_STEPS = 10_000         # the default budget's least optimiser steps (issue 22: 63 NDI samples)
PATIENCE_STEPS = 1_000     # early stopping's least optimiser steps without an improvement


# What `ctrkin train` trains for a task when --model is not given: the recommended models (the
# snap-aware FK and the follow IK, docs/reproduction.md) with the settings `reproduce --scale quick`
# trains them with (ctrkin.evaluation.scales, tested equal); a setting given on the command line wins.
# The follow IK's budget is in epochs (min_steps 0): it draws its perturbations anew every epoch and
# rolls itself out at fixed fractions of them. The snap-aware FK sees a window of FK_MEMORY_IB steps.
# IB 8 was measured against 2 (benchmarks/bench_fk_memory.py, docs/learned_kinematics.md: Memory of
# the recommended FK): better on the validation rows of the top-of-range robot, worse along mid-turn
# reversals and in snap magnitude, ×3.6 the training time and ×3-4.6 the streaming step; kept at 2.
# Its memory beyond the window is the play-operator lags of the joint path (FK_PLAY_LAGS;
# ctrkin.models.play_lags; bench_fk_memory.py, docs/learned_kinematics.md: Play lags as FK inputs).
# The follow IK sees the outer tube's absolute angle (FeatureLayout.outer_angle) and trains a quarter
# of its rows from joints the recording had earlier on its path (catch_up): on the top-of-range robot,
# validation over two seeds 5.07 mm (neither) -> 3.38 mm (both); held-out sequences better on three
# robots, the 10-point square and triangle worse (docs/learned_kinematics.md: The outer angle and
# catch-up rows). Its budget is IK_EPOCHS epochs (40 before): on the top-of-range robot's quick data,
# 40 -> 120 epochs took validation from 3.59 / 3.69 mm to 3.24 / 3.17 mm via the robot over two seeds,
# the held-out sequences from 3.43 / 4.02 to 3.24 / 3.29 mm, at three times the training time
# (benchmarks/bench_ik_floor.py; docs/learned_kinematics.md: The follow IK's budget). The full scale
# keeps 40: its epochs are four times as many steps.
# The snap-aware FK learns the tracker's position field with the network (FK_JOINT_FIELD;
# ctrkin.models.joint_field): validation picked it on all four robots of bench_fk_memory.py, test and
# mid-turn reversals improved on each (docs/learned_kinematics.md: A position field learned with the FK).
# `ctrkin train`'s recommended FK also trains the paper's LSTM-MLP and keeps the one validation prefers
# (FK_SELECT_BY_VALIDATION; ctrkin.training.selection): on the comet-lab OptiTrack logs (one amplitude of
# sweep, no snap) validation and the held-out sweep both prefer the LSTM-MLP (docs/real_robot.md). The
# reproduction's runs do not select: its robots snap and its protocols reverse everywhere.
# Its fold gate fits a scale g on the nominal folds, kept only where it lowers the leave-one-run-out
# residual of the training snaps (FK_FOLD_SCALE; ctrkin.families.snap_aware.fold_gate): g = 1 on
# default-top and design-b; on three-tube-central (g ≈ 0.5) the validation rows' RMSE as predict gives
# it fell 0.340 -> 0.268 mm at quick and 0.327 -> 0.175 mm at full scale, and the sweeps' and snap
# turns' P/R rose to 1.00 (bench_fk_memory.py arms ib2pf, ib2pgf; docs/learned_kinematics.md: The
# folds' scale, measured).
FK_MEMORY_IB = 2
FK_PLAY_LAGS = True
FK_JOINT_FIELD = True
FK_SELECT_BY_VALIDATION = True
FK_FOLD_SCALE = True
IK_OUTER_ANGLE = True
IK_CATCH_UP = 0.25
IK_EPOCHS = 120
RECOMMENDED: dict[str, dict[str, Any]] = {
    "fk": {"model": "lstm_mlp_branch", "batch_size": 256, "lr": 2e-3, "lr_schedule": "cosine",
           "base_epochs": 80, "patience": 80, "ib": FK_MEMORY_IB, "play_lags": FK_PLAY_LAGS,
           "joint_field": FK_JOINT_FIELD, "fold_scale": FK_FOLD_SCALE,
           "select_by_validation": FK_SELECT_BY_VALIDATION},
    "ik": {"model": "follow_mlp", "batch_size": 512, "lr": 2e-3, "lr_schedule": "cosine",
           "base_epochs": IK_EPOCHS, "patience": IK_EPOCHS, "min_steps": 0, "outer_angle": IK_OUTER_ANGLE,
           "catch_up": IK_CATCH_UP},
}


def scaled_lr(batch_size: int, base_lr: float = PAPER_LR, base_batch: int = PAPER_BATCH) -> float:
    """Square-root learning-rate rule for a larger batch: Adam's update noise falls with √batch, so
    lr grows with it (batch 32 -> 1e-3, the paper's; 512 -> 4e-3)."""
    return base_lr * math.sqrt(batch_size / base_batch)


def _help(text: str) -> dict[str, str]:
    """A field's metadata: its meaning, which is also its `ctrkin train --help` text."""
    return {"help": text}


@dataclass(frozen=True)
class TrainConfig:
    """Everything a training run depends on; saved as config.json beside the weights. Defaults are
    the paper's setup (IV.A). Each field's help says what it means; `ctrkin train` has one option per
    field (ctrkin.cli.from_config)."""

    task: Task = field(default="fk", metadata=_help(
        "fk: forward kinematics (joints -> tip pose); ik: inverse (tip poses -> joints)."))
    model: str = field(default="lstm_mlp", metadata=_help(
        "Registry name (ctrkin.families.registry.MODELS; `ctrkin train --list-models`). `ctrkin train` "
        "without --model trains the recommended model of its task with its settings (RECOMMENDED: "
        "lstm_mlp_branch for fk, follow_mlp for ik; options given still apply); the library's "
        "TrainConfig default is the paper's lstm_mlp."))
    options: dict[str, Any] = field(default_factory=dict, metadata=_help(
        "Model options, e.g. {'structure': 'S3'} (`ctrkin train --structure S3`, `--option KEY=VALUE`)."))
    ib: int = field(default=2, metadata=_help(
        "Input buffer: the current step and IB-1 previous ones (1..5 in the paper, 2 the final model; the "
        "recommended FK: FK_MEMORY_IB)."))
    delta: bool = field(default=True, metadata=_help(
        "The directional feature Δα0 (FK) or the pose deltas (IK); --no-delta drops it (Fig. 5b)."))
    angle_encoding: AngleEncoding = field(default="minmax", metadata=_help(
        "FK angle encoding: minmax (min-max of unwrapped degrees, paper), sincos, or phase (the "
        "paper's features and sin/cos α0; ctrkin.models.features)."))
    equivariant: bool = field(default=False, metadata=_help(
        "FK only: the inputs drop the absolute tube angles α1..αN (rotation-equivariant in the outer "
        "tube's frame), and what depends on the tip's place in space is fitted as a field of its "
        "position after training (ctrkin.models.field)."))
    play_lags: bool = field(default=False, metadata=_help(
        "FK: the inputs also hold the play-operator lags of α1, αN and βN − β1 along the joint path; "
        "the follow IK (follow_mlp): those of the target path's position (ctrkin.models.play_lags: a "
        "memory of the path beyond the window, no friction law assumed)."))
    tcm_prior: bool = field(default=False, metadata=_help(
        "FK only: the TCM is calibrated on the training rows (ctrkin.calibration, reproduce's quick "
        "budget) and followed along each recorded run with its friction state; the network learns "
        "the position's residual from it and the model adds it back (ctrkin.models.tcm_prior; the "
        "folder stores it as tcm_prior.toml). Needs a robot description whose calibration converges; "
        "streaming costs a TCM step per step, and probe and ONNX export are refused."))
    joint_field: bool = field(default=False, metadata=_help(
        "FK in the outer tube's frame only: a field of the tip's tracker-frame position (the "
        "tracker's distortion, ctrkin.models.field) is learned with the network, the loss taken on "
        "tracker-frame positions (ctrkin.models.joint_field), instead of the network learning it from "
        "the absolute angles alone. The model applies it after the frame (streaming, probe, ONNX)."))
    select_by_validation: bool = field(default=False, metadata=_help(
        "FK: also train the paper's LSTM-MLP (sin/cos angles, tracker frame, no lags, field or prior) "
        "with the same budget, seed and split, and keep whichever has the lower validation position "
        "RMSE (ctrkin.training.selection; metrics.json `model_selection`): the snap-aware FK's "
        "branches, lags and field help only where the recording identifies them (docs/real_robot.md). "
        "Twice the training time."))
    outer_angle: bool = field(default=False, metadata=_help(
        "The follow IK (follow_mlp) only: the inputs also hold sin/cos of the outer tube's absolute "
        "angle αN, for what is not rotation-equivariant about the insertion axis (the tracker's field, "
        "a registration error); without it the follow IK is equivariant by construction."))
    output_activation: OutputActivation = field(default="relu", metadata=_help(
        "Output layer activation: relu (paper eq. 7) or linear."))
    pose_source: PoseSource = field(default="measured", metadata=_help(
        "Pose columns to learn from (FK target, IK input): measured (tracker, as in the paper) or true "
        "(virtual-robot ground truth)."))
    split: Split = field(default="dataset", metadata=_help(
        "dataset: the dataset's saved split, else by sequence; sequence: whole sequences per part; "
        "random: the paper's 70:15:15 per-sample shuffle."))
    split_seed: int = field(default=0, metadata=_help("Seed of a sequence or random split."))
    lr: float = field(default=1e-3, metadata=_help("Adam learning rate (paper 1e-3)."))
    batch_size: int = field(default=32, metadata=_help("Batch size (paper 32)."))
    max_epochs: int | None = field(default=None, metadata=_help(
        "Maximum epochs (default: base_epochs, raised for a small set so that training gets at least "
        "min_steps optimiser steps: 44 training rows at batch 32 are 2 steps an epoch)."))
    base_epochs: int = field(default=PAPER_EPOCHS, metadata=_help(
        "The default budget's epochs on a large set (paper 500), when max_epochs is not given."))
    patience: int = field(default=20, metadata=_help(
        "Early stopping: epochs without a val-loss improvement of min_delta (at least patience_steps "
        "optimiser steps' worth of epochs)."))
    min_steps: int = field(default=MIN_STEPS, metadata=_help(
        "Optimiser steps the default budget (max_epochs not given) allows at least."))
    patience_steps: int = field(default=PATIENCE_STEPS, metadata=_help(
        "Early stopping waits at least this many optimiser steps without an improvement (on a small "
        "set 20 epochs are a few dozen steps, and a noisy val loss stopped training still under-fitting)."))
    min_delta: float = field(default=0.0, metadata=_help(
        "Smallest val-loss decrease that counts as an improvement for early stopping."))
    seed: int = field(default=0, metadata=_help("Seed of the initial weights and the batch order."))
    threads: int = field(default=2, metadata=_help("torch CPU threads."))
    drop_outliers: bool = field(default=True, metadata=_help(
        "Rows flagged `outlier` (encoder glitches) are not used as targets."))
    target_frame: TargetFrame | None = field(default=None, metadata=_help(
        "FK poses learned in the tracker frame (paper) or in the outer tube's frame (outer; "
        "ctrkin.models.frame). Default: the model's own, outer for lstm_mlp_branch (follow_mlp fixes "
        "it), tracker for the others. With --tcm-prior the tracker frame can do better: "
        "docs/learned_kinematics.md, The frame under the TCM prior."))
    lr_schedule: LrSchedule = field(default="constant", metadata=_help(
        "constant (paper) or cosine decay to lr/50 over max_epochs."))
    gate_weight: float = field(default=0.1, metadata=_help(
        "Branch models only (ctrkin.families.snap_aware): weight of the gate's cross-entropy beside "
        "the MAE loss."))
    unknown_prob: float = field(default=0.1, metadata=_help(
        "Branch models only: how often the previous branch state is hidden in training."))
    fold_scale: bool = field(default=False, metadata=_help(
        "Branch models only: the fold gate also fits a scale g on the nominal robot's folds "
        "(θ± = g·φ± ± c − κ·m_N, kept only where it lowers the leave-one-run-out residual of the "
        "training snaps; ctrkin.families.snap_aware.fold_gate); without it g = 1. The recommended "
        "FK's (`ctrkin train --task fk` and the reproduction)."))
    catch_up: float = field(default=0.0, metadata=_help(
        "The follow IK only: the share of its training rows that start from joints the recording had "
        "1-60 rows earlier in the same sequence, labelled with the recorded next joints: the catch-up "
        "after a dead band (ctrkin.families.follow.recipe); the recommended IK: 0.25."))
    follow: bool = field(default=False, metadata=_help(
        "The follow IK's feature layout (ctrkin.families.follow); model follow_mlp sets it."))
    loop: Loop = field(default="epoch", metadata=_help(
        "epoch: one gather of the shuffled training tensors per epoch, fused Adam (the per-batch work "
        "is the network alone); batch: the loop up to issue 11, index gathers and a plain Adam step per "
        "batch (kept for comparison: same batches, same seeds)."))
    fused_adam: bool = field(default=True, metadata=_help(
        "The epoch loop's Adam uses the fused CPU kernel (--no-fused-adam: the default kernel; the "
        "epoch loop is then bit-identical to the batch loop)."))
    fused_lstm: bool = field(default=True, metadata=_help(
        "The epoch loop trains a one-layer LSTM over its windows with ctrkin.models.window_lstm (the "
        "gate math fused, no recurrent product at the zero-state position: a batch-1024 step of the "
        "paper's FK ~1.3x faster; equal to torch's nn.LSTM within float32 round-off); "
        "--no-fused-lstm: torch's nn.LSTM (with --no-fused-adam the epoch loop is then bit-identical "
        "to the batch loop)."))
    val_smoothing: float = field(default=0.0, metadata=_help(
        "Early stopping on an exponential moving average of the val loss with this factor (0: the raw "
        "val loss, as the paper); the best epoch's weights are still chosen by the raw val loss."))
    max_seconds: float | None = field(default=None, metadata=_help(
        "Stop after this much training time (s, wall clock; default: no limit)."))
    device: Device = field(default="auto", metadata=_help(
        "Where the network trains: auto (CUDA where torch sees a GPU, else the CPU, and says which), "
        "cpu, or cuda (an error without one). The model folder is the same; results equal the CPU's "
        "within float rounding (ctrkin.training.device)."))

    def __post_init__(self) -> None:
        # the registry (torch, the networks) and the feature layout are imported here, not with the
        # module: `ctrkin train --help` reads this class and should not wait for torch
        from ctrkin.families.registry import get_entry, resolve_options

        if self.task not in ("fk", "ik"):
            raise ModelError(f"task must be 'fk' or 'ik', got {self.task!r}")
        entry = get_entry(self.model)
        object.__setattr__(self, "options", resolve_options(self.model, self.options))
        for key, value in entry.forced.items():
            if key == "task" and self.task != value:
                raise ModelError(f"model {self.model!r} is for task {value!r}, not {self.task!r}")
            object.__setattr__(self, key, value)        # e.g. the ablation entry fixes delta
        for key, value in entry.defaults.items():
            if getattr(self, key) is None:
                object.__setattr__(self, key, value)    # e.g. the snap-aware FK's outer frame
        if self.target_frame is None:
            object.__setattr__(self, "target_frame", "tracker")
        if self.output_activation not in OUTPUT_ACTIVATIONS:
            raise ModelError(f"output_activation must be one of {OUTPUT_ACTIVATIONS}")
        if self.pose_source not in POSE_SOURCES:
            raise ModelError(f"pose_source must be one of {POSE_SOURCES}, got {self.pose_source!r}")
        if self.split not in SPLITS:
            raise ModelError(f"split must be one of {SPLITS}, got {self.split!r}")
        for name, lo in (("batch_size", 1), ("max_epochs", 1), ("base_epochs", 1), ("patience", 1),
                         ("threads", 1),
                         ("min_steps", 0), ("patience_steps", 0)):
            v = getattr(self, name)
            if name == "max_epochs" and v is None:
                continue
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
        if self.tcm_prior and self.task != "fk":
            raise ModelError("tcm_prior applies to FK models only (task 'fk'): an IK model has no "
                             "physics prior to learn the residual of; drop --tcm-prior")
        if self.joint_field and (self.task != "fk" or self.target_frame != "outer"):
            raise ModelError("joint_field applies to FK models in the outer tube's frame (task 'fk', "
                             "target_frame 'outer', the snap-aware FK's default); drop it "
                             "(--no-joint-field) for another frame")
        if self.select_by_validation and self.task != "fk":
            raise ModelError("select_by_validation chooses between FK models (task 'fk')")
        if self.lr_schedule not in LR_SCHEDULES:
            raise ModelError(f"lr_schedule must be one of {LR_SCHEDULES}, got {self.lr_schedule!r}")
        if self.fold_scale and self.model != "lstm_mlp_branch":
            raise ModelError("fold_scale applies to the snap-aware FK's fold gate (model 'lstm_mlp_branch')")
        if not (self.gate_weight >= 0 and 0 <= self.unknown_prob <= 1):
            raise ModelError("gate_weight must be >= 0 and unknown_prob in [0, 1]")
        if not 0 <= self.catch_up <= 1 or (self.catch_up and not self.follow):
            raise ModelError("catch_up is a share in [0, 1] of the follow IK's training rows (model "
                             "'follow_mlp')")
        if self.loop not in LOOPS:
            raise ModelError(f"loop must be one of {LOOPS}, got {self.loop!r}")
        if not 0 <= self.val_smoothing < 1:
            raise ModelError(f"val_smoothing must be in [0, 1), got {self.val_smoothing}")
        if self.max_seconds is not None and not self.max_seconds > 0:
            raise ModelError(f"max_seconds must be positive or None, got {self.max_seconds}")
        if self.device not in DEVICES:
            raise ModelError(f"device must be one of {DEVICES}, got {self.device!r}")
        if self.min_delta < 0:
            raise ModelError(f"min_delta must be >= 0, got {self.min_delta}")
        self.layout(2)   # validates ib and angle_encoding

    def steps_per_epoch(self, train_rows: int) -> int:
        """Optimiser steps of one epoch over `train_rows` training rows (the last batch may be short)."""
        return max(1, math.ceil(train_rows / self.batch_size))

    def epoch_budget(self, train_rows: int) -> int:
        """max_epochs, or when it is not given base_epochs raised to min_steps optimiser steps."""
        if self.max_epochs is not None:
            return self.max_epochs
        return max(self.base_epochs, math.ceil(self.min_steps / self.steps_per_epoch(train_rows)))

    def patience_epochs(self, train_rows: int) -> int:
        """Early stopping's patience in epochs: `patience`, or patience_steps optimiser steps if that
        is more epochs (a small set's epoch is a few steps)."""
        return max(self.patience, math.ceil(self.patience_steps / self.steps_per_epoch(train_rows)))

    def layout(self, n_tubes: int) -> FeatureLayout:
        from ctrkin.models.features import FeatureLayout

        return FeatureLayout(task=self.task, n_tubes=n_tubes, ib=self.ib, delta=self.delta,
                             angle_encoding=self.angle_encoding, family="follow" if self.follow else None,
                             play=self.play_lags, equivariant=self.equivariant,
                             outer_angle=self.outer_angle)

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
                    ignore: tuple[str, ...] = ("max_epochs", "base_epochs", "min_steps", "threads",
                                               "max_seconds", "loop",
                                               "fused_adam", "fused_lstm", "device")) -> list[str]:
        """What differs, as 'key: a vs b' (keys that may change on resume are ignored: how, not what,
        is trained)."""
        a, b = self.to_dict(), other.to_dict()
        return [f"{k}: {json.dumps(a[k])} vs {json.dumps(b[k])}" for k in a
                if k not in ignore and a[k] != b[k]]
