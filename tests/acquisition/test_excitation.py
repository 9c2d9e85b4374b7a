"""The excitation protocol (ctrkin.acquisition.excitation): size, structure, ranges, seeds, and that
it shares no path with the held-out experiments."""

from __future__ import annotations

import numpy as np
import pytest

from ctrkin.acquisition import excitation as ex
from ctrkin.acquisition import protocols
from ctrkin.acquisition.ranges import ProtocolRanges
from ctrkin.robots.robot import Robot


def _reversals(a: np.ndarray) -> int:
    s = np.sign(np.diff(a))
    s = s[s != 0]
    return int((np.diff(s) != 0).sum())


@pytest.mark.parametrize(("scale", "runs"), [("tiny", 1), ("quick", 10), ("full", 40)])
def test_its_size_is_a_fifth_of_the_paper_protocols(robot, scale, runs):
    plan = protocols.build("excitation", robot, scale=scale, seed=8)
    paper = protocols.PAPER_SIZES[scale].n_samples()
    assert len(plan.runs) == runs
    assert plan.n_samples == runs * ex.RUN_SAMPLES
    assert plan.n_samples <= 0.25 * paper
    assert all(len(r.segments) == 1 and r.segments[0].record for r in plan.runs)   # one sequence a run


def test_runs_start_at_rest_and_move_in_small_steps_within_the_paper_ranges(robot):
    plan = protocols.build("excitation", robot, scale="quick", seed=3)
    ranges = ProtocolRanges.of(robot)
    for run in plan.runs:
        q = run.segments[0].q
        assert np.all(q[:ex.REST_SAMPLES] == q[0])                    # recorded at rest first
        step = np.abs(np.diff(q, axis=0))
        assert step[:, :2].max() <= 1.0 + 1e-9 and step[:, 2:].max() <= 0.1 + 1e-9
    q = plan.all_joints()
    d = q[:, 3] - q[:, 2]
    assert q[:, :2].min() >= 0.0 and q[:, :2].max() <= 360.0       # the paper protocol's α range
    assert d.min() >= ranges.d(4.0) - 1e-9 and d.max() <= ranges.d(20.0) + 1e-9
    assert q[:, 3].min() >= -5.0 - 1e-9 and q[:, 3].max() <= 0.0


def test_it_reverses_both_tubes_mid_turn_and_slides_before_turns(robot):
    plan = protocols.build("excitation", robot, scale="quick", seed=0)
    inner = [_reversals(r.segments[0].q[:, 0]) for r in plan.runs]
    outer = [_reversals(r.segments[0].q[:, 1]) for r in plan.runs]
    assert sum(inner) >= 10 and sum(outer) >= 3
    # reversal angles are drawn, not a fixed grid: the inner tube's turning points are (almost) all distinct
    points = []
    for r in plan.runs:
        a = r.segments[0].q[:, 0]
        da = np.sign(np.diff(a))
        idx = np.flatnonzero((da[:-1] * da[1:]) < 0) + 1
        points += [round(float(a[i]), 1) for i in idx if 0.0 < a[i] < 360.0]
    assert len(points) >= 10 and len(set(points)) >= 0.9 * len(points)
    # slides of every kind: d alone (inner tube), βN and d together (outer tube), βN alone (both)
    kinds = set()
    for r in plan.runs:
        q = r.segments[0].q
        dd, db = np.diff(q[:, 3] - q[:, 2]), np.diff(q[:, 3])
        moving = (np.abs(dd) > 1e-9) | (np.abs(db) > 1e-9)
        for k in np.flatnonzero(moving):
            kinds.add((abs(dd[k]) > 1e-9, abs(db[k]) > 1e-9, abs(q[k + 1, 2] - q[k, 2]) > 1e-9))
    assert {(True, False, True), (True, True, False), (False, True, True)} <= kinds


def test_it_is_seeded(robot):
    a = protocols.build("excitation", robot, scale="tiny", seed=5).all_joints()
    b = protocols.build("excitation", robot, scale="tiny", seed=5).all_joints()
    c = protocols.build("excitation", robot, scale="tiny", seed=6).all_joints()
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    assert len(protocols.build("excitation", robot, scale="tiny", seed=5, runs=3).runs) == 3
    with pytest.raises(ValueError, match="runs"):
        protocols.build("excitation", robot, scale="tiny", runs=0)


def test_it_shares_no_path_with_the_held_out_experiments(robot):
    """No recorded excitation sample repeats a held-out experiment's joints in the same order: no
    stretch of 20 consecutive joint vectors of the sweeps or the snap turns appears in it."""
    plan = protocols.build("excitation", robot, scale="quick", seed=8)
    exc = {tuple(np.round(r.segments[0].q[k:k + 20], 3).ravel()) for r in plan.runs
           for k in range(0, ex.RUN_SAMPLES - 20)}
    for name in ("sweeps", "snap-turns"):
        for run in protocols.build(name, robot, scale="quick").runs:
            for seg in run.segments:
                if seg.record:
                    q = seg.q
                    assert not any(tuple(np.round(q[k:k + 20], 3).ravel()) in exc
                                   for k in range(0, len(q) - 20, 5))


def test_it_works_on_three_tubes_with_the_middle_tube_at_the_outer(robot):
    from tests.acquisition.test_ranges import tube

    middle = tube(robot.tubes[1], od=0.56, id=0.45, straight_length=42.0)
    outer = tube(robot.tubes[1], od=0.8, id=0.66, straight_length=30.0)
    three = Robot(tubes=(robot.tubes[0], middle, outer), name="three")
    q = protocols.build("excitation", three, scale="tiny", seed=1).all_joints()
    assert q.shape[1] == 6
    assert np.array_equal(q[:, 1], q[:, 2]) and np.array_equal(q[:, 4], q[:, 5])
    assert _reversals(q[:, 0]) >= 1
