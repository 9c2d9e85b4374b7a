"""A dataset: a folder with `data.parquet` (samples) and `meta.json` (how they were made).

Writes are atomic: the folder is built beside the target and swapped in, so an interrupted write
never leaves a half-written dataset and never loses the one that was there.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ctrkin.data import schema
from ctrkin.data.splits import Split, split_by_sequence
from ctrkin.errors import DatasetError, RobotDescriptionError
from ctrkin.robots.robot import Robot
from ctrkin.util.folders import build_folder, file_hash, reading_folder
from ctrkin.util.locks import swapping, writer_lock
from ctrkin.version import __version__

DATA_FILE = "data.parquet"
META_FILE = "meta.json"
SPLIT_FILE = "split.json"


def validate_frame(frame: pd.DataFrame, n_tubes: int, source: str = "dataset") -> None:
    """Check columns, dtypes, NaNs and time order; errors name the column and row to fix."""
    missing = [c for c in schema.required_columns(n_tubes) if c not in frame.columns]
    if missing:
        raise DatasetError(f"{source}: missing column(s) {missing}; required: "
                           f"{schema.required_columns(n_tubes)}")
    if len(frame) == 0:
        raise DatasetError(f"{source}: has no samples (0 rows)")
    for c in schema.INDEX_COLUMNS:
        if not pd.api.types.is_integer_dtype(frame[c]):
            raise DatasetError(f"{source}: column {c!r} must hold integers, got dtype {frame[c].dtype}")
    for c in schema.FLAG_COLUMNS:
        if not pd.api.types.is_bool_dtype(frame[c]):
            raise DatasetError(f"{source}: column {c!r} must hold booleans, got dtype {frame[c].dtype}")
    numeric = schema.joint_columns(n_tubes) + schema.POSE_COLUMNS
    numeric += [c for c in schema.TRUE_POSE_COLUMNS if c in frame.columns]
    for c in numeric:
        if (not pd.api.types.is_numeric_dtype(frame[c]) or pd.api.types.is_bool_dtype(frame[c])
                or pd.api.types.is_complex_dtype(frame[c])):
            raise DatasetError(f"{source}: column {c!r} must hold numbers, got dtype {frame[c].dtype}")
        vals = frame[c].to_numpy(dtype=float)
        bad = ~np.isfinite(vals)
        if bad.any():
            r = int(np.argmax(bad))
            raise DatasetError(f"{source}: column {c!r} has NaN or inf at row {r}")
    sid = frame["sequence_id"].to_numpy()
    step = frame["step"].to_numpy()
    same = sid[1:] == sid[:-1]
    bad_order = same & (step[1:] <= step[:-1])
    if bad_order.any():
        r = int(np.argmax(bad_order)) + 1
        raise DatasetError(f"{source}: row {r}: 'step' must increase within sequence "
                           f"{sid[r]} (got {step[r - 1]} then {step[r]}); sort by time")
    row = schema.restarted_sequence(sid)
    if row is not None:
        raise DatasetError(f"{source}: row {row}: sequence_id {sid[row]} starts again after "
                           "other sequences; the rows of each sequence_id must be contiguous")


def _check_split(split: Split, n_rows: int, source: str) -> None:
    """The split must index rows of this frame, each row at most once."""
    parts = [split.train, split.val, split.test]
    idx = np.concatenate(parts)
    if idx.size and (idx.min() < 0 or idx.max() >= n_rows):
        raise DatasetError(f"{source}: split indexes row {int(idx.max())} but the dataset has {n_rows} "
                           "rows; make the split again (ctrkin dataset split)")
    if len(np.unique(idx)) != idx.size:
        raise DatasetError(f"{source}: split puts some rows in two parts; make the split again "
                           "(ctrkin dataset split)")
    if split.n_rows is not None and split.n_rows != n_rows:
        raise DatasetError(f"{source}: split was made for {split.n_rows} rows but the dataset has "
                           f"{n_rows}; make the split again (ctrkin dataset split)")


@dataclass(eq=False)
class Dataset:
    """frame: the samples (schema.py); robot: the robot they come from; meta: everything else
    (protocol, parameters, seed, noise levels, cleaning report ...)."""

    frame: pd.DataFrame
    robot: Robot
    meta: dict[str, Any] = field(default_factory=dict)
    split: Split | None = None

    def __post_init__(self) -> None:
        validate_frame(self.frame, self.robot.n_tubes)
        if self.split is not None:
            _check_split(self.split, len(self.frame), "dataset")

    # --- views -----------------------------------------------------------------------------------
    @property
    def n_tubes(self) -> int:
        return self.robot.n_tubes

    def joints(self) -> np.ndarray:
        """(T, 2N) joints (deg, mm) in the fixed order α1..αN, β1..βN."""
        return self.frame[schema.joint_columns(self.n_tubes)].to_numpy(dtype=float)

    def poses(self, true: bool = False) -> np.ndarray:
        """(T, 6) measured (or true) tip poses."""
        cols = schema.TRUE_POSE_COLUMNS if true else schema.POSE_COLUMNS
        if true and not self.has_truth:
            raise DatasetError("this dataset has no true pose columns (true_x ...)")
        return self.frame[cols].to_numpy(dtype=float)

    @property
    def has_truth(self) -> bool:
        return all(c in self.frame.columns for c in schema.TRUE_POSE_COLUMNS)

    def sequence_bounds(self) -> list[tuple[int, int]]:
        """[(start, stop)) row ranges of the sequences, in file order."""
        return schema.sequence_bounds(self.frame["sequence_id"].to_numpy())

    def get_split(self, seed: int = 0) -> Split:
        """The saved split, or a by-sequence 70:15:15 split made (and kept) on first use."""
        if self.split is None:
            self.split = split_by_sequence(self.frame["sequence_id"].to_numpy(), seed=seed)
        return self.split

    def save_split(self, folder: str | Path, split: Split, overwrite: bool = False) -> None:
        """Attach `split` and write only split.json into the saved dataset `folder` (atomically,
        under the folder's writer lock, while no reader reads the folder). A saved split that
        differs is replaced only if `overwrite` (DatasetError otherwise); saving the same split
        again changes nothing."""
        _check_split(split, len(self.frame), str(folder))
        target = Path(folder)
        with writer_lock(target, DatasetError, "split"):
            if not (target / DATA_FILE).is_file():
                raise DatasetError(f"{folder} is not a saved dataset; save it first")
            path = target / SPLIT_FILE
            if path.is_file() and not overwrite:
                saved = Split.load(path)
                if saved.to_dict() == split.to_dict():
                    self.split = split
                    return
                raise DatasetError(f"{folder} already has a saved {saved.kind} split (seed {saved.seed}, "
                                   f"sizes {saved.sizes()}); pass --overwrite to replace it")
            with swapping(target):          # a reader of the folder sees the old split or the new
                split.save(path)
        self.split = split

    # --- files -----------------------------------------------------------------------------------
    def save(self, folder: str | Path) -> Path:
        """Write the dataset folder (data.parquet, meta.json, split.json if any) atomically: it is
        built beside `folder` and swapped in, so a failure leaves the previous folder intact.
        `folder`, if it exists, must be a dataset ctrkin wrote (ctrkin.util.ownership), or empty."""
        target = Path(folder)
        meta = {**self.meta, "format_version": schema.FORMAT_VERSION, "robot": self.robot.to_dict(),
                "robot_fingerprint": self.robot.fingerprint(), "n_tubes": self.n_tubes,
                "units": schema.UNITS, "samples": len(self.frame),
                "sequences": int(self.frame["sequence_id"].nunique()),
                "ctrkin_version": __version__}
        with build_folder(target, "dataset", DatasetError, "save") as tmp:
            self.frame.to_parquet(tmp / DATA_FILE, index=False)
            meta["data_sha256"] = file_hash(tmp / DATA_FILE)
            (tmp / META_FILE).write_text(json.dumps(meta, indent=2, default=_json_default))
            if self.split is not None:
                self.split.save(tmp / SPLIT_FILE)
        self.meta = meta
        return target

    @classmethod
    def load(cls, folder: str | Path, robot: Robot | None = None) -> Dataset:
        """Read and validate a dataset folder. If `robot` is given it must be the dataset's robot."""
        with reading_folder(folder) as src:     # one version, never a mix (ctrkin.util.folders)
            return cls._load(src, robot)

    @classmethod
    def _load(cls, src: Path, robot: Robot | None) -> Dataset:
        if not (src / META_FILE).is_file() or not (src / DATA_FILE).is_file():
            raise DatasetError(f"{src} is not a ctrkin dataset: it needs {DATA_FILE} and {META_FILE}")
        try:
            meta = json.loads((src / META_FILE).read_text())
        except (OSError, json.JSONDecodeError) as e:
            raise DatasetError(f"{src / META_FILE} is not valid JSON: {e}") from None
        if not isinstance(meta, dict):
            raise DatasetError(f"{src / META_FILE} must hold a JSON object")
        version = meta.get("format_version")
        if version is None:
            raise DatasetError(f"{src / META_FILE} has no 'format_version': not written by ctrkin")
        if version != schema.FORMAT_VERSION:
            newer = isinstance(version, int) and version > schema.FORMAT_VERSION
            hint = "upgrade ctrkin to read it" if newer else "re-create it with this ctrkin"
            raise DatasetError(f"{src}: dataset format version {version!r}, but this ctrkin "
                               f"{__version__} reads version {schema.FORMAT_VERSION}; {hint}")
        if "robot" not in meta:
            raise DatasetError(f"{src / META_FILE} has no 'robot' description")
        try:
            ds_robot = Robot.from_dict(meta["robot"], source=f"{src / META_FILE} robot")
        except RobotDescriptionError as e:
            raise DatasetError(str(e)) from None
        stored = meta.get("robot_fingerprint")
        if stored is not None and stored != ds_robot.fingerprint():
            raise DatasetError(f"{src / META_FILE}: the robot description does not match its stored "
                               f"fingerprint {stored!r} (now {ds_robot.fingerprint()!r}): it was edited "
                               "after recording; restore it, or record the data again on the new robot")
        if robot is not None and robot.fingerprint() != ds_robot.fingerprint():
            raise DatasetError(f"{src} was recorded on robot {ds_robot.name!r} "
                               f"({ds_robot.fingerprint()}), not on {robot.name!r} "
                               f"({robot.fingerprint()})")
        stored_hash = meta.get("data_sha256")
        if stored_hash is not None and file_hash(src / DATA_FILE) != stored_hash:
            raise DatasetError(f"{src / DATA_FILE} is not the file this dataset was saved with (its "
                               f"SHA-256 differs from meta.json's data_sha256): corrupted or replaced; "
                               "restore it or record the data again")
        try:
            frame = pd.read_parquet(src / DATA_FILE)
        except Exception as e:  # pyarrow raises several types for corrupt files
            raise DatasetError(f"{src / DATA_FILE} cannot be read: {e}") from None
        split = Split.load(src / SPLIT_FILE) if (src / SPLIT_FILE).is_file() else None
        validate_frame(frame, ds_robot.n_tubes, source=str(src))
        if split is not None:
            _check_split(split, len(frame), str(src / SPLIT_FILE))
        return cls(frame=frame, robot=ds_robot, meta=meta, split=split)


def _json_default(o: object) -> object:
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON serialisable: {type(o)}")
