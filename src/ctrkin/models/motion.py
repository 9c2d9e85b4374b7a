"""Which way the outer tube's motor last turned, m_N ∈ {−1, 0, +1}, read from the recorded joints.

A tube base lags its motor by up to half the transmission's dead band, on the side it last moved from
(backlash and friction wind-up, a play operator; docs/virtual_robot.md). Where the outer tube points,
and so where a pair of tubes folds, depends on that side, which the encoders (reading the motors) do
not show but the joint path does. The learned side reads it here for the outer-tube frame's lag
(ctrkin.models.frame, ctrkin.models.outer_lag) and for a snap-aware model's fold gate; evaluation
reads it to compare tube angles rather than motor commands.

m_N is followed across the sequences of one run (the `run` column, in file order: the unrecorded
move between two sequences is a rotation from the end of one to the start of the next), reset at
rest, and skips the rows whose joints are not to be believed (encoder glitches, `outlier`).
"""

from __future__ import annotations

from typing import Any

import numpy as np


def run_continues(bounds: list[tuple[int, int]], runs: np.ndarray | None) -> list[bool]:
    """Per sequence: does it continue the run of the sequence before it (file order)?"""
    if runs is None:
        return [False] * len(bounds)
    return [k > 0 and b > a and bounds[k - 1][1] > bounds[k - 1][0] and runs[a] == runs[bounds[k - 1][1] - 1]
            for k, (a, b) in enumerate(bounds)]


def recorded_motion(frame: Any, joints: np.ndarray, bounds: list[tuple[int, int]], n_tubes: int
                    ) -> tuple[np.ndarray, np.ndarray | None]:
    """m_N (T,) of a dataset's rows and its runs (T,) (None without a `run` column): `outer_motion`
    followed across the runs of `frame` (a Dataset's frame), its `outlier` rows skipped."""
    runs = frame["run"].to_numpy() if "run" in frame.columns else None
    return outer_motion(joints, bounds, n_tubes, runs, frame["outlier"].to_numpy()), runs


def outer_motion(joints: np.ndarray, bounds: list[tuple[int, int]], n_tubes: int,
                 runs: np.ndarray | None = None, skip: np.ndarray | None = None) -> np.ndarray:
    """(T,) int8 m_N: the sign of the outer tube's last rotation up to each row (0: none since rest).
    Sequences of one run (runs (T,), in file order) are one path: the unrecorded move between them
    counts as a rotation from the end of one to the start of the next. Without runs every sequence
    starts at rest. skip (T,): rows whose joints are not to be believed (encoder glitches)."""
    alpha = np.asarray(joints, float)[:, n_tubes - 1].copy()
    if skip is not None:                       # a glitch row repeats the last believed angle
        for g in np.nonzero(skip)[0]:
            alpha[g] = alpha[g - 1] if g > 0 else alpha[g]
    out = np.zeros(len(alpha), dtype=np.int8)
    cur, last = 0, 0.0
    for (a, b), cont in zip(bounds, run_continues(bounds, runs), strict=True):
        if not cont:                           # at rest: `last` is the end of the previous sequence
            cur, last = 0, alpha[a] if b > a else last
        for t in range(a, b):
            d = alpha[t] - last
            if abs(d) > 1e-9:
                cur = 1 if d > 0 else -1
            out[t] = cur
            last = alpha[t]
    return out
