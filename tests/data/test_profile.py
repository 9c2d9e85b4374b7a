"""Import profiles: parsing errors name the line and key; scales, offsets, travel zero, averaging,
dropping and the reference-body composition on small logs in both comet-lab formats."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from ctrkin.data.profile import parse_profile
from ctrkin.data.profile_import import import_with_profile, relative_pose
from ctrkin.errors import DatasetError
from tests.lab_logs import configurations, ndi_log, nylon_robot, optitrack_log, to_ctrkin

OPTITRACK = """
[file]
header = false

[columns]
alpha_1 = 12
alpha_2 = 11
beta_1 = { column = 9, zero = "straight_length" }
beta_2 = { column = 8, zero = "straight_length" }
x = 14
y = 15
z = 16

[pose]
unit = "m"
orientation = "marker"

[groups]
count = 10

[drop]
all_zero = true
"""

NDI = """
[file]
header = false

[columns]
alpha_1 = 6
alpha_2 = 5
beta_1 = { column = 3, zero = "straight_length" }
beta_2 = { column = 2, zero = "straight_length" }
x = 9
y = 10
z = 11

[pose]
orientation = "marker"

[reference]
x = 18
y = 19
z = 20
quaternion = [21, 22, 23, 24]

[groups]
count = 20

[drop]
status = [{ column = 8, keep = ["Enabled"] }, { column = 17, keep = ["Enabled"] }]
"""


@pytest.mark.parametrize("text, expect", [
    (OPTITRACK.replace('unit = "m"', 'unit = "cm"'), r"line 15, \[pose\] unit"),
    (OPTITRACK.replace("alpha_2 = 11", "alpha_9 = 11"), r"line 7, \[columns\] alpha_9: unknown field"),
    (OPTITRACK.replace("x = 14", "x = 0"), r"line 10, \[columns\] x: column positions count from 1"),
    (OPTITRACK.replace("count = 10", "count = -1"), r"\[groups\] count"),
    (OPTITRACK.replace('orientation = "marker"', 'orientation = "tangent"'), "qw, qx, qy, qz"),
    (OPTITRACK.replace('zero = "straight_length"', 'zero = "front"', 1), r"line 8, \[columns\] beta_1"),
    (OPTITRACK + "\n[extra]\n", "unknown section"),
    (OPTITRACK.replace("[drop]", "[drop"), "not valid TOML.*line"),
])
def test_profile_errors_name_line_and_key(text, expect):
    with pytest.raises(DatasetError, match=expect):
        parse_profile(text, 2, source="p.toml")


def test_optitrack_format_scales_travel_zero_averaging_and_padding(tmp_path):
    robot = nylon_robot()
    lab_q = configurations(6, seed=1)
    tips = np.random.default_rng(2).uniform(-50, 50, (6, 3))
    log = optitrack_log(tmp_path / "sweep_a.csv", lab_q, tips, repeats=10, padding=13, noise_mm=0.05)
    ds = import_with_profile([log], parse_profile(OPTITRACK, 2), robot)
    assert len(ds.frame) == 6
    assert (ds.frame["n_readings"] == 10).all()
    assert ds.meta["cleaning"]["profile_drops"]["rows_all_zero"] == 13
    np.testing.assert_allclose(ds.joints(), to_ctrkin(robot, lab_q), atol=1e-9)   # β = travel − straight
    np.testing.assert_allclose(ds.poses()[:, :3], tips, atol=0.05)                 # m -> mm, averaged
    assert ds.meta["orientation"] == "absent"


def test_scale_and_offset_per_column(tmp_path):
    robot = nylon_robot()
    lab_q = configurations(3, seed=3)
    log = optitrack_log(tmp_path / "a.csv", lab_q, np.zeros((3, 3)) + 10.0, padding=0)
    text = OPTITRACK.replace("alpha_1 = 12", "alpha_1 = { column = 12, scale = -1.0, offset = 5.0 }")
    text = text.replace('beta_2 = { column = 8, zero = "straight_length" }',
                        "beta_2 = { column = 8, scale = 0.5, zero = -100.0 }")
    ds = import_with_profile([log], parse_profile(text, 2), robot)
    np.testing.assert_allclose(ds.frame["alpha_1"], 5.0 - lab_q[:, 0], atol=1e-9)
    np.testing.assert_allclose(ds.frame["beta_2"], 0.5 * lab_q[:, 3] - 100.0, atol=1e-9)


def test_several_files_make_one_dataset_with_a_sequence_each(tmp_path):
    robot = nylon_robot()
    logs = [optitrack_log(tmp_path / f"run_{k}.csv", configurations(4, seed=k),
                          np.full((4, 3), float(k)), padding=2) for k in range(3)]
    ds = import_with_profile(logs, parse_profile(OPTITRACK, 2), robot)
    assert ds.meta["sequence_labels"] == ["run_0", "run_1", "run_2"]
    assert ds.frame.groupby("sequence_id").size().tolist() == [4, 4, 4]


def test_joints_unchanged_groups(tmp_path):
    robot = nylon_robot()
    log = optitrack_log(tmp_path / "a.csv", configurations(5, seed=4), np.ones((5, 3)), repeats=3)
    text = OPTITRACK.replace("count = 10", "joints_unchanged = true")
    ds = import_with_profile([log], parse_profile(text, 2), robot)
    assert len(ds.frame) == 5 and (ds.frame["n_readings"] == 3).all()


def test_ndi_format_status_drop_and_reference_body(tmp_path):
    robot = nylon_robot()
    lab_q = configurations(4, seed=5)
    rel = np.random.default_rng(6).uniform(-40, 40, (4, 3)) + np.array([0.0, 0.0, 80.0])
    rot = Rotation.from_euler("xyz", [30, -50, 120], degrees=True)
    ref_pos = np.array([73.2, 91.3, -1295.6])
    log = ndi_log(tmp_path / "2023-10-7.csv", lab_q, rel, rot, ref_pos, repeats=20, bad_rows=(3, 45))
    ds = import_with_profile([log], parse_profile(NDI, 2), robot)
    assert ds.meta["cleaning"]["profile_drops"]["rows_status"] == 2
    assert ds.frame["n_readings"].tolist() == [19, 20, 19, 20]   # rows 3 and 45 dropped
    np.testing.assert_allclose(ds.poses()[:, :3], rel, atol=1e-5)   # R_refᵀ (p − p_ref)
    np.testing.assert_allclose(ds.joints(), to_ctrkin(robot, lab_q), atol=1e-5)


def test_relative_pose_composes_orientations():
    rng = np.random.default_rng(7)
    r_ref, r_rel = Rotation.random(5, random_state=1), Rotation.random(5, random_state=2)
    p_ref, p_rel = rng.normal(size=(5, 3)), rng.normal(size=(5, 3))
    p_tip = r_ref.apply(p_rel) + p_ref

    def wxyz(r):
        q = r.as_quat()
        return np.column_stack([q[:, 3], q[:, :3]])

    p, q = relative_pose(p_tip, wxyz(r_ref * r_rel), p_ref, wxyz(r_ref))
    np.testing.assert_allclose(p, p_rel, atol=1e-12)
    ang = (Rotation.from_quat(np.column_stack([q[:, 1:], q[:, 0]])).inv() * r_rel).magnitude()
    assert np.all(ang < 1e-9)


def test_missing_column_names_the_file(tmp_path):
    log = optitrack_log(tmp_path / "a.csv", configurations(2), np.zeros((2, 3)))
    text = OPTITRACK.replace("z = 16", "z = 40")
    with pytest.raises(DatasetError, match=r"a\.csv.*column 40 does not exist"):
        import_with_profile([log], parse_profile(text, 2), nylon_robot())


def test_absurd_counts_columns_and_delimiters_are_clear_errors():
    """Issue 27 item 20: profile `count = 2**64` and `delimiter = "\\n"` crashed (OverflowError,
    pandas ValueError); a column position or a scale beyond range likewise."""
    cases = [(OPTITRACK.replace("count = 10", "count = 18446744073709551616"), "count"),
             (OPTITRACK.replace("header = false", 'header = false\ndelimiter = "\\n"'), "delimiter"),
             (OPTITRACK.replace("header = false", 'header = false\ndelimiter = "."'), "delimiter"),
             (OPTITRACK.replace("x = 14", "x = 18446744073709551616"), "column positions"),
             (OPTITRACK.replace("x = 14", "x = { column = 14, scale = inf }"), "finite")]
    for text, words in cases:
        with pytest.raises(DatasetError, match=words):
            parse_profile(text, 2, source="p.toml")


def test_a_group_of_readings_with_different_joints_is_not_averaged(tmp_path):
    """Issue 27 item 9: a fixed count grouped readings of distinct configurations (a log written with
    one reading per configuration) and averaged them into poses no configuration had."""
    robot = nylon_robot()
    lab = configurations(40, seed=3)
    tips = np.column_stack([np.zeros(40), np.zeros(40), 200.0 + np.arange(40)])
    log = optitrack_log(tmp_path / "a.csv", lab, tips, repeats=1)
    # a profile's count that does not fit the log is refused with the count that does (issue 22's
    # readings-count check, which runs before any grouping): nothing is averaged
    with pytest.raises(DatasetError, match=r"joints change inside a group of 10 .* set \[groups\] count = 1"):
        import_with_profile([log], parse_profile(OPTITRACK, 2), robot)     # count = 10
    fitted = OPTITRACK.replace("count = 10", "count = 1")
    assert fitted != OPTITRACK
    ds = import_with_profile([log], parse_profile(fitted, 2), robot)
    assert len(ds.frame) == 40                                               # not 4 averages
    np.testing.assert_allclose(ds.joints(), to_ctrkin(robot, lab), atol=1e-9)
