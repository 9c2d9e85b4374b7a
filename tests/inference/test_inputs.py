"""What a model reads (issue 27, items 12, 13, 16, 21): labelled columns by name, ragged input and
interleaved sequences refused, IK targets without a unit quaternion refused, start joints checked as
every joint input; the same in batch and streaming, for every family that takes the input."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from ctrkin.data import Dataset
from ctrkin.errors import CtrkinError, DatasetError, JointError, ModelError
from ctrkin.inference import Kinematics
from ctrkin.training import TrainConfig, train

IK_NAMES = ("ik", "ik_refined", "follow")


@pytest.fixture(scope="module")
def models(model_dirs, sweeps, tmp_path_factory):
    """The session's FK and IK models and a follow IK of one epoch (what it answers does not matter
    here, only what it accepts)."""
    out = tmp_path_factory.mktemp("inputs") / "follow"
    cfg = TrainConfig(task="ik", model="follow_mlp", max_epochs=1, threads=1, options={"structure": "|D16"})
    train(sweeps, cfg, out, progress=False)
    return {**{k: Kinematics.load(v) for k, v in model_dirs.items()}, "follow": Kinematics.load(out)}


def _targets(sweeps, n=6):
    a, _ = sweeps.sequence_bounds()[1]
    return sweeps.poses(true=True)[a:a + n]


# --- item 12: labelled columns are read by name; a ragged list is a ctrkin error ------------------
@pytest.mark.parametrize("name", ["fk", "fk_branch", "fk_cnn"])
def test_fk_reads_a_dataframe_by_column_name(models, sweeps, name):
    fk = models[name]
    a, b = sweeps.sequence_bounds()[2]
    Q = sweeps.joints()[a:b]
    cols = list(sweeps.robot.joint_names())
    frame = pd.DataFrame(Q, columns=cols)
    ref = fk.predict(Q)
    swapped = frame[[cols[1], cols[0], *cols[2:]]]               # α2 before α1: a valid, other order
    np.testing.assert_array_equal(fk.predict(swapped), ref)
    np.testing.assert_array_equal(fk.predict(frame.assign(note="x")), ref)      # extra columns ignored
    np.testing.assert_array_equal(fk.predict(pd.DataFrame(Q)), ref)             # unlabelled: by position
    with pytest.raises(ModelError, match=r"lack the column\(s\) \['alpha_2'\]"):
        fk.predict(frame.drop(columns=["alpha_2"]))
    fk.reset()
    stream = np.array([fk.step(swapped.iloc[t]) for t in range(len(Q))])       # a labelled row, too
    assert np.abs(stream - ref).max() < 1e-5


def test_a_dataframe_with_sequence_ids_is_split_by_them(models, sweeps):
    fk = models["fk"]
    frame = sweeps.frame.iloc[::-1].iloc[::-1]                   # a plain DataFrame of the dataset
    np.testing.assert_array_equal(fk.predict(frame), fk.predict(sweeps))


@pytest.mark.parametrize("name", IK_NAMES)
def test_ik_reads_a_dataframe_by_column_name(models, sweeps, name):
    ik = models[name]
    T = _targets(sweeps)
    cols = ["x", "y", "z", "q0", "qx", "qy"]
    ref = ik.predict(T).joints
    frame = pd.DataFrame(T, columns=cols)[["qy", "z", "x", "q0", "y", "qx"]]
    np.testing.assert_array_equal(ik.predict(frame).joints, ref)
    with pytest.raises(ModelError, match=r"lack the column\(s\) \['q0'\]"):
        ik.predict(frame.drop(columns=["q0"]))
    ik.reset()
    first = ik.step(frame.iloc[0]).joints
    ik.reset()
    np.testing.assert_allclose(first, ik.step(T[0]).joints, atol=1e-9)


@pytest.mark.parametrize("name", ["fk", "ik"])
def test_a_ragged_list_is_a_ctrkin_error(models, name):
    kin = models[name]
    width = 4 if kin.task == "fk" else 6
    ragged = [[0.0] * width, [0.0] * (width - 2)]
    with pytest.raises(ModelError, match="equal-length rows"):
        kin.predict(ragged)
    kin.reset()
    with pytest.raises(CtrkinError):
        kin.step([[0.0, 1.0], [2.0]])


# --- item 13: interleaved sequence ids are refused, as a Dataset refuses them ----------------------
@pytest.mark.parametrize("name", ["fk", "fk_branch", "ik", "follow"])
def test_interleaved_sequence_ids_are_refused_like_a_dataset(models, sweeps, name):
    kin = models[name]
    raw = sweeps.joints()[:40] if kin.task == "fk" else _targets(sweeps, 40)
    sid = np.tile([0, 1], 20)
    with pytest.raises(ModelError, match="sequence_id 0 starts again at row 2"):
        kin.predict(raw, sequence_id=sid)
    frame = sweeps.frame.iloc[:40].assign(sequence_id=sid)
    with pytest.raises(DatasetError, match="sequence_id 0 starts again"):     # the same rule
        Dataset(frame, sweeps.robot, {})
    contiguous = np.repeat([0, 1], 20)
    out = kin.predict(raw, sequence_id=contiguous)
    assert len(out if kin.task == "fk" else out.joints) == 40


# --- item 16: an IK target's quaternion must be unit ------------------------------------------------
@pytest.mark.parametrize("name", IK_NAMES)
@pytest.mark.parametrize("quat", [(0.0, 0.0, 0.0), (0.5, 0.0, 0.0), (3.0, 0.0, 4.0)])
def test_ik_refuses_a_target_without_a_unit_quaternion(models, sweeps, name, quat):
    ik = models[name]
    T = _targets(sweeps)
    T[2, 3:] = quat
    with pytest.raises(ModelError, match=r"quaternion .* of norm"):
        ik.predict(T)
    ik.reset()
    ik.step(T[0])
    ik.step(T[1])
    with pytest.raises(ModelError, match=r"quaternion .* of norm"):
        ik.step(T[2])
    ik.step(T[3])                                    # the stream goes on after the refused target


# --- item 21: a follow IK's start joints are checked as every joint input --------------------------
@pytest.mark.parametrize("alpha", [1e300, -1e12])
def test_follow_ik_refuses_absurd_start_joints(models, sweeps, alpha):
    ik = models["follow"]
    start = sweeps.joints()[0].copy()
    start[0] = alpha
    T = _targets(sweeps)
    with pytest.raises(JointError, match="exceeds"):
        ik.predict(T, start_joints=start)
    with pytest.raises(JointError, match="exceeds"):
        ik.reset(start)
    with pytest.raises(JointError, match="exceeds"):             # and so does an FK input
        models["fk"].predict(start[None])
    with pytest.raises(ModelError, match="real numbers"):
        ik.reset(start.astype(complex) + 1j)
