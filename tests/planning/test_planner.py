"""The snap-safe planner on the paper robot (two tubes, bistable at full curved overlap)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from ctrkin import paper_robot, solve
from ctrkin.errors import CtrkinError
from ctrkin.planning import PlanConfig, plan_path, stability_margin
from ctrkin.planning.naive import naive_path

ROBOT = paper_robot()
FULL = (-20.0, 0.0)         # β1, β2: the curved sections on each other (the fold near α0 = 208°)


def _tips(alphas: list[float], beta: tuple[float, float] = FULL) -> np.ndarray:
    """Tips of point-wise (least-energy) solves at α1 = alphas, α2 = 0: a target path whose
    history-free IK crosses the bistable band."""
    return np.array([solve(ROBOT, [a, 0.0, *beta]).tip_position for a in alphas])


def test_margin_is_one_aligned_and_falls_towards_the_fold() -> None:
    aligned = stability_margin(ROBOT, solve(ROBOT, [0.0, 0.0, *FULL]))
    assert aligned == pytest.approx(1.0)
    prev = solve(ROBOT, [0.0, 0.0, *FULL])
    margins = []
    for a in range(10, 206, 15):
        prev = solve(ROBOT, [float(a), 0.0, *FULL], guess=prev)
        margins.append(stability_margin(ROBOT, prev))
    assert all(b < a for a, b in itertools.pairwise(margins))
    assert margins[-1] < 0.3


def test_the_naive_ik_snaps_where_the_planner_does_not() -> None:
    start = np.array([150.0, 0.0, *FULL])
    targets = _tips(list(range(160, 271, 20)))
    legs = naive_path(ROBOT, start, targets)
    assert sum(int(leg.snaps.sum()) for leg in legs) >= 1
    plan = plan_path(ROBOT, start, targets)
    assert not plan.snap.any()
    assert plan.n_reached == len(targets)
    assert plan.margin.min() >= PlanConfig().min_margin
    reached = plan.tips[plan.target >= 0]
    assert np.linalg.norm(reached - targets, axis=1).max() <= 1.0
    # the plan is what the mechanics does: following its joints from the start gives its tips, no snap
    from ctrkin import follow
    traj = follow(ROBOT, plan.q)
    assert not traj.snaps.any()
    np.testing.assert_allclose(traj.tip_positions, plan.tips, atol=1e-6)


def test_joints_stay_within_the_limits() -> None:
    cfg = PlanConfig(alpha_limits_deg=(-90.0, 90.0), beta_limits_mm=(-15.0, -1.0))
    targets = _tips([40.0, -60.0], beta=(-12.0, -3.0))
    plan = plan_path(ROBOT, np.array([0.0, 0.0, -10.0, -2.0]), targets, config=cfg)
    assert plan.n_reached == 2
    assert (plan.q[:, :2] >= -90.0).all() and (plan.q[:, :2] <= 90.0).all()
    assert (plan.q[:, 2:] >= -15.0).all() and (plan.q[:, 2:] <= -1.0).all()
    assert ROBOT.is_valid(plan.q).all()


def test_an_unreachable_target_is_reported_with_the_snap_on_offer() -> None:
    start = np.array([150.0, 0.0, *FULL])
    plan = plan_path(ROBOT, start, np.array([[0.0, 0.0, 200.0]]))    # beyond the robot's length
    (report,) = plan.targets
    assert not report.reached and report.error_mm > 1.0
    assert len(plan.q) == 1                                          # the robot stays where it is
    assert report.offer is not None and not report.offer.reachable
    assert report.offer.jump_mm > 1.0                                # the fold at full overlap
    assert 180.0 < report.offer.q[0] < 240.0 or -240.0 < report.offer.q[0] - 360.0 < -120.0
    assert "jumps" in report.offer.describe()


def test_orientation_targets_are_reached_with_their_tangent() -> None:
    eqs = [solve(ROBOT, q) for q in ([30.0, 10.0, -12.0, -2.0], [-40.0, 0.0, -8.0, -1.0])]
    pos = np.array([e.tip_position for e in eqs])
    tan = np.array([e.tip_tangent for e in eqs])
    plan = plan_path(ROBOT, np.array([0.0, 0.0, -10.0, 0.0]), pos, tan)
    assert plan.n_reached == 2
    for rep, t in zip(plan.targets, tan, strict=True):
        got = plan.q[rep.step]
        eq = solve(ROBOT, got)
        assert np.degrees(np.arccos(np.clip(eq.tip_tangent @ t, -1, 1))) < 2.0


def test_bad_inputs_are_refused() -> None:
    with pytest.raises(CtrkinError, match="targets"):
        plan_path(ROBOT, np.zeros(4), np.array([[np.nan, 0.0, 50.0]]))
    with pytest.raises(CtrkinError, match="min_margin"):
        PlanConfig(min_margin=1.5)
    with pytest.raises(CtrkinError, match="limits"):
        plan_path(ROBOT, np.array([800.0, 0.0, -10.0, 0.0]), np.array([[0.0, 0.0, 50.0]]))


def test_a_start_below_the_margin_may_lead_out_but_not_further_in() -> None:
    """A robot that starts nearer a fold than min_margin still gets a plan, whose margin never falls
    below where it started (found on the benchmark: the planner went nowhere from such a start)."""
    start = solve(ROBOT, [0.0, 0.0, *FULL])
    for a in range(10, 201, 10):
        start = solve(ROBOT, [float(a), 0.0, *FULL], guess=start)
    m0 = stability_margin(ROBOT, start)
    assert m0 < 0.25
    targets = _tips([120.0, 60.0])
    plan = plan_path(ROBOT, start, targets)
    assert plan.n_reached == 2 and not plan.snap.any()
    assert plan.margin.min() >= m0 - 1e-9
    assert plan.margin[-1] > 0.25
