"""From a Dataset to normalised training tensors: features, windows, split, min-max fit on train only."""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, replace

import numpy as np

from ctrkin.data.dataset import Dataset
from ctrkin.data.splits import Split, random_split, split_by_sequence
from ctrkin.errors import ModelError
from ctrkin.models.branch_labels import branch_labels, previous_labels
from ctrkin.models.features import FeatureLayout, sequence_features, windows
from ctrkin.models.frame import OuterFrame
from ctrkin.models.motion import recorded_motion
from ctrkin.models.normalize import MinMax
from ctrkin.models.outer_lag import fit_outer_lag
from ctrkin.training.config import TrainConfig


@dataclass(eq=False)
class Prepared:
    """X: (T, IB, F) float32 normalised windows, Y: (T, O) float32 normalised targets, for every row;
    raw_in: (T, 2N | 6) raw inputs, target: (T, O) raw targets; rows: split -> usable row indices;
    branch models only (else None): state (T,) branch labels, state_prev (T,) the previous row's
    (0.5 at a sequence start), forced (T,) rows whose label does not depend on history."""

    layout: FeatureLayout
    x_norm: MinMax
    y_norm: MinMax
    X: np.ndarray
    Y: np.ndarray
    raw_in: np.ndarray
    target: np.ndarray
    split: Split
    rows: dict[str, np.ndarray]
    bounds: list[tuple[int, int]]
    state: np.ndarray | None = None
    state_prev: np.ndarray | None = None
    forced: np.ndarray | None = None
    frame: OuterFrame | None = None
    outer_deg: np.ndarray | None = None

    def to_world(self, pred: np.ndarray, rows: np.ndarray) -> np.ndarray:
        """Predicted (len(rows), O) targets in the frame users see (tracker frame for FK)."""
        if self.frame is None or self.outer_deg is None:
            return pred
        return self.frame.to_world(pred, self.outer_deg[rows])


def outer_frame(ds: Dataset, joints: np.ndarray, poses: np.ndarray, train: np.ndarray, seed: int
                ) -> tuple[OuterFrame, np.ndarray]:
    """The outer tube's frame of an FK model and the (T,) angle it turns with at each row: the
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


def inputs_and_targets(ds: Dataset, task: str, pose_source: str) -> tuple[np.ndarray, np.ndarray]:
    """Raw model inputs and targets: FK joints -> poses, IK poses -> joints."""
    if pose_source == "true" and not ds.has_truth:
        raise ModelError("pose_source='true' needs a dataset with true_* pose columns (virtual robot); "
                         "use pose_source='measured'")
    poses = ds.poses(true=pose_source == "true")
    return (ds.joints(), poses) if task == "fk" else (poses, ds.joints())


def choose_split(ds: Dataset, cfg: TrainConfig) -> Split:
    if cfg.split == "dataset":
        return ds.get_split(seed=cfg.split_seed)
    if cfg.split == "sequence":
        return split_by_sequence(ds.frame["sequence_id"].to_numpy(), seed=cfg.split_seed)
    return random_split(len(ds.frame), seed=cfg.split_seed)


def data_signature(ds: Dataset) -> str:
    """A short hash of the robot and the samples, to refuse resuming on different data."""
    h = hashlib.sha256(ds.robot.fingerprint().encode())
    for arr in (ds.joints(), ds.poses(), ds.frame["sequence_id"].to_numpy()):
        h.update(np.ascontiguousarray(arr).tobytes())
    return h.hexdigest()[:16]


def split_rows(ds: Dataset, cfg: TrainConfig) -> tuple[Split, dict[str, np.ndarray]]:
    """The split of `cfg` and its usable rows per part (outliers dropped if cfg.drop_outliers)."""
    split = choose_split(ds, cfg)
    keep = np.ones(len(ds.frame), dtype=bool)
    if cfg.drop_outliers:
        keep &= ~ds.frame["outlier"].to_numpy(dtype=bool)
    rows = {name: np.sort(idx[keep[idx]]) for name, idx in
            (("train", split.train), ("val", split.val), ("test", split.test))}
    if len(rows["train"]) == 0 or len(rows["val"]) == 0:
        raise ModelError(f"the split leaves {len(rows['train'])} training and {len(rows['val'])} validation "
                         f"rows; record more sequences (a by-sequence split needs at least 3)")
    return split, rows


def prepare(ds: Dataset, cfg: TrainConfig, branches: bool = False) -> Prepared:
    """Features, windows, split and normalisation of `ds` for `cfg`; branches: also the branch
    labels of a snap-aware model (ctrkin.models.branch_labels, from the `snap` column)."""
    layout = cfg.layout(ds.n_tubes)
    raw_in, target = inputs_and_targets(ds, cfg.task, cfg.pose_source)
    bounds = ds.sequence_bounds()
    split, rows = split_rows(ds, cfg)
    frame, outer_deg, net_in = None, None, raw_in
    if cfg.target_frame == "outer":     # FK targets in the outer tube's frame (ctrkin.models.frame)
        frame, outer_deg = outer_frame(ds, raw_in, target, rows["train"], cfg.seed)
        target = frame.to_local(target, outer_deg)
        net_in = frame.network_joints(raw_in, outer_deg)
    feats = sequence_features(layout, net_in, bounds)
    x_norm = MinMax.fit(feats[rows["train"]])
    y_norm = MinMax.fit(target[rows["train"]])
    X = windows(x_norm.transform(feats), bounds, layout.ib).astype(np.float32)
    Y = y_norm.transform(target).astype(np.float32)
    prep = Prepared(layout, x_norm, y_norm, X, Y, raw_in, target, split, rows, bounds, frame=frame,
                    outer_deg=outer_deg)
    if branches:
        n = ds.n_tubes
        joints = ds.joints()
        labels, forced = branch_labels(joints[:, 0] - joints[:, n - 1], ds.frame["snap"].to_numpy(), bounds)
        prep.state, prep.forced = labels, forced
        prep.state_prev = previous_labels(labels, bounds)
    return prep
