"""The planner with a learned snap model (planning.learned) on the tests' small snap-aware FK, trained
on TCM sweeps of the paper robot (its fold near α0 = 208° at full overlap). Its two heads lie only
about 0.5 mm apart at the fold and 0.7 mm at α0 = 0 (three epochs of a 16-unit network), where its
labels change without a snap: the tests count a flip with a jump above 0.3 mm as a snap (the default,
2 mm, is for a trained model) and probe the margin 90° either way, which keeps α0 = 0 out of reach
from the states they probe (α0 ≥ 100°)."""

from __future__ import annotations

import numpy as np
import pytest

from ctrkin import Kinematics, follow, paper_robot, solve
from ctrkin.errors import ModelError
from ctrkin.planning import PlanConfig, plan_path
from ctrkin.planning.learned import LearnedSnapModel
from ctrkin.planning.naive import naive_path

ROBOT = paper_robot()
FULL = (-20.0, 0.0)
JUMP, CAP = 0.3, 90.0


@pytest.fixture(scope="module")
def fk_branch(model_dirs):
    return Kinematics.load(model_dirs["fk_branch"])


def _turn(a0: float, a1: float) -> np.ndarray:
    return np.array([[a, 0.0, *FULL] for a in np.arange(a0, a1 + 1e-9, 5.0)])


def test_a_turn_through_the_fold_is_a_predicted_snap_and_the_margin_shrinks_towards_it(fk_branch):
    model = LearnedSnapModel(fk_branch, jump_mm=JUMP, cap_deg=CAP)
    start = model.start(np.array([100.0, 0.0, *FULL]))
    assert start.state[0] in (0, 1) and start.margin_deg[0] == CAP       # the fold 108° ahead
    q = _turn(105.0, 300.0)
    route = model.stream(q)
    (snaps,) = np.nonzero(route.snap)
    assert len(snaps) == 1 and 190.0 <= q[snaps[0], 0] <= 230.0          # the nominal fold: 208°
    assert route.jump_mm[snaps[0]] > JUMP and route.state[snaps[0]] != route.state[snaps[0] - 1]
    before = route.margin_deg[(q[:, 0] >= 140.0) & (q[:, 0] < q[snaps[0], 0])]
    assert np.all(np.diff(before) < 0) and before[-1] < 10.0           # shrinks to the fold
    assert abs(before[0] - (q[snaps[0], 0] - 140.0)) < 10.0             # the rotation left to it
    again = model.stream(q)                                             # nothing kept between calls
    np.testing.assert_array_equal(again.state, route.state)
    np.testing.assert_allclose(again.margin_deg, route.margin_deg)


def test_the_planner_keeps_off_the_learned_snap(fk_branch):
    """The naive plan's joints snap on the mechanics and on the learned model; the planner with the
    model keeps every step at least learned_min_deg of inner rotation from the model's predicted snap
    (or the start's margin where lower), which rules out routes the mechanics alone took, and it
    reports the targets it cannot reach so, never approximates them."""
    start = np.array([150.0, 0.0, *FULL])
    targets = np.array([solve(ROBOT, [a, 0.0, *FULL]).tip_position for a in range(160, 271, 20)])
    legs = naive_path(ROBOT, start, targets)
    naive_q = np.concatenate([leg.q for leg in legs])
    model = LearnedSnapModel(fk_branch, jump_mm=JUMP, cap_deg=CAP)
    model.start(start)
    assert model.stream(naive_q).snap.any()
    cfg = PlanConfig(learned_min_deg=50.0)
    alone = plan_path(ROBOT, start, targets, config=cfg)
    plan = plan_path(ROBOT, start, targets, config=cfg,
                     learned=LearnedSnapModel(fk_branch, jump_mm=JUMP, cap_deg=CAP))
    assert plan.learned is not None and len(plan.learned.margin_deg) == len(plan.q)
    floor = min(50.0, plan.learned.margin_deg[0])
    assert not plan.learned.snap.any() and plan.learned.margin_deg.min() >= floor
    model.start(start)
    assert model.stream(alone.q[1:]).margin_deg.min() < floor           # the mechanics alone went closer
    assert plan.n_reached < alone.n_reached
    for rep in plan.targets:
        assert (rep.reached and rep.error_mm <= 1.0) or (not rep.reached and rep.step == -1)
    traj = follow(ROBOT, plan.q)                                         # and still safe on the mechanics
    assert not traj.snaps.any() and plan.margin.min() >= PlanConfig().min_margin


def test_a_model_without_a_branch_state_is_refused(model_dirs):
    with pytest.raises(ModelError, match="branch state"):
        LearnedSnapModel(Kinematics.load(model_dirs["fk"]))
    with pytest.raises(ModelError, match="FK"):
        LearnedSnapModel(Kinematics.load(model_dirs["ik"]))


def test_a_route_beyond_what_the_model_knows_is_refused(fk_branch):
    """A route more than a turn outside the model's trained α range: the model would extrapolate, so
    it cannot vouch for it (the planner rejects such a route)."""
    model = LearnedSnapModel(fk_branch, jump_mm=JUMP, cap_deg=CAP)
    model.start(np.array([100.0, 100.0, *FULL]))
    route = model.stream(np.array([[a, 100.0, *FULL] for a in np.arange(105.0, 900.0, 5.0)]))
    assert route.refused and "range" in route.refused
    assert 0 < len(route.state) < 159                                   # cut where it refused
    assert len(route.snap) == len(route.margin_deg) == len(route.state)
