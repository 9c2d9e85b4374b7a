"""The recommended models' training data: the paper dataset with the excitation runs added to its
training rows only (ctrkin.evaluation.datasets.with_training_runs, save_training_set)."""

from __future__ import annotations

import numpy as np
import pytest

from ctrkin.acquisition import protocols
from ctrkin.acquisition.recorder import record
from ctrkin.errors import DatasetError
from ctrkin.evaluation.datasets import with_training_runs
from ctrkin.virtual import VirtualConfig, VirtualRobot


@pytest.fixture(scope="module")
def recorded(robot):
    virtual = VirtualRobot(robot, VirtualConfig().central(), seed=0)
    paper = record(protocols.build("paper", robot, scale="tiny", levels=(8.0,), outer_step_deg=180.0),
                   virtual, seed=0, workers=1, progress=False)
    extra = record(protocols.build("excitation", robot, scale="tiny", seed=8, runs=2), virtual, seed=8,
                   workers=1, progress=False)
    return paper, extra


def test_the_extra_runs_are_training_rows_only_and_keep_their_own_sequences_and_runs(recorded):
    paper, extra = recorded
    with pytest.raises(DatasetError, match="split"):
        with_training_runs(paper, extra)
    split = paper.get_split(seed=0)
    both = with_training_runs(paper, extra)
    n, m = len(paper.frame), len(extra.frame)
    assert len(both.frame) == n + m == both.split.n_rows
    assert np.array_equal(both.split.val, split.val) and np.array_equal(both.split.test, split.test)
    assert np.array_equal(both.split.train, np.r_[split.train, n + np.arange(m)])
    added = both.frame.iloc[n:]
    assert set(added["sequence_id"]).isdisjoint(paper.frame["sequence_id"])
    assert set(added["run"]).isdisjoint(paper.frame["run"])
    assert added["sequence_id"].nunique() == extra.frame["sequence_id"].nunique() == 2
    assert np.array_equal(both.joints()[n:], extra.joints())
    assert both.meta["training_runs"]["protocol"] == "excitation"
    assert len(both.sequence_bounds()) == len(paper.sequence_bounds()) + 2


def test_runs_of_another_robot_are_refused(recorded, robot):
    import dataclasses

    paper, extra = recorded
    paper.get_split(seed=0)
    other = dataclasses.replace(extra, robot=dataclasses.replace(robot, name="other"))
    with pytest.raises(DatasetError, match="other"):
        with_training_runs(paper, other)
