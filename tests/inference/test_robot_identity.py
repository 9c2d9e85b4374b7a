"""A model refuses data from a robot whose tubes differ, not from one that was only renamed; and
`Kinematics` has a readable repr and typed forward/inverse entry points."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ctrkin.errors import ModelError
from ctrkin.inference import IKResult, Kinematics
from ctrkin.robots import Robot


def test_renamed_robot_is_accepted_changed_tubes_are_refused(sweeps, model_dirs) -> None:
    fk = Kinematics.load(model_dirs["fk"])
    renamed = dataclasses.replace(sweeps, robot=dataclasses.replace(sweeps.robot, name="bench-2"))
    np.testing.assert_array_equal(fk.predict(renamed), fk.predict(sweeps))
    tube = dataclasses.replace(sweeps.robot.tubes[1], curvature=1 / 20.0)
    other = Robot(tubes=(sweeps.robot.tubes[0], tube), name=sweeps.robot.name)
    with pytest.raises(ModelError, match=r"tubes\[1\]\.curvature"):
        fk.predict(dataclasses.replace(sweeps, robot=other))


def test_repr_and_typed_entry_points(sweeps, model_dirs) -> None:
    fk, ik = Kinematics.load(model_dirs["fk"]), Kinematics.load(model_dirs["ik"])
    assert repr(fk).startswith("Kinematics(task='fk', model='lstm_mlp', robot='paper', n_tubes=2, ib=2")
    assert "refined" in repr(Kinematics.load(model_dirs["ik_refined"]))
    Q = sweeps.joints()[:30]
    np.testing.assert_array_equal(fk.forward(Q), fk.predict(Q))
    res = ik.inverse(sweeps.poses()[:30])
    assert isinstance(res, IKResult) and res.joints.shape == (30, 4)
    fk.reset()
    np.testing.assert_allclose(fk.step_pose(Q[0]), fk.predict(Q[:1])[0], atol=1e-5)
    ik.reset()
    assert ik.step_joints(sweeps.poses()[0]).joints.shape == (4,)
    with pytest.raises(ModelError, match="needs an IK model"):
        fk.inverse(sweeps.poses()[:3])
    with pytest.raises(ModelError, match="needs an FK model"):
        ik.step_pose(Q[0])
