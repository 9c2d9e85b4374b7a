"""A learned model flags joints outside its training range instead of answering silently."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from ctrkin.evaluation.real import out_of_range


def test_out_of_range_flags_per_joint_with_margin():
    names = ["alpha_1", "alpha_2", "beta_1", "beta_2"]
    kin = SimpleNamespace(bundle=SimpleNamespace(x_norm=SimpleNamespace(
        lo=np.array([-90.0, 0.0, -160.0, -91.0, 0.0]), span=np.array([180.0, 1.0, 40.0, 1.0, 1.0]))),
        layout=SimpleNamespace(input_names=(*names, "alpha_0")))
    joints = np.array([[0.0, 0.5, -150.0, -90.5],     # inside
                       [95.0, 0.5, -150.0, -90.5],    # 5° beyond 90, margin 9°: inside
                       [100.0, 0.5, -150.0, -90.5],   # beyond the margin
                       [0.0, 0.5, -110.0, -90.5]])    # β1 beyond -120 + 2 mm
    flags = out_of_range(kin, joints, names)
    assert flags["rows"].tolist() == [False, False, True, True]
    assert flags["joints"]["alpha_1"]["count"] == 1 and flags["joints"]["beta_1"]["count"] == 1
    assert abs(flags["joints"]["alpha_1"]["margin"] - 9.0) < 1e-12
