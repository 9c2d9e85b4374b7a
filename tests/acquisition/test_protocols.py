"""Protocol plans: sizes, validity, structure (no mechanics)."""

from __future__ import annotations

import numpy as np
import pytest

from ctrkin.acquisition import protocols
from ctrkin.acquisition.plan import move
from ctrkin.errors import JointError


def test_full_paper_protocol_has_the_papers_size(robot):
    plan = protocols.build("paper", robot, scale="full")
    assert plan.n_samples == 8 * 36 * 721
    assert abs(plan.n_samples - 212_527) / 212_527 < 0.05
    assert len(plan.runs) == 8
    # every recorded sequence is one forward-and-back inner turn of 721 samples
    recorded = [s for r in plan.runs for s in r.segments if s.record]
    assert {s.q.shape[0] for s in recorded} == {721}


def test_paper_levels_cover_the_arbitrary_path(robot):
    paper = protocols.build("paper", robot, scale="full").all_joints()
    arb = protocols.build("arbitrary", robot).all_joints()
    d_p, d_a = paper[:, 3] - paper[:, 2], arb[:, 3] - arb[:, 2]
    assert d_p.min() <= d_a.min() and d_a.max() <= d_p.max()
    assert paper[:, 3].min() <= arb[:, 3].min() and arb[:, 3].max() <= paper[:, 3].max()


@pytest.mark.parametrize(("scale", "levels", "angles", "samples"), [
    ("tiny", [4.0, 20.0], 4, 5_768), ("quick", [4.0, 10.0, 15.0, 20.0], 18, 51_912)])
def test_smaller_paper_protocols_keep_low_and_high_overlap(robot, scale, levels, angles, samples):
    plan = protocols.build("paper", robot, scale=scale)
    assert [lv["relative_translation_mm"] for lv in plan.levels] == levels
    assert len(plan.params["outer_angles_deg"]) == angles
    assert plan.n_samples == samples == protocols.PAPER_SIZES[scale].n_samples()


def test_transitions_are_small_steps_and_sequences_join_up(robot):
    plan = protocols.build("paper", robot, scale="tiny", levels=(4.0, 12.0, 20.0))
    for run in plan.runs:
        q = np.concatenate([s.q for s in run.segments])
        step = np.abs(np.diff(q, axis=0))
        assert step[:, :2].max() <= 1.0 + 1e-9
        assert step[:, 2:].max() <= 0.1 + 1e-9


def test_arbitrary_path_in_our_convention(robot):
    q = protocols.build("arbitrary", robot).all_joints()
    assert q.shape == (361, 4)
    np.testing.assert_allclose(q[0], [360.0, 0.0, -20.0, 0.0])
    np.testing.assert_allclose(q[-1], [0.0, 360.0, -10.0, -5.0])
    # outer retracts 5 mm, inner extends 10 mm: relative translation 20 -> 5 mm
    np.testing.assert_allclose(q[[0, -1], 3] - q[[0, -1], 2], [20.0, 5.0])


def test_random_points_are_seeded_and_flag_targets(robot):
    a = protocols.build("random-points", robot, seed=5, n_points=7)
    b = protocols.build("random-points", robot, seed=5, n_points=7)
    c = protocols.build("random-points", robot, seed=6, n_points=7)
    np.testing.assert_array_equal(a.all_joints(), b.all_joints())
    assert not np.array_equal(a.params["targets"], c.params["targets"])
    recorded = [s for s in a.runs[0].segments if s.record]
    assert len(recorded) == 7
    for seg, target in zip(recorded, a.params["targets"], strict=True):
        assert seg.is_target is not None and seg.is_target.sum() == 1 and seg.is_target[-1]
        np.testing.assert_allclose(seg.q[-1], target)


def test_sweeps_are_the_five_paper_levels(robot):
    plan = protocols.build("sweeps", robot)
    assert [lv["relative_translation_mm"] for lv in plan.levels] == [4.0, 8.0, 12.0, 16.0, 20.0]
    assert plan.n_samples == 5 * 721


def test_move_steps_and_endpoints():
    a, b = np.array([0.0, 10.0, -5.0, -1.0]), np.array([7.5, 10.0, -5.35, -1.0])
    path = move(a, b, 2)
    assert len(path) == 8
    np.testing.assert_allclose(path[-1], b)
    assert np.abs(np.diff(np.r_[a[None], path], axis=0)).max() <= 1.0
    assert move(a, a, 2).shape == (0, 4)


def test_unreachable_levels_and_bad_names_are_explained(robot):
    with pytest.raises(JointError, match=r"outside 0\.\.20\.5 mm"):
        protocols.build("paper", robot, scale="quick", levels=(4.0, 25.0))
    with pytest.raises(ValueError, match="choose one of"):
        protocols.build("spiral", robot)
    with pytest.raises(ValueError, match="scale must be one of"):
        protocols.build("sweeps", robot, scale="huge")  # type: ignore[arg-type]
