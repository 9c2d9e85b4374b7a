"""The IK experiments' checks: the joints the FK model and the robot are driven through."""

from __future__ import annotations

import numpy as np

from ctrkin.evaluation.experiments_ik import joined


def test_joined_reaches_every_row_in_small_steps_within_its_sequence() -> None:
    Q = np.array([[0.0, 0.0, -30.0, -10.0],
                  [40.0, 0.0, -30.0, -10.0],       # a 40° jump: 40 steps of 1°
                  [40.0, 0.0, -30.5, -10.0],       # 0.5 mm: 5 steps of 0.1 mm
                  [10.0, 90.0, -28.0, -9.0],       # second sequence starts here, no move into it
                  [10.5, 90.0, -28.0, -9.0]])
    path, at, sid = joined(Q, 2, [(0, 3), (3, 5)])
    np.testing.assert_allclose(path[at], Q)
    np.testing.assert_array_equal(at, [0, 40, 45, 46, 47])
    np.testing.assert_array_equal(sid, [0] * 46 + [1] * 2)
    for s in (0, 1):
        steps = np.abs(np.diff(path[sid == s], axis=0))
        assert steps[:, :2].max() <= 1.0 + 1e-9 and steps[:, 2:].max() <= 0.1 + 1e-9
