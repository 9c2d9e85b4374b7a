"""From a Dataset to normalised training tensors: features, windows, split, min-max fit on train only."""

from __future__ import annotations

import hashlib
from dataclasses import dataclass

import numpy as np

from ctrkin.data.dataset import Dataset
from ctrkin.data.splits import Split, random_split, split_by_sequence
from ctrkin.errors import ModelError
from ctrkin.models.features import FeatureLayout, sequence_features, windows
from ctrkin.models.normalize import MinMax
from ctrkin.training.config import TrainConfig


@dataclass(eq=False)
class Prepared:
    """X: (T, IB, F) float32 normalised windows, Y: (T, O) float32 normalised targets, for every row;
    raw_in: (T, 2N | 6) raw inputs, target: (T, O) raw targets; rows: split -> usable row indices."""

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


def prepare(ds: Dataset, cfg: TrainConfig) -> Prepared:
    layout = cfg.layout(ds.n_tubes)
    raw_in, target = inputs_and_targets(ds, cfg.task, cfg.pose_source)
    bounds = ds.sequence_bounds()
    feats = sequence_features(layout, raw_in, bounds)
    split = choose_split(ds, cfg)
    keep = np.ones(len(ds.frame), dtype=bool)
    if cfg.drop_outliers:
        keep &= ~ds.frame["outlier"].to_numpy(dtype=bool)
    rows = {name: np.sort(idx[keep[idx]]) for name, idx in
            (("train", split.train), ("val", split.val), ("test", split.test))}
    if len(rows["train"]) == 0 or len(rows["val"]) == 0:
        raise ModelError(f"the split leaves {len(rows['train'])} training and {len(rows['val'])} validation "
                         f"rows; record more sequences (a by-sequence split needs at least 3)")
    x_norm = MinMax.fit(feats[rows["train"]])
    y_norm = MinMax.fit(target[rows["train"]])
    X = windows(x_norm.transform(feats), bounds, layout.ib).astype(np.float32)
    Y = y_norm.transform(target).astype(np.float32)
    return Prepared(layout, x_norm, y_norm, X, Y, raw_in, target, split, rows, bounds)
