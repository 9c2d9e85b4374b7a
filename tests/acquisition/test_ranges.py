"""The protocols' translations carried over to any robot (ctrkin.acquisition.ranges): the paper robot
keeps the paper's numbers exactly; a robot that cannot reach d = 20 mm gets levels it can reach, at
the same places of its curved overlap."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ctrkin.acquisition import protocols
from ctrkin.acquisition.ranges import ProtocolRanges
from ctrkin.acquisition.task_paths import CORNER, corner_of
from ctrkin.acquisition.trajectories import PAPER_LEVELS_MM
from ctrkin.errors import JointError
from ctrkin.robots import paper_robot
from ctrkin.robots.overlap import curved_overlap
from ctrkin.robots.robot import Robot
from ctrkin.robots.tube import Tube

ALL = ("paper", "sweeps", "random-points", "arbitrary", "snap-turns", "excitation")


def tube(like: Tube, **changes: float) -> Tube:
    """A one-arc tube like `like` (a paper robot tube) with `changes`."""
    keys = ("od", "id", "straight_length", "curved_length", "curvature", "youngs_modulus", "poisson_ratio")
    return Tube(**{**{k: getattr(like, k) for k in keys}, **changes})


def short_robot() -> Robot:
    """The paper robot with its inner tube's straight part 7 mm shorter: L1 − L2 = 13.5 mm, so d = 20
    mm (the paper's top level) is out of reach; its curves overlap fully from d = 13 mm."""
    paper = paper_robot()
    inner = tube(paper.tubes[0], straight_length=50.0)
    return dataclasses.replace(paper, tubes=(inner, paper.tubes[1]), name="short")


def test_the_paper_robot_keeps_the_papers_numbers_exactly() -> None:
    robot = paper_robot()
    r = ProtocolRanges.of(robot)
    assert (r.onset_mm, r.full_mm, r.reach_mm, r.retract_mm, r.scale) == (5.5, 20.0, 20.5, 5.0, 1.0)
    for size in protocols.PAPER_SIZES.values():
        assert r.levels(size.levels_mm) == size.levels_mm
    assert r.levels(PAPER_LEVELS_MM) == PAPER_LEVELS_MM
    assert corner_of(robot) == CORNER
    # every plan's parameters hold the constants the paper's protocols were written with, bit for bit
    paper = protocols.build("paper", robot, scale="tiny").params
    assert paper["levels_mm"] == [4.0, 20.0] and paper["outer_betas_mm"] == [0.0, -2.5, -5.0]
    rnd = protocols.build("random-points", robot, n_points=3).params
    assert rnd["d_range_mm"] == [4.0, 20.0] and rnd["outer_beta_range_mm"] == [-5.0, 0.0]
    arb = protocols.build("arbitrary", robot).params
    assert arb["start"] == protocols.ARBITRARY_START and arb["end"] == protocols.ARBITRARY_END
    snap = protocols.build("snap-turns", robot).params
    assert snap["d_mm"] == 20.0 and snap["outer_betas_mm"] == [-1.25, -3.75]


def test_a_robot_that_cannot_reach_20_mm_gets_levels_from_its_curved_overlap() -> None:
    robot = short_robot()
    r = ProtocolRanges.of(robot)
    assert (r.onset_mm, r.full_mm, r.reach_mm) == (0.0, 13.0, 13.5)   # the curves touch at d = 0
    with pytest.raises(JointError, match="outside"):                 # the paper's levels: refused
        protocols.build("paper", robot, scale="tiny", levels=(4.0, 20.0))
    plan = protocols.build("paper", robot, scale="quick")
    levels = [lv["relative_translation_mm"] for lv in plan.levels]
    assert levels == [2.6, 6.5, 9.75, 13.0]                           # k = min(13 / 14.5, 13 / 20)
    overlap = curved_overlap(robot, np.array([[0, 0, -d, 0] for d in (*levels, r.reach_mm)]))
    assert overlap[-2] == pytest.approx(overlap.max())              # the top level at full overlap
    assert np.all(np.diff(overlap[:-1]) > 0)                          # from little to full overlap
    for name in ALL:                                                  # every protocol fits the robot
        q = protocols.build(name, robot, scale="tiny").all_joints()
        d = q[:, 3] - q[:, 2]
        assert d.min() >= 0 and d.max() <= r.reach_mm + 1e-12
        assert q[:, 3].min() >= -r.retract_mm - 1e-12
    assert protocols.build("snap-turns", robot).params["d_mm"] == 13.0


def test_the_outer_retraction_follows_the_outer_curved_length() -> None:
    paper = paper_robot()
    outer = tube(paper.tubes[1], straight_length=37.0 + 14.5 - 7.25, curved_length=7.25)
    robot = dataclasses.replace(paper, tubes=(paper.tubes[0], outer), name="half-curve")
    r = ProtocolRanges.of(robot)
    assert r.retract_mm == 2.5                                   # a third of 7.25 mm, as 5 of 14.5
    assert protocols.build("paper", robot, scale="tiny").params["outer_betas_mm"] == [0.0, -1.25, -2.5]


def test_one_curved_tube_spans_the_reach_and_a_short_inner_tube_is_refused() -> None:
    paper = paper_robot()
    straight = tube(paper.tubes[1], straight_length=51.5, curved_length=0.0)
    r = ProtocolRanges.of(dataclasses.replace(paper, tubes=(paper.tubes[0], straight), name="one"))
    assert (r.onset_mm, r.full_mm) == (0.0, 20.5)
    assert r.levels((4.0, 20.0)) == (4.1, 20.5)                          # d · 20.5 / 20
    inner = tube(paper.tubes[0], straight_length=36.5)   # L1 = L2 = 51.5 mm
    with pytest.raises(JointError, match="inner one the longest"):
        ProtocolRanges.of(dataclasses.replace(paper, tubes=(inner, paper.tubes[1]), name="flush"))


def test_a_three_tube_robot_reads_its_ranges_with_the_middle_tube_at_the_outer() -> None:
    paper = paper_robot()
    middle = tube(paper.tubes[1], od=0.56, id=0.45, straight_length=42.0)
    outer = tube(paper.tubes[1], od=0.8, id=0.66, straight_length=30.0)
    robot = Robot(tubes=(paper.tubes[0], middle, outer), name="three")
    r = ProtocolRanges.of(robot)
    assert r.reach_mm == 72.0 - 56.5                       # L1 − L2: the middle tube's tip is next
    for name in ALL:
        robot.check_joints(protocols.build(name, robot, scale="tiny").all_joints())
