"""Dataset folder format: round trip, version check, corrupted or incomplete files, atomic save."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pandas as pd
import pytest

from ctrkin.data import Dataset, Split, random_split, schema, split_by_sequence
from ctrkin.data.dataset import DATA_FILE, META_FILE, SPLIT_FILE
from ctrkin.errors import DatasetError
from ctrkin.robots import Robot, Tube
from tests.data.conftest import synthetic_frame


def test_round_trip_keeps_frame_meta_and_split(tmp_path, small_dataset):
    small_dataset.split = split_by_sequence(small_dataset.frame["sequence_id"].to_numpy(), seed=3)
    small_dataset.frame["n_readings"] = np.int64(5)  # optional columns survive
    small_dataset.save(tmp_path / "ds")
    back = Dataset.load(tmp_path / "ds")
    pd.testing.assert_frame_equal(back.frame, small_dataset.frame)
    assert back.meta["protocol"] == "test" and back.meta["protocol_params"] == {"k": 1}
    assert back.meta["seed"] == 7
    assert back.meta["format_version"] == schema.FORMAT_VERSION
    assert back.meta["samples"] == len(small_dataset.frame) and back.meta["sequences"] == 5
    assert back.robot.fingerprint() == small_dataset.robot.fingerprint()
    assert back.split is not None and back.split.kind == "sequence" and back.split.seed == 3
    for part in ("train", "val", "test"):
        np.testing.assert_array_equal(back.split.part(part), small_dataset.split.part(part))
    np.testing.assert_array_equal(back.joints(), small_dataset.joints())
    np.testing.assert_array_equal(back.poses(), small_dataset.poses())


def test_views_and_sequence_bounds(small_dataset):
    assert small_dataset.joints().shape == (45, 4)
    assert small_dataset.poses().shape == (45, 6)
    assert small_dataset.sequence_bounds() == [(0, 12), (12, 20), (20, 30), (30, 36), (36, 45)]
    assert not small_dataset.has_truth
    with pytest.raises(DatasetError, match="no true pose columns"):
        small_dataset.poses(true=True)


def test_true_pose_columns_round_trip(tmp_path, small_dataset):
    for c in schema.POSE_COLUMNS:
        small_dataset.frame[f"true_{c}"] = small_dataset.frame[c] + 0.5
    small_dataset.save(tmp_path / "ds")
    back = Dataset.load(tmp_path / "ds")
    assert back.has_truth
    np.testing.assert_allclose(back.poses(true=True)[:, :3], back.poses()[:, :3] + 0.5)


def _edit_meta(folder, **changes):
    meta = json.loads((folder / META_FILE).read_text())
    for k, v in changes.items():
        if v is None:
            meta.pop(k)
        else:
            meta[k] = v
    (folder / META_FILE).write_text(json.dumps(meta))


def test_newer_format_version_is_refused(tmp_path, small_dataset):
    folder = small_dataset.save(tmp_path / "ds")
    _edit_meta(folder, format_version=schema.FORMAT_VERSION + 1)
    with pytest.raises(DatasetError, match=r"format version 2.*reads version 1; upgrade ctrkin"):
        Dataset.load(folder)


def test_missing_format_version_is_refused(tmp_path, small_dataset):
    folder = small_dataset.save(tmp_path / "ds")
    _edit_meta(folder, format_version=None)
    with pytest.raises(DatasetError, match="no 'format_version'"):
        Dataset.load(folder)


def test_corrupted_parquet_is_refused(tmp_path, small_dataset):
    folder = small_dataset.save(tmp_path / "ds")
    data = (folder / DATA_FILE).read_bytes()
    (folder / DATA_FILE).write_bytes(data[: len(data) // 2])
    with pytest.raises(DatasetError, match=r"data\.parquet is not the file this dataset was saved with"):
        Dataset.load(folder)
    _edit_meta(folder, data_sha256=None)      # a folder written by another tool: no hash to check
    with pytest.raises(DatasetError, match=r"data.parquet cannot be read"):
        Dataset.load(folder)


def test_bad_meta_json_is_refused(tmp_path, small_dataset):
    folder = small_dataset.save(tmp_path / "ds")
    (folder / META_FILE).write_text('{"format_version": 1, "robot": ')
    with pytest.raises(DatasetError, match=r"meta\.json is not valid JSON"):
        Dataset.load(folder)


def test_bad_robot_in_meta_is_refused(tmp_path, small_dataset):
    folder = small_dataset.save(tmp_path / "ds")
    _edit_meta(folder, robot={"name": "x"})
    with pytest.raises(DatasetError, match="needs a 'tubes' list"):
        Dataset.load(folder)


def test_missing_files_are_refused(tmp_path, small_dataset):
    folder = small_dataset.save(tmp_path / "ds")
    (folder / DATA_FILE).unlink()
    with pytest.raises(DatasetError, match=r"is not a ctrkin dataset: it needs data\.parquet and meta\.json"):
        Dataset.load(folder)


def _rewrite_frame(folder, frame):
    """data.parquet written by hand or by another tool: without a data_sha256 in meta.json (the
    validation below is what such folders get)."""
    frame.to_parquet(folder / DATA_FILE, index=False)
    _edit_meta(folder, data_sha256=None)


def test_missing_column_is_named(tmp_path, small_dataset):
    folder = small_dataset.save(tmp_path / "ds")
    _rewrite_frame(folder, small_dataset.frame.drop(columns=["z", "beta_2"]))
    with pytest.raises(DatasetError, match=r"missing column\(s\) \['beta_2', 'z'\]"):
        Dataset.load(folder)


def test_nan_is_named_by_column_and_row(tmp_path, small_dataset):
    folder = small_dataset.save(tmp_path / "ds")
    frame = small_dataset.frame.copy()
    frame.loc[17, "qx"] = np.nan
    _rewrite_frame(folder, frame)
    with pytest.raises(DatasetError, match="column 'qx' has NaN or inf at row 17"):
        Dataset.load(folder)


def test_unsorted_steps_are_named_by_row(tmp_path, small_dataset):
    folder = small_dataset.save(tmp_path / "ds")
    frame = small_dataset.frame.copy()
    frame.loc[[4, 5], "step"] = [5, 4]
    _rewrite_frame(folder, frame)
    with pytest.raises(DatasetError, match=r"row 5: 'step' must increase within sequence 0 \(got 5 then 4\)"):
        Dataset.load(folder)


def test_non_contiguous_sequences_are_refused(robot):
    frame = synthetic_frame(robot, lengths=(4, 4, 4))
    frame.loc[8:, "sequence_id"] = 0
    frame.loc[8:, "step"] = np.arange(10, 14)
    with pytest.raises(DatasetError, match="row 8: sequence_id 0 starts again"):
        Dataset(frame=frame, robot=robot)


def test_wrong_dtypes_are_refused(robot):
    frame = synthetic_frame(robot)
    with pytest.raises(DatasetError, match="'snap' must hold booleans"):
        Dataset(frame=frame.assign(snap=frame["snap"].astype(int)), robot=robot)
    with pytest.raises(DatasetError, match="'step' must hold integers"):
        Dataset(frame=frame.assign(step=frame["step"].astype(float)), robot=robot)
    with pytest.raises(DatasetError, match="has no samples"):
        Dataset(frame=frame.iloc[:0], robot=robot)


def test_load_checks_the_robot(tmp_path, small_dataset):
    folder = small_dataset.save(tmp_path / "ds")
    other = Robot(tubes=small_dataset.robot.tubes, name="other")
    with pytest.raises(DatasetError, match="was recorded on robot 'paper'"):
        Dataset.load(folder, robot=other)
    three = Robot(tubes=(*small_dataset.robot.tubes,
                         Tube(od=1.0, id=0.8, straight_length=20.0, curved_length=10.0, curvature=0.02)))
    with pytest.raises(DatasetError, match="was recorded on robot"):
        Dataset.load(folder, robot=three)
    assert Dataset.load(folder, robot=small_dataset.robot).robot.name == "paper"


def test_split_that_does_not_fit_the_frame_is_refused(tmp_path, small_dataset):
    folder = small_dataset.save(tmp_path / "ds")
    random_split(100, seed=0).save(folder / SPLIT_FILE)
    with pytest.raises(DatasetError, match=r"split indexes row 9[0-9] but the dataset has 45 rows"):
        Dataset.load(folder)
    (folder / SPLIT_FILE).write_text('{"kind": "random"}')
    with pytest.raises(DatasetError, match="malformed split: missing key"):
        Dataset.load(folder)


def test_save_split_writes_only_the_split(tmp_path, small_dataset):
    folder = small_dataset.save(tmp_path / "ds")
    before = (folder / DATA_FILE).stat().st_mtime_ns
    split = random_split(len(small_dataset.frame), seed=4)
    small_dataset.save_split(folder, split)
    assert (folder / DATA_FILE).stat().st_mtime_ns == before
    loaded = Dataset.load(folder).split
    assert loaded is not None and loaded.kind == "random" and loaded.n_rows == 45
    with pytest.raises(DatasetError, match="split indexes row"):
        small_dataset.save_split(folder, random_split(50, seed=4))


def test_failed_save_leaves_the_old_dataset_intact(tmp_path, small_dataset, robot, monkeypatch):
    folder = small_dataset.save(tmp_path / "ds")
    new = Dataset(frame=synthetic_frame(robot, lengths=(5, 5, 5), seed=9), robot=robot,
                  split=random_split(15, seed=0))

    def crash(self, path):  # fails after data.parquet and meta.json of the new folder are written
        raise OSError("disk full")

    monkeypatch.setattr(Split, "save", crash)
    with pytest.raises(OSError, match="disk full"):
        new.save(folder)
    back = Dataset.load(folder)
    pd.testing.assert_frame_equal(back.frame, small_dataset.frame)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ds"]  # no temporary folder left behind


def test_save_replaces_an_existing_dataset(tmp_path, small_dataset, robot):
    folder = small_dataset.save(tmp_path / "ds")
    new = Dataset(frame=synthetic_frame(robot, lengths=(5, 5), seed=9), robot=robot)
    new.save(folder)
    assert len(Dataset.load(folder).frame) == 10
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ds"]


def test_get_split_defaults_to_sequences(small_dataset):
    split = small_dataset.get_split(seed=1)
    assert split.kind == "sequence" and small_dataset.get_split() is split


def test_load_recovers_a_swap_interrupted_between_its_renames(tmp_path, small_dataset):
    """Issue 9 item 8: a crash between the two renames left no dataset and the data in `.NAME.old-*`;
    `load` neither recovered nor mentioned it."""
    folder = small_dataset.save(tmp_path / "ds")
    folder.rename(tmp_path / ".ds.old-1a2b3c4d")          # the first rename done, the second not
    with pytest.warns(UserWarning, match="restored"):
        back = Dataset.load(folder)
    pd.testing.assert_frame_equal(back.frame, small_dataset.frame)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ds"]
    # the swap finished but the old copy was not removed yet: the new dataset wins, the copy goes
    shutil.copytree(folder, tmp_path / ".ds.old-5e6f7a8b")
    Dataset.load(folder)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ds"]


def test_edited_robot_in_meta_is_refused(tmp_path, small_dataset):
    """Issue 9 item 8: an edited robot in meta.json loaded although the fingerprint did not match."""
    folder = small_dataset.save(tmp_path / "ds")
    meta = json.loads((folder / META_FILE).read_text())
    meta["robot"]["tubes"][0]["curvature"] *= 1.1
    (folder / META_FILE).write_text(json.dumps(meta))
    with pytest.raises(DatasetError, match="does not match its stored fingerprint"):
        Dataset.load(folder)


def test_flipped_bits_in_the_parquet_file_are_refused(tmp_path, small_dataset):
    """Found by benchmarks/fuzz.py: a few flipped bits in data.parquet loaded as other numbers (parquet
    pages carry no checked CRC). meta.json now holds the file's SHA-256."""
    folder = small_dataset.save(tmp_path / "ds")
    raw = bytearray((folder / DATA_FILE).read_bytes())
    raw[len(raw) // 3] ^= 0x04
    (folder / DATA_FILE).write_bytes(bytes(raw))
    with pytest.raises(DatasetError, match="SHA-256 differs"):
        Dataset.load(folder)
