"""Curved overlap of the paper robot's tubes (ctrkin.robots.overlap)."""

from __future__ import annotations

import numpy as np
import pytest

from ctrkin.acquisition.protocols import config
from ctrkin.robots import paper_robot
from ctrkin.robots.overlap import curved_overlap


@pytest.mark.parametrize(("d", "overlap"), [(0.0, 0.0), (4.0, 0.0), (5.5, 0.0), (12.0, 6.5),
                                            (20.0, 14.5), (20.5, 14.5)])
def test_curved_overlap_of_the_paper_robot(robot, d, overlap):
    # inner curved part s in [beta1 + 57, beta1 + 72], outer in [beta2 + 37, beta2 + 51.5]
    q = config(2, 0.0, 0.0, -3.0, d)
    assert curved_overlap(robot, q[None, :])[0] == pytest.approx(overlap, abs=1e-12)


def test_one_row_equals_the_vectorised_overlap():
    """curved_overlap_one (the streaming steps') equals curved_overlap row by row, on random joints
    of both built-in robots, including tubes pulled behind the plate (spans clipped at s = 0)."""
    from ctrkin.robots import timclab_robot
    from ctrkin.robots.overlap import curved_overlap_one

    rng = np.random.default_rng(5)
    for robot in (paper_robot(), timclab_robot()):
        n = robot.n_tubes
        lengths = np.asarray(robot.lengths, float)
        beta = -rng.uniform(0.0, 1.0, (300, n)) * lengths
        beta.sort(axis=1)                   # β1 ≤ … ≤ βN (inner tubes further back)
        Q = np.c_[np.zeros((300, n)), beta]
        want = curved_overlap(robot, Q)
        got = np.array([curved_overlap_one(robot, q[n:]) for q in Q])
        np.testing.assert_allclose(got, want, atol=1e-12)
        assert (want > 0).any() and (want == 0).any()
