"""How a model family learns: the `Recipe` a family gives the generic training engine
(ctrkin.training.engine), and the paper's recipe (IV.A) that the windowed families share.

The engine owns what every training has: the split, the folder built aside and swapped in under a
lock, the seeds, Adam, the epochs with their learning rate, early stopping, per-epoch checkpoints,
history and curves. A recipe owns what its family learns from and how:

    prepare(data)             features, targets and normalisation from the training rows -> Prepared
    epoch_tensors(epoch, b)   the (X, Y) training tensors of an epoch (the same every epoch, or drawn
                              anew: the follow IK perturbs its joints each epoch and rolls itself out)
    loss(net, x, y, idx, g)   one batch's loss (paper: MAE); idx: the batch's rows of those tensors
    val_loss(net)             the validation loss early stopping watches
    finish(bundle, folder)    its metrics (val / test errors in physical units) and its own files

`checkpoints`: whether the engine keeps a checkpoint after every epoch and resumes from it; a recipe
without (a cheap training) is started over when killed, and a finished folder of the same setup is
reused.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
import torch

from ctrkin.data.dataset import Dataset
from ctrkin.data.tracker_view import recorded_tracker_view
from ctrkin.errors import ModelError
from ctrkin.metrics import metrics_json_joint_errors, metrics_json_pose_errors
from ctrkin.models.features import FeatureLayout, delta_columns, postprocess, sequence_features, windows
from ctrkin.models.field import PositionField
from ctrkin.models.frame import OuterFrame
from ctrkin.models.joint_field import FieldLayer, TrackerLoss, field_if_it_helps, field_layer
from ctrkin.models.motion import recorded_motion
from ctrkin.models.normalize import MinMax
from ctrkin.models.outer_lag import fit_outer_lag
from ctrkin.models.play_lags import recorded_lags
from ctrkin.models.store import FRAME, write_json
from ctrkin.models.tcm_prior import calibrate_prior, dataset_prior, save_prior
from ctrkin.models.workspace import Workspace

if TYPE_CHECKING:
    from ctrkin.calibration.model import CalibratedTCM
    from ctrkin.data.splits import Split
    from ctrkin.models.store import ModelBundle

Log = Callable[[str], None]


class TrainSettings(Protocol):
    """The fields of a training configuration (ctrkin.training.TrainConfig) that recipes read."""

    @property
    def task(self) -> str:
        ...

    @property
    def model(self) -> str:
        ...

    @property
    def ib(self) -> int:
        ...

    @property
    def pose_source(self) -> str:
        ...

    @property
    def target_frame(self) -> str | None:     # TrainConfig resolves None to the model's frame
        ...

    @property
    def seed(self) -> int:
        ...

    @property
    def max_epochs(self) -> int | None:      # the engine hands recipes a resolved budget (an int)
        ...

    @property
    def val_smoothing(self) -> float:
        ...

    @property
    def max_seconds(self) -> float | None:
        ...

    @property
    def gate_weight(self) -> float:
        ...

    @property
    def unknown_prob(self) -> float:
        ...

    @property
    def fold_scale(self) -> bool:
        ...

    @property
    def catch_up(self) -> float:
        ...

    @property
    def tcm_prior(self) -> bool:
        ...

    @property
    def joint_field(self) -> bool:
        ...

    def layout(self, n_tubes: int) -> FeatureLayout:
        ...


@dataclass(frozen=True, eq=False)
class TrainingData:
    """What the engine hands a recipe: the dataset, the configuration, the split and the usable rows
    of each part ("train", "val", "test"; outliers dropped where the configuration says so)."""

    ds: Dataset
    cfg: TrainSettings
    split: Split
    rows: dict[str, np.ndarray]


@dataclass(frozen=True, eq=False)
class Prepared:
    """What the model folder stores of a recipe's preparation: the feature layout, the min-max pre/post
    step fitted on the training rows, the outer-tube frame (or None) and config.json entries of the
    family's own (`extra`, beside the data's provenance)."""

    layout: FeatureLayout
    x_norm: MinMax
    y_norm: MinMax
    frame: OuterFrame | None = None
    extra: dict[str, Any] = field(default_factory=dict)


class Recipe(Protocol):
    """A family's training (module docstring)."""

    checkpoints: bool

    def prepare(self, data: TrainingData) -> Prepared:
        ...

    def epoch_tensors(self, epoch: int, bundle: ModelBundle) -> tuple[torch.Tensor, torch.Tensor]:
        ...

    def loss(self, net: torch.nn.Module, x: torch.Tensor, y: torch.Tensor, idx: torch.Tensor,
             gen: torch.Generator) -> torch.Tensor:
        ...

    def val_loss(self, net: torch.nn.Module) -> float:
        ...

    def attach(self, net: torch.nn.Module) -> None:     # what trains beside the network, on it
        ...

    def detach(self, net: torch.nn.Module) -> None:     # ... and off it before it is saved
        ...

    def finish(self, bundle: ModelBundle, folder: Path, log: Log) -> dict[str, Any]:
        ...


def inputs_and_targets(ds: Dataset, task: str, pose_source: str) -> tuple[np.ndarray, np.ndarray]:
    """Raw model inputs and targets: FK joints -> poses, IK poses -> joints."""
    if pose_source == "true" and not ds.has_truth:
        raise ModelError("pose_source='true' needs a dataset with true_* pose columns (virtual robot); "
                         "use pose_source='measured'")
    poses = ds.poses(true=pose_source == "true")
    return (ds.joints(), poses) if task == "fk" else (poses, ds.joints())


def fit_outer_frame(ds: Dataset, joints: np.ndarray, poses: np.ndarray, train: np.ndarray, seed: int
                    ) -> tuple[OuterFrame, np.ndarray]:
    """The outer tube's frame of a model and the (T,) angle it turns with at each row: the
    registration fitted on training rows, then the outer tube's lag (ctrkin.models.outer_lag) from
    training rows at rest and after outer turns, with m_N followed across the runs of ds. The network
    sees the frame's angle as its αN input (OuterFrame.lagged_inputs)."""
    n = ds.n_tubes
    frame = OuterFrame.fit(ds.robot, joints[train], poses[train], seed=seed)
    bounds = ds.sequence_bounds()
    motion, _ = recorded_motion(ds.frame, joints, bounds, n)
    use = np.zeros(len(joints), dtype=bool)
    use[train] = True
    local = frame.to_local(poses, joints[:, n - 1])
    lag = fit_outer_lag(ds.robot, joints, local, motion, bounds, use)
    frame = replace(frame, lag=lag, lagged_inputs=True)
    return frame, frame.outer_angle(ds.robot, joints, motion)


def predict_windows(net: torch.nn.Module, X: np.ndarray, rows: np.ndarray, batch: int = 8192) -> np.ndarray:
    """Network outputs (len(rows), O) for the windows X[rows] (normalised space), torch, no grad."""
    outs = []
    net.eval()
    with torch.inference_mode():
        for a in range(0, len(rows), batch):
            outs.append(net(torch.from_numpy(X[rows[a:a + batch]])).numpy())
    return np.concatenate(outs) if outs else np.zeros((0, net.n_outputs), np.float32)  # type: ignore


class WindowRecipe:
    """The paper's recipe (IV.A, eq. 1-2): per-step features in windows of IB steps that never cross
    a sequence, min-max fitted on the training rows, targets in the tracker frame or the outer tube's
    (ctrkin.models.frame), the MAE loss; an IK model also gets its workspace (ctrkin.models.workspace).

    After `prepare`: X (T, IB, F) and Y (T, O) float32 normalised windows and targets of every row,
    raw_in (T, 2N | 6) raw inputs, target (T, O) raw targets (local frame where there is one; with
    tcm_prior the position's residual from the prior), bounds the sequences, frame and outer_deg (T,)
    the frame's angle (None without a frame), prior_tcm and prior_pos (T, 3) mm the calibrated TCM
    and its positions in the target's frame (None without tcm_prior); tracker the loss through a
    position field learned with the network (ctrkin.models.joint_field; None without joint_field)."""

    checkpoints = True

    def __init__(self, cfg: TrainSettings) -> None:
        self.cfg = cfg

    def prepare(self, data: TrainingData) -> Prepared:
        cfg, ds = self.cfg, data.ds
        self.data = data
        self.layout = cfg.layout(ds.n_tubes)
        self.raw_in, target = inputs_and_targets(ds, cfg.task, cfg.pose_source)
        self.bounds = ds.sequence_bounds()
        self.rows = data.rows
        self.frame: OuterFrame | None = None
        self.outer_deg: np.ndarray | None = None
        self.prior_tcm: CalibratedTCM | None = None
        self.prior_pos: np.ndarray | None = None
        prior = None
        if cfg.tcm_prior:               # the calibrated TCM along the recorded runs (ctrkin.models.tcm_prior)
            self.prior_tcm = calibrate_prior(ds, self.rows["train"])
            prior = dataset_prior(self.prior_tcm, ds)
        net_in = self.raw_in
        tracker_target = target
        if cfg.target_frame == "outer":     # FK targets in the outer tube's frame (ctrkin.models.frame)
            self.frame, self.outer_deg = fit_outer_frame(ds, self.raw_in, target, self.rows["train"],
                                                         cfg.seed)
            target = self.frame.to_local(target, self.outer_deg)
            if prior is not None:       # the same affine map: the residual adds back exactly
                prior = self.frame.to_local(prior, self.outer_deg)
            net_in = self.frame.network_joints(self.raw_in, self.outer_deg)
        if prior is not None:           # the network learns the position's residual
            self.prior_pos = prior[:, :3].copy()
            target = np.array(target, dtype=np.float64, copy=True)
            target[:, :3] -= self.prior_pos
        self.target = target
        lags = None
        if self.layout.play:            # the play lags of the joints as recorded, along each run
            lags = recorded_lags(ds.frame, self.raw_in, self.bounds, ds.n_tubes).columns()
        feats = sequence_features(self.layout, net_in, self.bounds, lags)
        self.x_norm = MinMax.fit(feats[self.rows["train"]])
        self.y_norm = MinMax.fit(target[self.rows["train"]])
        self.X = windows(self.x_norm.transform(feats), self.bounds, self.layout.ib).astype(np.float32)
        self.Y = self.y_norm.transform(target).astype(np.float32)
        train = self.rows["train"]
        self.Xt, self.Yt = torch.from_numpy(self.X[train]), torch.from_numpy(self.Y[train])
        self.tracker: TrackerLoss | None = None
        self.field_layer: FieldLayer | None = None
        if cfg.joint_field:             # positions judged in the tracker frame (ctrkin.models.joint_field)
            assert self.frame is not None and self.outer_deg is not None
            reg = self.frame.registration
            self.tracker = TrackerLoss.build(self.y_norm, self.outer_deg, prior, tracker_target,
                                             reg.rotation, reg.translation, train)
            self.train_t = torch.from_numpy(np.asarray(train, np.int64))
            self.field_centre = tracker_target[train, :3].mean(axis=0)
            self.field_scale = float(np.sqrt(((tracker_target[train, :3] - self.field_centre) ** 2)
                                             .sum(axis=1).mean())) or 1.0
        return Prepared(self.layout, self.x_norm, self.y_norm, self.frame)

    def epoch_tensors(self, epoch: int, bundle: ModelBundle) -> tuple[torch.Tensor, torch.Tensor]:
        return self.Xt, self.Yt

    def loss(self, net: torch.nn.Module, x: torch.Tensor, y: torch.Tensor, idx: torch.Tensor,
             gen: torch.Generator) -> torch.Tensor:
        return self.pose_loss(net, net(x), y, idx)

    def pose_loss(self, net: torch.nn.Module, y_hat: torch.Tensor, y: torch.Tensor, idx: torch.Tensor
                  ) -> torch.Tensor:
        """The MAE of a batch's outputs y_hat against y (paper IV.A), its positions in the tracker
        frame through the field layer where one is learned (ctrkin.models.joint_field)."""
        if self.tracker is None:
            return torch.nn.functional.l1_loss(y_hat, y)
        return self.tracker.loss(field_layer(net), y_hat, y, self.train_t[idx])

    def attach(self, net: torch.nn.Module) -> None:
        """Add what trains beside the network to it before the optimiser sees its parameters: the
        field layer of a joint field (its weights then follow the network's best epoch and
        checkpoints). `detach` takes it off before the network is saved."""
        if self.tracker is not None:
            net.joint_field = FieldLayer(self.field_centre, self.field_scale)

    def detach(self, net: torch.nn.Module) -> None:
        if hasattr(net, "joint_field"):
            self.field_layer = field_layer(net)
            del net.joint_field

    def predict_rows(self, net: torch.nn.Module, rows: np.ndarray, X: np.ndarray | None = None
                     ) -> np.ndarray:
        """Normalised outputs (len(rows), O) of the network for rows of the dataset; X: the
        normalised windows (T, IB, F) to read them from (default the training's, self.X)."""
        return predict_windows(net, self.X if X is None else X, rows)

    def val_loss(self, net: torch.nn.Module) -> float:
        rows = self.rows["val"]
        pred = self.predict_rows(net, rows)
        if self.tracker is None:
            return float(np.mean(np.abs(pred - self.Y[rows])))
        with torch.no_grad():
            return float(self.tracker.loss(field_layer(net), torch.from_numpy(pred),
                                           torch.from_numpy(self.Y[rows]), torch.from_numpy(rows)))

    def to_world(self, pred: np.ndarray, rows: np.ndarray) -> np.ndarray:
        """Predicted (len(rows), O) targets in the frame users see (the tracker frame for FK), the
        prior's positions added back where the network learned the residual."""
        if self.prior_pos is not None:
            pred = np.array(pred, dtype=np.float64, copy=True)
            pred[:, :3] += self.prior_pos[rows]
        if self.frame is None or self.outer_deg is None:
            return pred
        return self.frame.to_world(pred, self.outer_deg[rows])

    def finish(self, bundle: ModelBundle, folder: Path, log: Log) -> dict[str, Any]:
        if self.prior_tcm is not None:
            save_prior(self.prior_tcm, folder)
            bundle.prior = self.prior_tcm
        field = self.keep_joint_field(bundle, folder, log) if self.field_layer is not None else None
        if field is None and self.layout.equivariant and self.frame is not None:
            self.fit_field(bundle, folder, log)
        metrics = self.evaluate(bundle)
        if field is not None:
            metrics["joint_field"] = field
        if self.layout.task == "ik":
            train, val = self.rows["train"], self.rows["val"]
            pose_norm = self.x_norm.subset(slice(0, 6))
            Workspace.fit(self.raw_in[train], self.raw_in[val], pose_norm,
                          train_joints=self.target[train]).save(folder)
        return metrics

    def fit_field(self, bundle: ModelBundle, folder: Path, log: Log) -> None:
        """An equivariant FK's position field (ctrkin.models.field) from its training rows' residuals
        against the poses it learned from, into the frame (and the folder's frame.json)."""
        assert self.frame is not None
        train = self.rows["train"]
        yn = self.predict_rows(bundle.net, train)
        pred = self.to_world(postprocess(self.layout, self.y_norm.inverse(yn)), train)
        measured = inputs_and_targets(self.data.ds, "fk", self.cfg.pose_source)[1][train]
        groups = self.data.ds.frame["sequence_id"].to_numpy()[train]
        pf = PositionField.fit(pred[:, :3], measured[:, :3], groups)
        log(f"position field: degree {pf.degree}, cross-validated residual {pf.cv_rms_mm:.3f} mm "
            f"(without it {pf.cv_rms_without_mm:.3f} mm)")
        self.frame = replace(self.frame, field=pf)
        bundle.frame = self.frame
        write_json(folder / FRAME, self.frame.to_dict())

    def keep_joint_field(self, bundle: ModelBundle, folder: Path, log: Log) -> dict[str, Any]:
        """The field learned with the network into the frame (and the folder's frame.json) where it
        lowers the validation rows' position RMS (joint_field.field_if_it_helps); its metrics entry."""
        assert self.frame is not None and self.field_layer is not None
        rows = self.rows["val"] if len(self.rows["val"]) else self.rows["train"]
        yn = self.predict_rows(bundle.net, rows)
        pred = self.to_world(postprocess(self.layout, self.y_norm.inverse(yn)), rows)[:, :3]
        measured = inputs_and_targets(self.data.ds, "fk", self.cfg.pose_source)[1][rows, :3]
        pf, with_mm, without_mm = field_if_it_helps(self.field_layer, pred, measured)
        log(f"position field learned with the network: {with_mm:.3f} mm on the validation rows, "
            f"{without_mm:.3f} mm without it: " + ("kept" if pf is not None else "not kept"))
        if pf is not None:
            self.frame = replace(self.frame, field=pf)
            bundle.frame = self.frame
            write_json(folder / FRAME, self.frame.to_dict())
        return {"kept": pf is not None, "val_position_rmse_mm": with_mm,
                "val_position_rmse_without_mm": without_mm}

    def evaluate(self, bundle: ModelBundle) -> dict[str, Any]:
        """Loss (normalised MAE) and physical errors on the training, validation and test rows (the
        training figures feed the engine's fit summary, ctrkin.training.fit), with the inputs the
        trained model gets in use: step-change features clipped to their training range, as
        `Kinematics.predict` clips them. Without it, a held-out file with larger steps than training's
        (random configurations against sweeps) was reported on extrapolated inputs, and `ctrkin
        evaluate` gave another figure for the same rows."""
        res: dict[str, Any] = {}
        ds = self.data.ds
        measured_fk = self.layout.task == "fk" and bundle.config.pose_source == "measured"
        truth = recorded_tracker_view(ds) if measured_fk else None
        X = self.X
        dcols = delta_columns(self.layout)
        if len(dcols):                  # normalised on the training rows: their range is [0, 1]
            X = X.copy()
            X[..., dcols] = np.clip(X[..., dcols], 0.0, 1.0)
        for part in ("train", "val", "test"):
            rows = self.rows[part]
            if len(rows) == 0:
                continue
            yn = self.predict_rows(bundle.net, rows, X)
            m: dict[str, Any] = {"loss": float(np.mean(np.abs(yn - self.Y[rows]))), "rows": len(rows)}
            pred = self.to_world(postprocess(self.layout, self.y_norm.inverse(yn)), rows)
            if self.layout.task == "fk":
                m["vs_measured"] = metrics_json_pose_errors(pred, ds.poses()[rows],
                                                            ds.meta.get("orientation") != "absent")
                if truth is not None:  # the truth as the tracker sees it: the model's frame and sensor point
                    m["vs_true"] = metrics_json_pose_errors(pred, truth[rows])
                elif ds.has_truth:
                    m["vs_true"] = metrics_json_pose_errors(pred, ds.poses(true=True)[rows])
            else:
                m["joints"] = metrics_json_joint_errors(pred, ds.joints()[rows], ds.n_tubes)
            res[part] = m
        return res
