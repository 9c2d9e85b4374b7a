"""Three-tube NDI logs in the comet-lab format, and the mistakes a two-tube habit makes with them:
the example three-tube profile and robot import them (statuses, missing tools, short rows); a
two-tube profile refuses them; a wrong readings-per-configuration count, a profile for another
number of tubes and joints out of range are refused with what to change. Small logs written here."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from ctrkin.data.profile import load_profile, parse_profile
from ctrkin.data.profile_import import import_with_profile
from ctrkin.errors import DatasetError
from ctrkin.robots.robot import Robot
from tests.lab_logs import ndi_lab_log

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
ROBOT3 = EXAMPLES / "robots" / "comet_nylon_ndi_3tube.toml"
PROFILE3 = EXAMPLES / "profiles" / "comet_ndi_3tube.toml"
PROFILE2 = EXAMPLES / "profiles" / "comet_ndi.toml"
REF_ROT, REF_POS = Rotation.from_euler("xyz", [20, -40, 100], degrees=True), np.array([76.5, -25.1, -1344.8])


def three_tube_log(path: Path, k: int = 6, repeats: int = 20, seed: int = 0, status=None):
    """Random lab joints as the lab's generator draws them (cumulative travel X <= Y <= Z)."""
    rng = np.random.default_rng(seed)
    lin = np.column_stack([rng.integers(0, 41, k), rng.integers(0, 46, k), rng.integers(0, 46, k)])
    travel = np.cumsum(lin, axis=1).astype(float)
    rot = rng.integers(-45, 46, (k, 3)).astype(float)
    tips = rng.normal(size=(k, 1, 3)) * 10 + np.array([0.0, 0.0, 120.0]) + np.zeros((k, repeats, 3))
    return ndi_lab_log(path, travel, rot, tips, REF_ROT, REF_POS, status), travel, rot, tips[:, 0]


def test_the_three_tube_profile_imports_a_three_tube_log_with_bad_readings(tmp_path):
    status = np.full((6, 20), "Enabled", dtype=object)
    status[1, 3:6] = "PartiallyOutOfVolume"
    status[2, 0] = "Missing"                                   # its cells empty
    status[4, 19] = "OutOfVolume"
    log, travel, rot, tips = three_tube_log(tmp_path / "2023-11-20_01-51-26.csv", status=status)
    text = log.read_text().splitlines()
    text[2 * 20 + 5] = text[2 * 20 + 5].split(",Enabled,")[0] + ",Missing,"      # a short row: tool 2 gone
    log.write_text("\n".join(text) + "\n")
    robot = Robot.from_toml(ROBOT3)
    ds = import_with_profile([log], load_profile(PROFILE3, 3), robot)
    f = ds.frame
    assert len(f) == 6 and ds.meta["cleaning"]["profile_drops"]["rows_status"] == 6
    assert f["n_readings"].tolist() == [20, 17, 18, 20, 19, 20]
    np.testing.assert_allclose(ds.joints()[:, :3], rot[:, ::-1])                     # C, B, A
    np.testing.assert_allclose(ds.joints()[:, 3:], travel[:, ::-1] - [250.0, 170.0, 90.0])
    np.testing.assert_allclose(f[["x", "y", "z"]].to_numpy(), tips, atol=1e-5)
    assert ds.meta["orientation"] == "absent"


def test_a_two_tube_profile_refuses_a_three_tube_log(tmp_path):
    log, *_ = three_tube_log(tmp_path / "three.csv")
    robot2 = Robot.from_toml(EXAMPLES / "robots" / "comet_nylon_ndi.toml")
    with pytest.raises(DatasetError, match=r"line 1, column 7 reads .* stays 0.*comet_ndi_3tube\.toml"):
        import_with_profile([log], load_profile(PROFILE2, 2), robot2)
    with pytest.raises(DatasetError, match=r"maps the joints of a 2-tube robot .* robot has 3 tubes"):
        load_profile(PROFILE2, 3)
    with pytest.raises(DatasetError, match=r"maps the joints of a 3-tube robot .* robot has 2 tubes"):
        load_profile(PROFILE3, 2)


@pytest.mark.parametrize("count, words", [(10, "split into 2 samples; set [groups] count = 20"),
                                          (40, "change inside a group of 40 readings"),
                                          (30, "configuration lasts 20 rows: set [groups] count = 20")])
def test_a_wrong_readings_per_configuration_count_is_refused(tmp_path, count, words):
    log, *_ = three_tube_log(tmp_path / "three.csv")
    profile = parse_profile(PROFILE3.read_text().replace("joints_unchanged = true", f"count = {count}"), 3,
                            "p.toml")
    with pytest.raises(DatasetError) as e:
        import_with_profile([log], profile, Robot.from_toml(ROBOT3))
    assert words in str(e.value) and "p.toml" in str(e.value)


def test_joint_errors_point_at_the_profile_not_at_options_it_ignores(tmp_path):
    log, *_ = three_tube_log(tmp_path / "three.csv")
    profile = parse_profile(PROFILE3.read_text().replace('column = 4, zero = "straight_length"',
                                                         "column = 4, zero = 0"), 3, "p.toml")
    with pytest.raises(DatasetError) as e:
        import_with_profile([log], profile, Robot.from_toml(ROBOT3))
    assert "check p.toml: its [columns]" in str(e.value) and "--units" not in str(e.value)
