"""Fold tables against the two-tube snapping criterion (docs/mechanics.md: Model)."""

from __future__ import annotations

import numpy as np
import pytest

from ctrkin.mechanics.continuation import follow
from ctrkin.mechanics.folds import fold_angles
from tests.mechanics.test_analytic import _robot, critical_overlap

SI, SO = 60.0, 30.0         # straight (transmission) lengths of the compliant case of test_analytic


def test_no_fold_below_the_critical_overlap_and_symmetric_folds_above() -> None:
    lc = critical_overlap(SI, SO, rigid=False)
    below = _robot(0.97 * lc, SI, SO, rigid=False)
    fwd, bwd = fold_angles(below, np.array([[-SI, -SO]]))
    assert fwd[0] == 0.0 and bwd[0] == 0.0
    folds = []
    for factor in (1.05, 1.2):
        fwd, bwd = fold_angles(_robot(factor * lc, SI, SO, rigid=False), np.array([[-SI, -SO]]))
        assert fwd[0] > 0.0 and bwd[0] < 0.0
        assert fwd[0] == pytest.approx(-bwd[0], abs=0.5)         # the pair is symmetric about π
        folds.append(fwd[0])
    assert folds[1] > folds[0]                                    # the band widens with the overlap


def test_folds_are_where_a_continued_turn_snaps() -> None:
    """The tabulated fold is the first snapped row of a sweep: a finer independent sweep snaps
    between it and one table step before it."""
    robot = _robot(1.2 * critical_overlap(SI, SO, rigid=False), SI, SO, rigid=False)
    fwd, _ = fold_angles(robot, np.array([[-SI, -SO]]), step_deg=0.5)
    phi = np.arange(-60.0, 60.0, 0.1)
    q = np.c_[180.0 + phi, np.zeros_like(phi), np.full_like(phi, -SI), np.full_like(phi, -SO)]
    snapped = phi[follow(robot, q).snaps]
    assert len(snapped) == 1
    assert fwd[0] - 0.5 - 1e-9 <= snapped[0] <= fwd[0] + 1e-9


def test_unreachable_translations_are_moved_to_the_stops() -> None:
    robot = _robot(1.2 * critical_overlap(SI, SO, rigid=False), SI, SO, rigid=False)
    fwd, _ = fold_angles(robot, np.array([[-SI - 500.0, -SO]]))    # inner tube pulled in too far
    assert np.isfinite(fwd).all()
