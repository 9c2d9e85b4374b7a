"""Import of a user's robot log: units, quaternion forms, cleaning counts, clear errors."""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ctrkin.data import schema
from ctrkin.data.cleaning import CleaningConfig
from ctrkin.data.importer import ImportConfig, import_csv
from ctrkin.errors import DatasetError
from tests.data.conftest import readings

RENAME = {"time": "stamp", "alpha_1": "rot_in", "alpha_2": "rot_out", "beta_1": "lin_in",
          "beta_2": "lin_out", "x": "px", "y": "py", "z": "pz"}
MAP = {v: k for k, v in RENAME.items()}


def _write(df: pd.DataFrame, path: Path) -> Path:
    df.to_csv(path, index=False, float_format="%.17g")
    return path


def _full_quaternion(q5: np.ndarray, roll_deg: float | np.ndarray = 0.0) -> np.ndarray:
    """(w, x, y, 0) composed with a roll about the tip's own z axis: (R, 4) (w, x, y, z)."""
    h = np.radians(roll_deg) / 2 * np.ones(len(q5))
    c, s = np.cos(h), np.sin(h)
    w, x, y = q5[:, 0], q5[:, 1], q5[:, 2]
    # (w, x, y, 0) ⊗ (c, 0, 0, s)
    return np.column_stack([w * c, x * c + y * s, y * c - x * s, w * s])


@pytest.fixture
def log(sweep) -> pd.DataFrame:
    q, poses = sweep
    return readings(q, poses, n_readings=5, noise_mm=0.02, seed=3)


def test_import_in_radians_and_metres_equals_degrees_and_mm(tmp_path, log):
    ref = import_csv(_write(log, tmp_path / "deg.csv"), _robot(), ImportConfig())
    si = log.rename(columns=RENAME)
    for c in ("rot_in", "rot_out"):
        si[c] = np.radians(si[c])
    for c in ("lin_in", "lin_out", "px", "py", "pz"):
        si[c] = si[c] / 1000.0
    q4 = _full_quaternion(log[["q0", "qx", "qy"]].to_numpy())
    si = si.drop(columns=["q0", "qx", "qy"])
    si[["ox", "oy", "oz", "ow"]] = q4[:, [1, 2, 3, 0]]
    cfg = ImportConfig.from_mapping(MAP, angle_unit="rad", beta_unit="m", position_unit="m",
                                    quaternion_columns=("ox", "oy", "oz", "ow"), quaternion_order="xyzw")
    got = import_csv(_write(si, tmp_path / "si.csv"), _robot(), cfg)
    pd.testing.assert_frame_equal(got.frame, ref.frame, rtol=1e-9, atol=1e-9)
    assert got.meta["cleaning"]["samples"] == ref.meta["cleaning"]["samples"] == 145


def _robot():
    from ctrkin.robots import paper_robot

    return paper_robot()


@settings(max_examples=25, deadline=None)
@given(data=st.data())
def test_unit_conversion_round_trips(data):
    """Any valid joints and positions written in rad/m come back in deg/mm."""
    m = 8
    beta2 = data.draw(st.lists(st.floats(-30.0, 0.0), min_size=m, max_size=m))
    d = data.draw(st.lists(st.floats(0.0, 20.0), min_size=m, max_size=m))
    alpha = data.draw(st.lists(st.floats(-720.0, 720.0), min_size=2 * m, max_size=2 * m))
    pos = data.draw(st.lists(st.floats(-80.0, 80.0), min_size=3 * m, max_size=3 * m))
    q = np.column_stack([np.reshape(alpha, (m, 2)), np.subtract(beta2, d), beta2])
    p = np.reshape(pos, (m, 3))
    frame = pd.DataFrame({"step": np.arange(m), "alpha_1": np.radians(q[:, 0]),
                          "alpha_2": np.radians(q[:, 1]),
                          "beta_1": q[:, 2] / 1000, "beta_2": q[:, 3] / 1000, "x": p[:, 0] / 1000,
                          "y": p[:, 1] / 1000, "z": p[:, 2] / 1000, "q0": 1.0, "qx": 0.0, "qy": 0.0})
    cfg = ImportConfig(angle_unit="rad", beta_unit="m", position_unit="m",
                       cleaning=CleaningConfig(outliers="flag"))
    with tempfile.TemporaryDirectory() as tmp:
        ds = import_csv(_write(frame, Path(tmp) / "log.csv"), _robot(), cfg)
    np.testing.assert_allclose(ds.joints(), q, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(ds.poses()[:, :3], p, rtol=1e-12, atol=1e-9)


def test_quaternion_order_and_roll(tmp_path, log):
    ref = import_csv(_write(log, tmp_path / "ref.csv"), _robot())
    rng = np.random.default_rng(0)
    q4 = _full_quaternion(log[["q0", "qx", "qy"]].to_numpy(), rng.uniform(-180, 180, len(log)))
    q4[::7] *= -1  # q and -q are the same rotation
    base = log.drop(columns=["q0", "qx", "qy"])
    wxyz = base.assign(qw=q4[:, 0], qx=q4[:, 1], qy=q4[:, 2], qz=q4[:, 3])  # named like the fields
    got = import_csv(_write(wxyz, tmp_path / "wxyz.csv"), _robot())
    pd.testing.assert_frame_equal(got.frame, ref.frame, rtol=1e-9, atol=1e-9)
    assert got.meta["cleaning"]["orientation"] == "quaternion"
    xyzw = base.assign(a=q4[:, 1], b=q4[:, 2], c=q4[:, 3], d=q4[:, 0])
    cfg = ImportConfig(quaternion_columns=("a", "b", "c", "d"), quaternion_order="xyzw")
    got = import_csv(_write(xyzw, tmp_path / "xyzw.csv"), _robot(), cfg)
    pd.testing.assert_frame_equal(got.frame, ref.frame, rtol=1e-9, atol=1e-9)
    wrong = ImportConfig(quaternion_columns=("a", "b", "c", "d"), quaternion_order="wxyz")
    bad = import_csv(tmp_path / "xyzw.csv", _robot(), wrong)
    assert np.abs(bad.poses()[:, 3:] - ref.poses()[:, 3:]).max() > 0.1
    assert ref.meta["cleaning"]["warnings"] == []


def test_backward_tangents_are_warned_about(tmp_path, log):
    swapped = ImportConfig.from_mapping({"q0": "qx", "qx": "q0"})  # scalar part mixed up
    ds = import_csv(_write(log, tmp_path / "log.csv"), _robot(), swapped)
    assert any("point backwards" in w and "--quat-order" in w for w in ds.meta["cleaning"]["warnings"])


def test_tangent_orientation(tmp_path, log, sweep):
    from ctrkin.pose import tangent_from_quat

    ref = import_csv(_write(log, tmp_path / "ref.csv"), _robot())
    t = tangent_from_quat(log[["q0", "qx", "qy"]].to_numpy()) * 3.0
    tan = log.drop(columns=["q0", "qx", "qy"]).assign(tx=t[:, 0], ty=t[:, 1], tz=t[:, 2])
    got = import_csv(_write(tan, tmp_path / "tan.csv"), _robot())
    pd.testing.assert_frame_equal(got.frame, ref.frame, rtol=1e-9, atol=1e-9)


def test_five_readings_are_averaged(tmp_path, log, sweep):
    q, poses = sweep
    ds = import_csv(_write(log, tmp_path / "log.csv"), _robot())
    assert len(ds.frame) == len(q)
    assert (ds.frame["n_readings"] == 5).all()
    np.testing.assert_allclose(ds.joints(), q)
    mean = log[["x", "y", "z"]].to_numpy().reshape(len(q), 5, 3).mean(axis=1)
    np.testing.assert_allclose(ds.poses()[:, :3], mean, atol=1e-12)
    np.testing.assert_allclose(ds.poses()[:, 3:], poses[:, 3:], atol=1e-12)
    np.testing.assert_array_equal(ds.frame["step"], np.arange(len(q)))
    np.testing.assert_array_equal(ds.frame["source_line"], 2 + 5 * np.arange(len(q)))
    report = ds.meta["cleaning"]
    assert report["rows_read"] == 5 * len(q)
    assert report["readings_per_sample"] == {"min": 5, "median": 5.0, "max": 5}
    assert ds.meta["noise"]["position_std_mm"] == pytest.approx(0.02, rel=0.1)
    assert ds.meta["protocol"] == "import" and ds.meta["import"]["angle_unit"] == "deg"


def test_outliers_are_removed_and_counted(tmp_path, log, sweep):
    q, _ = sweep
    dirty = log.copy()
    dirty.loc[5 * 30: 5 * 30 + 4, "alpha_1"] += 90.0        # encoder glitch: a whole sample
    dirty.loc[5 * 80: 5 * 80 + 4, "x"] += 6.0               # tracker outlier: a whole sample
    dirty.loc[5 * 100 + 2, "z"] += 9.0                      # one bad reading among five
    path = _write(dirty, tmp_path / "dirty.csv")
    ds = import_csv(path, _robot())
    r = ds.meta["cleaning"]
    assert (r["joint_glitches"], r["pose_outliers"], r["readings_rejected"]) == (1, 1, 1)
    assert r["samples_averaged"] == len(q) and r["samples"] == len(q) - 2
    assert not ds.frame["outlier"].any()
    assert 30 not in ds.frame["step"].to_numpy() and 80 not in ds.frame["step"].to_numpy()
    assert ds.frame.loc[ds.frame["step"] == 100, "n_readings"].item() == 4
    flagged = import_csv(path, _robot(), ImportConfig(cleaning=CleaningConfig(outliers="flag")))
    assert len(flagged.frame) == len(q)
    assert flagged.frame.loc[flagged.frame["outlier"], "step"].tolist() == [30, 80]
    assert flagged.meta["cleaning"]["outliers_action"] == "flagged"


def test_missing_columns_are_named(tmp_path, log):
    path = _write(log.drop(columns=["beta_2", "qy"]), tmp_path / "log.csv")
    with pytest.raises(DatasetError, match=r"missing column\(s\) for \['beta_2', 'orientation: q0,qx,qy"):
        import_csv(path, _robot())
    path = _write(log.rename(columns=RENAME), tmp_path / "renamed.csv")
    with pytest.raises(DatasetError, match=r"--map LOG_COLUMN=FIELD"):
        import_csv(path, _robot())
    typo = {("rot_inner" if k == "rot_in" else k): v for k, v in MAP.items()}
    with pytest.raises(DatasetError, match=r"--map rot_inner=alpha_1: .* has no column 'rot_inner'"):
        import_csv(path, _robot(), ImportConfig.from_mapping(typo))
    with pytest.raises(DatasetError, match="unknown field 'alpha_3'"):
        import_csv(path, _robot(), ImportConfig.from_mapping({**MAP, "rot_in": "alpha_3"}))


def test_nan_and_text_are_named_by_line_and_column(tmp_path, log):
    bad = log.rename(columns=RENAME)
    bad.loc[41, "py"] = np.nan
    path = _write(bad, tmp_path / "nan.csv")
    with pytest.raises(DatasetError, match=r"line 43, column 'py' \(y\) is empty, NaN or inf"):
        import_csv(path, _robot(), ImportConfig.from_mapping(MAP))
    ds = import_csv(path, _robot(), ImportConfig.from_mapping(MAP, drop_incomplete=True))
    assert ds.meta["cleaning"]["rows_incomplete_dropped"] == 1
    text = log.astype(object)
    text.loc[7, "beta_1"] = "12 mm"
    with pytest.raises(DatasetError, match=r"line 9, column 'beta_1' \(beta_1\): '12 mm' is not a number"):
        import_csv(_write(text, tmp_path / "text.csv"), _robot())


def test_unsorted_time_is_named(tmp_path, log):
    bad = log.copy()
    bad.loc[[50, 51], "time"] = bad.loc[[51, 50], "time"].to_numpy()
    with pytest.raises(DatasetError,
                       match=r"line 53, column 'time' \(time\): .* the log must be sorted by time"):
        import_csv(_write(bad, tmp_path / "log.csv"), _robot())


def test_joints_outside_limits_are_named_or_dropped(tmp_path, log):
    bad = log.rename(columns=RENAME)
    bad.loc[60:64, "lin_out"] = 2.0  # outer tube base in front of the plate
    path = _write(bad, tmp_path / "log.csv")
    with pytest.raises(DatasetError, match=r"line 62: joints outside the limits of robot 'paper': "
                                           r"beta_2 must be <= 0 mm.*columns \['lin_in', 'lin_out'\] "
                                           r"read \{'lin_in': -12.0, 'lin_out': 2.0\}.*--drop-invalid"):
        import_csv(path, _robot(), ImportConfig.from_mapping(MAP))
    ds = import_csv(path, _robot(), ImportConfig.from_mapping(MAP, drop_invalid_joints=True))
    assert ds.meta["cleaning"]["rows_invalid_joints_dropped"] == 5
    assert len(ds.frame) == len(log) // 5 - 1
    inverted = log.copy()
    inverted.loc[3, "beta_1"] = 1.0  # inner base in front of the outer one
    with pytest.raises(DatasetError, match=r"line 5: .*beta_1 <= beta_2 is required"):
        import_csv(_write(inverted, tmp_path / "inv.csv"), _robot())


def test_sequences_from_labels_and_time_gaps(tmp_path, log):
    labelled = log.assign(run=np.where(np.arange(len(log)) < 300, "fwd", "back"))
    ds = import_csv(_write(labelled, tmp_path / "lab.csv"), _robot(),
                    ImportConfig.from_mapping({"run": "sequence_id"}))
    assert ds.sequence_bounds() == [(0, 60), (60, 145)]
    assert ds.meta["sequence_labels"] == ["fwd", "back"]
    np.testing.assert_array_equal(ds.frame["step"].to_numpy()[58:62], [58, 59, 0, 1])
    mixed = labelled.copy()
    mixed.loc[400:404, "run"] = "fwd"
    with pytest.raises(DatasetError,
                       match=r"line 402, column 'run' \(sequence_id\): sequence 'fwd' starts again"):
        import_csv(_write(mixed, tmp_path / "mixed.csv"), _robot(),
                   ImportConfig.from_mapping({"run": "sequence_id"}))
    gap = log.copy()
    gap.loc[500:, "time"] += 30.0  # logging paused for 30 s
    path = _write(gap, tmp_path / "gap.csv")
    assert len(import_csv(path, _robot()).sequence_bounds()) == 2
    assert len(import_csv(path, _robot(), ImportConfig(sequence_gap=None)).sequence_bounds()) == 1
    assert len(import_csv(path, _robot(), ImportConfig(sequence_gap=60.0)).sequence_bounds()) == 1


def test_step_column_groups_readings(tmp_path, sweep):
    q, poses = sweep
    log = readings(q[:20], poses[:20], n_readings=3)
    log["sample"] = np.repeat(np.arange(20) * 10, 3)
    log.loc[3:5, "alpha_1"] += 1e-3  # encoder jitter within the readings of one sample
    ds = import_csv(_write(log, tmp_path / "log.csv"), _robot(),
                    ImportConfig.from_mapping({"sample": "step"}))
    assert len(ds.frame) == 20 and (ds.frame["n_readings"] == 3).all()
    np.testing.assert_array_equal(ds.frame["step"], np.arange(20) * 10)
    assert ds.frame["alpha_1"].iloc[1] == pytest.approx(q[1, 0] + 1e-3)


def test_snap_flags(tmp_path, sweep):
    q, poses = sweep
    log = readings(q, poses, n_readings=1)
    ds = import_csv(_write(log, tmp_path / "log.csv"), _robot())
    assert not ds.frame["snap"].any() and ds.meta["cleaning"]["snap_source"] == "detected"
    log["snap"] = 0
    log.loc[40, "snap"] = 1
    ds = import_csv(_write(log, tmp_path / "snap.csv"), _robot())
    assert ds.frame.loc[ds.frame["snap"], "step"].tolist() == [40]
    assert ds.meta["cleaning"]["snap_source"] == "log"


def test_bad_quaternion_norm_is_named(tmp_path, log):
    bad = log.copy()
    bad.loc[12, "q0"] = 0.2
    with pytest.raises(DatasetError,
                       match=r"line 14: the quaternion in columns \['q0', 'qx', 'qy'\] has norm"):
        import_csv(_write(bad, tmp_path / "log.csv"), _robot())


def test_import_config_is_validated():
    with pytest.raises(DatasetError, match="angle unit must be 'deg' or 'rad'"):
        ImportConfig(angle_unit="grad")  # type: ignore[arg-type]
    with pytest.raises(DatasetError, match="field 'x' is mapped twice"):
        ImportConfig.from_mapping({"a": "x", "b": "x"})
    with pytest.raises(DatasetError, match="quaternion_columns needs four log columns"):
        ImportConfig(quaternion_columns=("a", "b", "c"))
    with pytest.raises(DatasetError, match="sequence_gap must be"):
        ImportConfig(sequence_gap=-1.0)


def test_unreadable_files(tmp_path):
    with pytest.raises(DatasetError, match="does not exist"):
        import_csv(tmp_path / "none.csv", _robot())
    (tmp_path / "empty.csv").write_text("")
    with pytest.raises(DatasetError, match="is not a readable CSV file"):
        import_csv(tmp_path / "empty.csv", _robot())
    (tmp_path / "header.csv").write_text(",".join(schema.joint_columns(2)) + "\n\n")
    with pytest.raises(DatasetError, match="has a header but no data rows"):
        import_csv(tmp_path / "header.csv", _robot())


def test_positions_in_metres_read_as_mm_are_warned_about(tmp_path, log):
    metres = log.assign(x=log["x"] / 1000, y=log["y"] / 1000, z=log["z"] / 1000)
    ds = import_csv(_write(metres, tmp_path / "log.csv"), _robot())
    assert any("--units position=m" in w for w in ds.meta["cleaning"]["warnings"])
    ds = import_csv(tmp_path / "log.csv", _robot(), ImportConfig(position_unit="m"))
    assert ds.meta["cleaning"]["warnings"] == []


def test_short_row_is_named(tmp_path):
    path = tmp_path / "short.csv"
    path.write_text("alpha_1,alpha_2,beta_1,beta_2,x,y,z,q0,qx,qy\n0,0,-10,0,1,2,50,1,0,0\n1,0,-10,0,1,2,50\n")
    with pytest.raises(DatasetError, match=r"line 3, column 'q0' \(q0\) is empty"):
        import_csv(path, _robot())


def test_step_beyond_float_precision_is_an_error(tmp_path, log):
    """2^53 + 1 and 2^53 are the same float64: two samples would silently be averaged together."""
    df = log.copy()
    df["step"] = np.repeat(np.arange(len(df) // 5), 5).astype(object)
    df.loc[:4, "step"] = 2**53 + 1
    df.loc[5:, "step"] = [2**53 + 2 + k for k in range(len(df) - 5)]
    path = tmp_path / "big.csv"
    df.to_csv(path, index=False)
    with pytest.raises(DatasetError, match=r"line 2, column 'step'.*2\^53"):
        import_csv(path, _robot())


def test_complex_joint_value_is_named(tmp_path, log):
    df = log.astype({"alpha_1": object})
    df.loc[7, "alpha_1"] = "(3+2j)"
    with pytest.raises(DatasetError, match=r"line 9, column 'alpha_1'.*complex number"):
        import_csv(_write(df, tmp_path / "c.csv"), _robot())


def test_complex_joints_are_errors(tmp_path, log):
    """Issue 9 item 9: complex joints were truncated to their real part."""
    from ctrkin.data import Dataset
    from ctrkin.errors import JointError

    cplx = log.astype({"alpha_1": object})
    cplx.loc[3, "alpha_1"] = "(10+2j)"
    with pytest.raises(DatasetError, match="complex number"):
        import_csv(_write(cplx, tmp_path / "c.csv"), _robot(), ImportConfig())
    with pytest.raises(JointError, match="complex"):
        _robot().check_joints(np.array([1 + 2j, 0, -20, -5]))
    ds = import_csv(_write(log, tmp_path / "ok.csv"), _robot(), ImportConfig())
    frame = ds.frame.copy()
    frame["alpha_1"] = frame["alpha_1"] + 1j
    with pytest.raises(DatasetError, match="alpha_1"):
        Dataset(frame=frame, robot=_robot())


def test_distinct_configurations_sharing_a_step_are_not_averaged(tmp_path):
    """Issue 27 item 9: 484 readings of 484 distinct configurations became 244 samples, each the mean
    of two different joint vectors, with no warning (the log numbered them in pairs)."""
    n = 60
    q = np.zeros((n, 4))
    q[:, 0] = np.arange(n) * 2.0
    q[:, 2], q[:, 3] = -15.0, -5.0
    poses = np.tile([1.0, 2.0, 50.0, 1.0, 0.0, 0.0], (n, 1))
    poses[:, 0] += np.arange(n)
    log = readings(q, poses, n_readings=1)
    log["step"] = np.arange(n) // 2
    path = tmp_path / "log.csv"
    log.to_csv(path, index=False)
    from ctrkin.robots import paper_robot

    ds = import_csv(path, paper_robot(), ImportConfig())
    assert len(ds.frame) == n
    np.testing.assert_array_equal(ds.joints(), q)
    assert any("never averaged" in w for w in ds.meta["cleaning"]["warnings"])
    # real repeated readings (equal joints within a step) are still averaged
    rep = readings(q, poses, n_readings=3)
    rep["step"] = np.repeat(np.arange(n), 3)
    rep.to_csv(path, index=False)
    ds = import_csv(path, paper_robot(), ImportConfig())
    assert len(ds.frame) == n and not ds.meta["cleaning"]["warnings"]
