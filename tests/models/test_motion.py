"""m_N, the direction of the outer tube's last rotation, from the recorded joints (ctrkin.models.motion)."""

from __future__ import annotations

import numpy as np

from ctrkin.models.motion import outer_motion


def test_outer_motion_follows_a_run_across_sequences_and_skips_glitches() -> None:
    alpha_n = np.array([0.0, 0.0, 20.0, 20.0, 20.0, 99.0, 20.0, 10.0, 10.0])
    q = np.c_[np.zeros_like(alpha_n), alpha_n]
    bounds = [(0, 2), (2, 4), (4, 7), (7, 9)]
    runs = np.array([0, 0, 0, 0, 0, 0, 0, 1, 1])
    skip = np.zeros(len(q), bool)
    skip[5] = True
    m = outer_motion(q, bounds, 2, runs, skip)
    # rest, then +20° between sequences 0 and 1 of run 0, a glitch ignored, a new run at rest
    np.testing.assert_array_equal(m, [0, 0, 1, 1, 1, 1, 1, 0, 0])
    np.testing.assert_array_equal(outer_motion(q, bounds, 2), [0, 0, 0, 0, 0, 1, -1, 0, 0])
