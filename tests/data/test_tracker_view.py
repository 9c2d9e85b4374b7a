"""The recorded tracker view (training's truth) is the virtual tracker's, bit for bit, after a save."""

from __future__ import annotations

import numpy as np
import pytest

from ctrkin.acquisition import protocols
from ctrkin.acquisition.demo import sweep_dataset
from ctrkin.acquisition.recorder import record
from ctrkin.data import Dataset
from ctrkin.data.tracker_view import recorded_tracker_view
from ctrkin.errors import DatasetError
from ctrkin.virtual import VirtualRobot
from ctrkin.virtual.truth import tracker_truth


@pytest.fixture(scope="module")
def arbitrary(robot) -> Dataset:
    return record(protocols.build("arbitrary", robot, scale="quick"), VirtualRobot(robot, seed=3), seed=0,
                  workers=1, progress=False)


def test_recorded_view_equals_the_rebuilt_virtual_tracker(arbitrary, tmp_path) -> None:
    expected = tracker_truth(arbitrary)
    assert expected is not None
    np.testing.assert_array_equal(recorded_tracker_view(arbitrary), expected)
    arbitrary.save(tmp_path / "ds")
    np.testing.assert_array_equal(recorded_tracker_view(Dataset.load(tmp_path / "ds")), expected)
    # it is the truth seen through the registration error, not the truth itself
    assert np.abs(expected - arbitrary.poses(true=True)).max() > 1e-3
    assert arbitrary.meta["virtual_robot"]["tracker"]["field_warp"] is not None   # the warp is in it


def test_no_view_without_a_recorded_tracker(arbitrary, robot) -> None:
    tcm_made = sweep_dataset(robot, translations=(10,), outer_alphas=(0,), step_deg=30)
    assert recorded_tracker_view(tcm_made) is None
    incomplete = {"tracker": {"registration_rotation": [[1.0]]}}
    broken = Dataset(frame=arbitrary.frame, robot=arbitrary.robot,
                     meta={**arbitrary.meta, "virtual_robot": incomplete})
    with pytest.raises(DatasetError, match="record the dataset again"):
        recorded_tracker_view(broken)
    bad_warp = {**arbitrary.meta["virtual_robot"]["tracker"], "field_warp": {"amplitude_mm": [[1.0]]}}
    warped = Dataset(frame=arbitrary.frame, robot=arbitrary.robot,
                     meta={**arbitrary.meta, "virtual_robot": {"tracker": bad_warp}})
    with pytest.raises(DatasetError, match="field warp"):
        recorded_tracker_view(warped)
