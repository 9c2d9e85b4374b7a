"""The split a training runs on, and the signatures that tell whether a saved run was made on the same
data and split (resuming on other data would leak trained rows into the test rows)."""

from __future__ import annotations

import hashlib

import numpy as np

from ctrkin.data.dataset import Dataset
from ctrkin.data.splits import Split, random_split, split_by_sequence
from ctrkin.errors import ModelError
from ctrkin.training.config import TrainConfig


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


def split_signature(rows: dict[str, np.ndarray]) -> str:
    """A short hash of the train/val/test rows: resuming on another split would leak the epochs
    trained on the old training rows into the new test rows."""
    h = hashlib.sha256()
    for name in ("train", "val", "test"):
        h.update(name.encode())
        h.update(np.ascontiguousarray(rows[name], dtype=np.int64).tobytes())
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
