"""A warm continuation step as one compiled call (issue 26): the common step of `follow` and of
`solve(q, guess=previous)`, where the joints turn (β kept, so the grid is the previous step's) on a
robot without contact effects and Newton from the predicted state lands on a stable equilibrium
that continues the branch.

`warm_step` does in one call what `continuation._advance` does in Python for that step's first
try: α in radians with whole turns removed (grid.reduced_radians, the same bits), the damped
Newton solve (kernels.newton, its passes flat: mechanics.passes) and the acceptance test of a
continuation step (stable; a twist change within `jump`; det J continuous: |det J − det J_prev| ≤
slack + rate · det J_prev). Where the test fails (a fold near, a large step) the caller takes the
general path from the start, which repeats this try and goes on to sub-steps and the snap search:
the decisions, and so the snaps, are the general path's.
"""

from __future__ import annotations

import math

from numba import njit

from ctrkin.mechanics.grid import reduced_radians
from ctrkin.mechanics.kernels import newton


@njit(cache=True)
def warm_step(q, q_from, guess, x_prev, det_prev, lengths, beta, tips, rigid, k, gj, bounds, kap,
              kapy, present, nsteps, nsample, tol, max_iter, max_step, max_turn, jump, slack, rate,
              alpha, x_out, body_out):
    """One warm step from joints q_from to q (2N,) (deg, mm) on the grid of the previous step (its
    β), without contact effects. guess (N,) rad/mm: Newton's start (the predicted state); x_prev
    (N,) rad/mm and det_prev: the previous equilibrium's state and det J; lengths (N,) mm; the rest
    of the problem as kernels.newton takes it. Writes alpha (N,) rad (grid.reduced_radians), x_out (N,),
    body_out (7,) (kernels.newton). Returns (accepted, iterations, |r|∞, det J, min det H, passes):
    accepted when no α turns by more than max_turn (deg: continuation.MAX_TURN_DEG, the step is
    then one try) and Newton converged to a stable equilibrium with max_i |Δxi| Li ≤ jump (rad)
    and |det J − det_prev| ≤ slack + rate det_prev.
    """
    n = alpha.shape[0]
    turn = 0.0
    for i in range(n):
        turn = max(turn, abs(q[i] - q_from[i]))
    if not turn <= max_turn:
        return False, 0, math.inf, math.nan, math.nan, 0
    reduced_radians(q, alpha)
    conv, it, rn, det_j, det_h, passes = newton(
        guess, alpha, beta, tips, rigid, k, gj, bounds, kap, kapy, present, nsteps, nsample, tol,
        max_iter, max_step, x_out, body_out, None, None, None, None, None)
    accepted = conv and det_j > 0.0 and det_h > 0.0
    if accepted:
        twist = 0.0
        for i in range(n):
            twist = max(twist, abs((x_out[i] - x_prev[i]) * lengths[i]))
        accepted = twist <= jump and abs(det_j - det_prev) <= slack + rate * det_prev
    return accepted, it, rn, det_j, det_h, passes
