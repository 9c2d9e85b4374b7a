"""A plan driven with tracker feedback (ctrkin.control.plan_feedback): on a robot whose tracker is
registered a few millimetres off (what a plan made on the model cannot know), the corrections take
every target within 1 mm as the tracker sees it, every command on the model's branch above the
planner's margin, and the robot never snaps."""

from __future__ import annotations

import numpy as np
import pytest

from ctrkin import follow, paper_robot, solve
from ctrkin.control.plan_feedback import FeedbackConfig, _correct, _replan, execute_plan
from ctrkin.errors import CtrkinError
from ctrkin.geometry import RigidTransform
from ctrkin.planning import PlanConfig, plan_path, stability_margin

ROBOT = paper_robot()
BETA = (-12.0, -3.0)   # part of the curved sections on each other, the outer tube off its stop


class OffsetRig:
    """The paper robot's mechanics followed step by step (snaps flagged), seen through a tracker
    registered 2° and ~1.5 mm off, with 0.1 mm of seeded noise per reading."""

    def __init__(self, start: np.ndarray) -> None:
        self.eq = solve(ROBOT, start)
        self.reg = RigidTransform.from_rotvec(np.radians(2.0) * np.array([1.0, 0.0, 0.0]),
                                              np.array([1.0, -0.5, 0.5]))
        self.rng = np.random.default_rng(7)
        self.tips: list[np.ndarray] = []
        self.snaps = 0

    def move(self, q: np.ndarray) -> None:
        tr = follow(ROBOT, q, start=self.eq)
        self.eq = tr.equilibria[-1]
        self.snaps += int(tr.snaps.sum())
        self.tips.extend(tr.tip_positions)

    def seen(self, tip: np.ndarray) -> np.ndarray:
        return self.reg.apply_points(tip[None, :])[0]

    def measure(self) -> np.ndarray:
        return self.seen(self.eq.tip_position) + 0.1 * self.rng.standard_normal(3)


def test_feedback_takes_each_target_within_1mm_without_a_snap() -> None:
    start = np.array([0.0, 0.0, *BETA])
    targets = np.array([solve(ROBOT, [a, 0.0, *BETA]).tip_position for a in (40.0, -30.0)])
    plan = plan_path(ROBOT, start, targets)
    assert plan.n_reached == 2
    rig = OffsetRig(start)
    done = execute_plan(ROBOT, plan, targets, rig)
    tips = np.array(rig.tips)
    open_loop = np.linalg.norm([rig.seen(t) for t in plan.tips[[r.step for r in plan.targets]]] - targets,
                               axis=1)
    assert open_loop.min() > 1.0                    # the plan alone misses as the tracker sees it
    seen = np.array([rig.seen(tips[i]) for i in done.at])
    assert np.linalg.norm(seen - targets, axis=1).max() <= 1.0
    assert done.settled.all() and done.steps.min() >= 1 and not done.refused.any()
    assert rig.snaps == 0
    floor = min(PlanConfig().min_margin, stability_margin(ROBOT, solve(ROBOT, start)))
    assert done.margin.min() >= floor
    assert len(done.q) == len(tips)                 # every command was driven, in order


def test_where_no_local_step_is_safe_another_rotation_is_searched_and_checked() -> None:
    # the inner tube at full extension (beta_1 = beta_2): a correction the local step cannot make (a
    # case of the planning benchmark, where the tracker's view needed another relative rotation)
    cur = solve(ROBOT, np.array([-148.3, 4.7, -24.5, -24.5]))
    err = np.array([2.15, -5.48, 1.05])
    cfg = PlanConfig()
    floor = min(cfg.min_margin, stability_margin(ROBOT, cur))
    assert _correct(ROBOT, cur, err, cfg, FeedbackConfig(), floor) is None
    route = _replan(ROBOT, cur, cur.tip_position + err, cfg, floor)
    assert route is not None
    assert not route.snaps.any() and route.margin.min() >= floor
    assert np.linalg.norm(route.tips[-1] - (cur.tip_position + err)) <= cfg.tol_mm
    steps = np.abs(np.diff(np.vstack([cur.q, route.q]), axis=0))
    assert steps[:, :2].max() <= 5.0 + 1e-9 and steps[:, 2:].max() <= 1.0 + 1e-9   # followed in route steps


def test_bad_feedback_settings_are_refused() -> None:
    for bad in (dict(tol_mm=0.0), dict(gain=1.5), dict(max_steps=-1), dict(ik_iterations=0)):
        with pytest.raises(CtrkinError):
            FeedbackConfig(**bad)
