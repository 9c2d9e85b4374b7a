"""Continuation with friction on translating paths and through reversals on three tubes (issue 20;
mechanics.continuation).

While the tubes translate, a slipping friction element's torsional tangent depends on the
sub-step's own axial slip (contact C4), so det J is not a measure of the branch that two sub-steps
of different length can be compared by. follow used to reject such sub-steps as branch changes and
halve its way down to 1/256 of a step on every step (the default virtual robot's arbitrary path:
10,264 Newton solves for 121 steps instead of 141).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ctrkin import follow, paper_robot, solve
from ctrkin.acquisition.protocols import arbitrary, paper
from ctrkin.mechanics import Equilibrium, continuation
from ctrkin.mechanics.friction import SLIP
from ctrkin.mechanics.pointwise import newton, prepare, with_state
from ctrkin.mechanics.settings import DEFAULT_SETTINGS
from ctrkin.virtual import VirtualConfig, VirtualRobot
from ctrkin.virtual.transmission import dead_band, play
from tests.evaluation.test_reproduce_other_robots import three_tube_robot


@pytest.fixture(scope="module")
def rough_path() -> tuple[object, np.ndarray]:
    """The default virtual robot's true tubes (friction μ 0.2 between them, clearance, the arc
    profile of precurvature) and the first 111 steps of the arbitrary path (every step turns both
    tubes and translates them: βN 0 → −5 mm, β1 −20 → −10 mm over 361 steps)."""
    robot = VirtualRobot(paper_robot(), seed=0).true_robot
    assert robot.friction > 0
    return robot, arbitrary(paper_robot()).runs[0].segments[0].q[:111]


def test_det_j_of_a_sliding_translation_depends_on_the_sub_step(rough_path) -> None:
    """The cause: from the same equilibrium (step 60), a sub-step of 1/8 of a step and one of 1/2
    along the same translating path stay on one branch with every element slipping, yet their det J
    differ 3.5-fold (15.2 and 4.3: about the inverse of the sub-step's axial slip), far beyond the
    continuation's rate bound (half)."""
    robot, Q = rough_path
    eq = follow(robot, Q[:61]).equilibria[-1]
    dets, tips = [], []
    for frac in (0.125, 0.5):
        q = Q[60] + frac * (Q[61] - Q[60])
        pb = with_state(prepare(robot, q, DEFAULT_SETTINGS, checked=True), eq.friction_state)
        sol = newton(pb, eq.x, DEFAULT_SETTINGS)
        assert sol.stable
        assert (np.frombuffer(sol.modes, dtype=np.float64) == SLIP).all()
        dets.append(sol.det_j)
        tips.append(sol.x)
    assert np.abs(tips[1] - tips[0]).max() * robot.tubes[0].length < 0.35   # same branch (JUMP_RAD)
    assert dets[0] > 2.0 * dets[1]
    assert abs(dets[1] - dets[0]) > continuation.DET_SLACK + continuation.DET_RATE * dets[0]


def test_follow_keeps_whole_steps_on_a_translating_path_with_sliding_contacts(rough_path, monkeypatch
                                                                              ) -> None:
    """The fix: on a translating (sub)step with a slipping element det J is not compared, so follow
    takes whole steps (at most 2 Newton solves a step here; 93 a step before, from step 100 on 519),
    and the path is the one followed in steps four times finer (to 0.3 mm: the friction law's
    combined slip depends on the increments) with the same snap. Measured with elements of
    ε = 0.2 µm (at the default 2 µm the two paths differ by up to 0.35 mm: more elastic slip per
    increment)."""
    robot, Q = rough_path
    calls = [0]
    real = continuation.newton

    def counted(*args, **kwargs):
        calls[0] += 1
        return real(*args, **kwargs)

    monkeypatch.setattr(continuation, "newton", counted)
    stiff = dataclasses.replace(DEFAULT_SETTINGS, stick_mm=2e-4)
    tr = follow(robot, Q, settings=stiff)
    assert calls[0] <= 2 * len(Q)
    assert tr.stable.all()
    fine_q = np.vstack([Q[:1], *(np.linspace(Q[i], Q[i + 1], 5)[1:] for i in range(len(Q) - 1))])
    fine = follow(robot, fine_q, settings=stiff)
    assert np.abs(tr.tip_positions - fine.tip_positions[::4]).max() < 0.3
    assert tr.n_snaps == fine.n_snaps


def test_det_j_is_still_compared_where_it_measures_the_branch() -> None:
    """Without friction (and on rotations, or while every element sticks) det J stays comparable."""
    stick = np.zeros(3).tobytes()
    slip = np.full(3, float(SLIP)).tobytes()
    assert continuation._det_comparable(b"", b"", translating=True)
    assert continuation._det_comparable(stick, stick, translating=True)
    assert continuation._det_comparable(slip, slip, translating=False)
    assert not continuation._det_comparable(slip, slip, translating=True)
    assert not continuation._det_comparable(stick, slip, translating=False)


@pytest.fixture(scope="module")
def three_tube_reversal() -> tuple[object, Equilibrium, np.ndarray]:
    """The three-tube robot of the tiny reproduction (tests/evaluation/test_reproduce_other_robots.py)
    as the virtual robot's true tubes at the central values (μ 0.2), seed 0: run 1 of the paper
    protocol's tiny scale up to its third segment, a full inner turn 0 → 360 → 0° with the middle and
    outer tubes at 90° (d = 15.5 mm). Returns the true robot, its equilibrium before that segment and
    the segment's tube-base joints up to 5 steps past the reversal (the motors' play holds α1 for a
    step, then it turns back by 0.5°)."""
    robot = three_tube_robot()
    virtual = VirtualRobot(robot, VirtualConfig().central(), seed=0)
    run = paper(robot, scale="tiny").runs[1]
    state = virtual.rest(run.start)
    for seg in run.segments[:2]:
        state = virtual.move(state, seg.q)[1]
    Q = run.segments[2].q[:367]
    out = np.empty_like(Q)
    play(Q, dead_band(robot, virtual.config, Q), state.play, out)
    return virtual.true_robot, state.equilibrium, virtual.base_joints(out)


def test_follow_steps_through_an_inner_reversal_on_three_tubes(three_tube_reversal) -> None:
    """At the reversal every friction element turns from slip to stick, and Newton from the last
    state stalls beside a stick/slip kink at every sub-step down to 1/256 of the step (2 of 25 starts
    near it converge at 1/16, none at 1/4 or the whole step), so follow spent its search budget and
    gave that step up (not converged, NaN pose). Now the rest of such a step is taken from the
    multi-start search of `recover` when it finds the branch within a step's twist: every step
    converges, without a snap at the reversal, to the equilibrium a point-wise solve from the step
    before with its friction state finds."""
    robot, start, base = three_tube_reversal
    tr = follow(robot, base, start=start)
    assert tr.converged.all() and tr.stable.all()
    turn = int(np.argmax(np.diff(base[:, 0]) < 0)) + 1     # the first step back
    assert 355 <= turn <= 365 and not tr.snaps[turn - 1:turn + 2].any()
    before = tr.equilibria[turn - 1]
    alone = solve(robot, base[turn], guess=before, state=before.friction_state)
    assert np.abs(alone.tip_position - tr.equilibria[turn].tip_position).max() < 1e-6
