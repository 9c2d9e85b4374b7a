"""A cold solve's common case as one compiled call (issue 26): `solve(robot, q)` without a guess
or friction state, on a robot without contact effects, whose first Newton solve (from untwisted
tubes, pointwise.cold_solution) lands on a stable equilibrium.

`cold_start` does in one call what `pointwise.prepare` and the first Newton solve of
`pointwise.cold_solution` do: the joint check (robots.joint_check.joint_violations, the check of
Robot.check_joints), α less whole turns and the grid (grid.prepare), the bound on the RK4 steps
(SolverSettings.max_rk4_steps) and the Newton solve from uz(0) = 0 (kernels.newton), the same
functions on the same numbers. Where the joints are invalid or the grid too fine it returns a
status and nothing else: the caller takes the Python path, which raises the error that names the
problem. An unstable first solve goes on in Python as before (the multi-start search).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ctrkin.mechanics.grid import prepare
from ctrkin.mechanics.kernels import newton
from ctrkin.robots.joint_check import joint_violations

VALID, INVALID_JOINTS, TOO_MANY_STEPS = 0, 1, 2


@njit(cache=True)
def cold_start(q, joint_lengths, tube_len, extra, sec_len, sec_kap, sec_kapy, n_sec, h, max_rk4,
               rigid, k, gj, tol, max_iter, max_step, x_out, body_out):
    """q (2N,) joints (deg, mm); joint_lengths (N,): Robot._lengths (the joint check's); the robot's
    arrays (mechanics.arrays.RobotArrays) and the RK4 step h (pointwise.rk4_step); max_rk4,
    tol, max_iter, max_step: SolverSettings'. Returns (status, alpha, beta − extra, tips, grid
    (6 arrays), RK4 steps of a pass (grid nsteps summed), converged, iterations, |r|∞, det J,
    min det H, passes), writing x_out (N,) and body_out (7,) as kernels.newton; status VALID, or
    INVALID_JOINTS / TOO_MANY_STEPS with the arrays empty and the solve not made."""
    n = tube_len.shape[0]
    rows = np.empty((1, 2 * n))
    rows[0, :] = q
    if joint_violations(rows, joint_lengths)[1] >= 0:
        return _not_made(INVALID_JOINTS, n)
    alpha, beta, tips, grid, _ = prepare(q, tube_len, extra, sec_len, sec_kap, sec_kapy, n_sec, h)
    if grid[5].sum() > max_rk4:
        return _not_made(TOO_MANY_STEPS, n)
    conv, it, rn, det_j, det_h, passes = newton(
        np.zeros(n), alpha, beta, tips, rigid, k, gj, grid[0], grid[1], grid[2], grid[3], grid[4],
        grid[5], tol, max_iter, max_step, x_out, body_out, None, None, None, None, None)
    return VALID, alpha, beta, tips, grid, grid[4].sum(), conv, it, rn, det_j, det_h, passes


@njit(cache=True)
def _not_made(status, n):
    """cold_start's result where it stops at `status`: empty arrays, no solve."""
    e1, e2 = np.empty(0), np.empty((0, n))
    ei = np.empty(0, dtype=np.int64)
    return status, e1, e1, e1, (e1, e2, e2, e2, ei, ei), 0, False, 0, np.inf, np.nan, np.nan, 0
