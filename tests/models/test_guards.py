"""FK input guards (issue 9 item 2) and model files that cannot be read (item 6)."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from ctrkin.errors import JointError, ModelError
from ctrkin.inference import Kinematics


@pytest.fixture(scope="module")
def fk(model_dirs):
    return Kinematics.load(model_dirs["fk"])


def test_invalid_joints_are_refused_in_predict_and_step(fk):
    """`predict([[0, 0, -40, 5]])` (β2 > 0) returned a pose."""
    for bad in ([0.0, 0.0, -40.0, 5.0], [0.0, 0.0, -10.0, -20.0], [np.nan, 0.0, -20.0, -5.0],
                [0.0, np.inf, -20.0, -5.0]):
        with pytest.raises((JointError, ModelError)):
            fk.predict(np.array([bad]))
        fk.reset()
        with pytest.raises(JointError):
            fk.step(np.array(bad))


def test_step_recovers_after_a_bad_step(fk):
    """`step` with NaN raised ZeroDivisionError in the engine and the next valid step raised too."""
    q = np.array([[10.0, 0.0, -20.0, -5.0], [12.0, 0.0, -20.0, -5.0]])
    fk.reset()
    good = [fk.step(r) for r in q]
    fk.reset()
    first = fk.step(q[0])
    with pytest.raises(JointError):
        fk.step(np.array([np.nan, 0.0, -20.0, -5.0]))
    np.testing.assert_allclose(first, good[0])
    np.testing.assert_allclose(fk.step(q[1]), good[1], atol=1e-12)   # the state did not move


def test_far_alpha_is_wrapped_alike_in_predict_and_step_or_refused(fk):
    """α = 1e5 and α mod 360 gave poses 28 mm apart; α = 1e200 gave NaN in predict and a finite pose in
    step. Whole turns are now taken off a sequence that starts outside the trained range, alike in
    predict and step; absurd angles are refused in both."""
    base = np.array([[30.0, 0.0, -20.0, -5.0], [33.0, 0.0, -20.0, -5.0], [36.0, 0.0, -20.0, -5.0]])
    far, near = base.copy(), base.copy()
    far[:, 0] += 360.0 * 277              # ≈ 1e5 deg
    near[:, 0] += 360.0 * 5               # the same tube positions, five turns on
    ref = fk.predict(near)
    np.testing.assert_allclose(fk.predict(far), ref, atol=1e-9)
    fk.reset()
    np.testing.assert_allclose(np.array([fk.step(r) for r in far]), ref, atol=1e-5)
    for huge in (1e200, -1e12):
        bad = base.copy()
        bad[:, 0] = huge
        with pytest.raises(JointError, match="wrap the angles"):
            fk.predict(bad)
        fk.reset()
        with pytest.raises(JointError, match="wrap the angles"):
            fk.step(bad[0])
    drift = base.copy()
    drift[2, 0] += 3600.0                 # a sequence that wanders ten turns away from training
    with pytest.raises(ModelError, match="more than a turn outside"):
        fk.predict(drift)
    fk.reset()
    fk.step(drift[0])
    fk.step(drift[1])
    with pytest.raises(ModelError, match="more than a turn outside"):
        fk.step(drift[2])


def test_ik_step_refuses_nan_target(model_dirs):
    ik = Kinematics.load(model_dirs["ik"])
    with pytest.raises(ModelError, match="NaN"):
        ik.step(np.array([0.0, np.nan, 50.0, 1.0, 0.0, 0.0]))


def test_truncated_workspace_is_a_model_error(model_dirs, tmp_path):
    """A truncated workspace.npz raised zipfile.BadZipFile from Kinematics.load."""
    folder = tmp_path / "ik"
    shutil.copytree(model_dirs["ik"], folder)
    data = (folder / "workspace.npz").read_bytes()
    (folder / "workspace.npz").write_bytes(data[: len(data) // 2])
    with pytest.raises(ModelError, match=r"workspace\.npz"):
        Kinematics.load(folder)
    from ctrkin.inference.workspace import Workspace
    with pytest.raises(ModelError, match="cannot read the IK workspace"):
        Workspace.load(folder)
