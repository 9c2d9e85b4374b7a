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

`follow` itself goes further: `warm_run` does consecutive such steps in one call, with its
predictor (`extrapolate`), up to the first that is not accepted or not a rotation; `friction_run`
does the same on a robot with friction or clearance (the stations' state carried from step to
step), `moving_run` for translating steps without contact effects (a grid each step) and
`friction_moving_run` for translating steps with them (a grid and its stations each step; det J
compared only where the stick/slip pattern held with no element slipping, as _advance does on a
translating step). compiled_runs.Steps makes their Equilibrium objects when they are read.
"""

from __future__ import annotations

import math

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

from ctrkin.mechanics.contact import SLIP, gather_state, state_after, station_table
from ctrkin.mechanics.grid import prepare, reduced_radians
from ctrkin.mechanics.kernels import _newton, newton
from ctrkin.mechanics.passes import flat_work


@njit(cache=True)
def _turn(q, q_from, n):
    """max_i |q_i − q_from_i| over the N rotations (deg): the step's largest turn."""
    turn = 0.0
    for i in range(n):
        turn = max(turn, abs(q[i] - q_from[i]))
    return turn


@njit(cache=True)
def _twist(x, x_prev, lengths, n):
    """max_i |x_i − x_prev_i| L_i: the largest change of a tube's twist over its length (rad)."""
    twist = 0.0
    for i in range(n):
        twist = max(twist, abs((x[i] - x_prev[i]) * lengths[i]))
    return twist


@njit(cache=True)
def _accepted(conv, det_j, det_h, x, x_prev, lengths, n, det_prev, jump, slack, rate, held):
    """The acceptance test of a continuation step (continuation._advance's): Newton converged
    (conv) to a stable equilibrium (det J > 0, min det H > 0), no tube's twist changed by more than
    jump (rad: max_i |x_i − x_prev_i| L_i, lengths (N,) mm) and det J continuous, |det J −
    det_prev| ≤ slack + rate det_prev. That last is asked only where `held` (friction_run: the
    stick/slip pattern is the previous step's; True without contact effects): a pattern that
    changes may make det J jump."""
    if not (conv and det_j > 0.0 and det_h > 0.0):
        return False
    return _twist(x, x_prev, lengths, n) <= jump and (
        abs(det_j - det_prev) <= slack + rate * det_prev or not held)


@njit(cache=True)
def _predict(t, same, snapped, xs, weights, path_states, guess):
    """guess (N,) = follow's predictor at step t: the polynomial through the m states behind t on
    one branch (m ≤ path_states; continuation.Predictor), or the last state where m = 1."""
    m = 1
    while m < path_states and same[t - m + 1] and not snapped[t - m]:
        m += 1
    if m > 1:
        extrapolate(weights[m], xs[t - m:t], guess)
    else:
        guess[:] = xs[t - 1]


@njit(cache=True)
def _record(t, rn, det_j, det_h, it, stats, counts):
    """An accepted step's figures: stats[t] = (|r|∞, det J, min det H), counts[t, 0] = iterations."""
    stats[t, 0] = rn
    stats[t, 1] = det_j
    stats[t, 2] = det_h
    counts[t, 0] = it


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
    if not _turn(q, q_from, n) <= max_turn:
        return False, 0, math.inf, math.nan, math.nan, 0
    reduced_radians(q, alpha)
    conv, it, rn, det_j, det_h, passes = newton(
        guess, alpha, beta, tips, rigid, k, gj, bounds, kap, kapy, present, nsteps, nsample, tol,
        max_iter, max_step, x_out, body_out, None, None, None, None, None)
    accepted = _accepted(conv, det_j, det_h, x_out, x_prev, lengths, n, det_prev, jump, slack,
                         rate, True)
    return accepted, it, rn, det_j, det_h, passes


@intrinsic
def _fma(typingctx, a, b, c):
    """a b + c rounded once (LLVM's llvm.fma.f64: the FMA instruction, or an exact software
    fallback where the CPU has none)."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        d = ir.DoubleType()
        fn = builder.module.declare_intrinsic("llvm.fma", [d], ir.FunctionType(d, [d, d, d]))
        return builder.call(fn, args)

    return sig, codegen


@njit(cache=True)
def extrapolate(w, xs, out):
    """out (N,) = Σj w[j] xs[j] (xs (k, N)): the predictor's polynomial at τ from its Lagrange
    weights (continuation.Predictor), each term added by one fused multiply-add, j in order, from
    0. That is the order and the rounding of numpy's w.dot(xs) on this machine's OpenBLAS (its
    Haswell dgemv) for N ≤ 3 (tested against it), and one definition for the compiled run of steps
    and the general path alike on any machine and N."""
    for i in range(xs.shape[1]):
        acc = 0.0
        for j in range(xs.shape[0]):
            acc = _fma(w[j], xs[j, i], acc)  # type: ignore[call-arg]  # (the typing context is numba's)
        out[i] = acc


@njit(cache=True)
def warm_run(Q, start, rotation, same, snapped, xs, det_prev, weights, path_states, lengths, beta,
             tips, rigid, k, gj, bounds, kap, kapy, present, nsteps, nsample, tol, max_iter,
             max_step, max_turn, jump, slack, rate, alpha, body, stats, counts, done):
    """Consecutive warm steps of `follow` from step `start` in one compiled call: each what
    warm_step does for one (continuation._advance's first try: same grid, no contact effects),
    with `follow`'s predictor, until a step is not a rotation (rotation[t] False), is not
    accepted or the path ends. Returns the number m of steps accepted: start … start + m − 1.

    Q (T, 2N) joints; rotation, same, snapped (T,) bool: step t keeps β, repeats step t − 1's
    increment, snapped on its way in (continuation.follow's flags); xs (T, N): the states, rows
    before `start` given, the accepted ones written; det_prev: det J of step start − 1; weights
    (path_states + 1, path_states): row k, the predictor's Lagrange weights at τ = 1 through k
    states (continuation._lagrange(1, k)); the problem on the grid of step start − 1 as
    kernels.newton takes it; max_turn, jump, slack, rate: warm_step's. Writes, per accepted step
    t: alpha[t] (N,) rad, xs[t], body[t] (7,) (kernels._tip), stats[t] = (|r|∞, det J, min det H),
    counts[t] = (iterations, passes), and done[0] = the steps accepted so far (read where the
    run raised: ZeroDivisionError and the like, as warm_step). counts[t, 1] is written for the
    step that is not accepted as well (its passes, spent)."""
    n = xs.shape[1]
    work = flat_work(n)
    guess = np.empty(n)
    det = det_prev
    t = start
    done[0] = 0
    while t < Q.shape[0] and rotation[t]:
        _predict(t, same, snapped, xs, weights, path_states, guess)
        q, q_from = Q[t], Q[t - 1]
        if not _turn(q, q_from, n) <= max_turn:
            break
        reduced_radians(q, alpha[t])
        conv, it, rn, det_j, det_h, passes = _newton(
            guess, alpha[t], beta, tips, rigid, k, gj, bounds, kap, kapy, present, nsteps, nsample,
            tol, max_iter, max_step, xs[t], body[t], work, None, None, None, None, None)
        counts[t, 1] = passes
        if not _accepted(conv, det_j, det_h, xs[t], xs[t - 1], lengths, n, det, jump, slack, rate,
                         True):
            break
        _record(t, rn, det_j, det_h, it, stats, counts)
        det = det_j
        t += 1
        done[0] = t - start
    return t - start


@njit(cache=True)
def _same_modes(a, b):
    """The stick/slip patterns a, b (K,) are the same bytes (continuation._det_comparable compares
    the bytes of float64: equal values of equal sign)."""
    for j in range(a.shape[0]):
        if not (a[j] == b[j] and math.copysign(1.0, a[j]) == math.copysign(1.0, b[j])):
            return False
    return True


@njit(cache=True)
def friction_run(Q, start, rotation, same, snapped, xs, det_prev, weights, path_states, lengths,
                 beta, tips, rigid, k, gj, bounds, kap, kapy, present, nsteps, nsample, tol,
                 max_iter, max_step, max_turn, jump, slack, rate, table, pairs, prm, slot, q_state,
                 modes_prev, theta, cvar, cout, alpha, body, stats, counts, done):
    """warm_run on a robot with friction (contact stations on the grid of step start − 1): each
    step what continuation._advance's first try does there, from the friction state of the step
    before (theta[t − 1] (P · slots,), held at joints q_state for step start, Q[t − 1] after):
    the stations' state at Q[t] (contact.gather_state) into cvar[t] (K + P,), the Newton solve with
    the stations (their outputs into cout[t] (K, 8)), the acceptance test (stable, twist within
    jump, det J continuous unless the stick/slip pattern changed: modes_prev (K,) for step start,
    cout[t − 1, :, 3] after) and the state after it (contact.state_after) into theta[t]. table,
    pairs, prm, slot: the grid's friction.Stations. The rest as warm_run."""
    n = xs.shape[1]
    size = theta.shape[1]
    guess = np.empty(n)
    det = det_prev
    t = start
    done[0] = 0
    while t < Q.shape[0] and rotation[t]:
        _predict(t, same, snapped, xs, weights, path_states, guess)
        q, q_from = Q[t], Q[t - 1]
        if not _turn(q, q_from, n) <= max_turn:
            break
        reduced_radians(q, alpha[t])
        cvar[t, :] = gather_state(theta[t - 1], slot, q, q_state if t == start else q_from)
        conv, it, rn, det_j, det_h, passes = newton(
            guess, alpha[t], beta, tips, rigid, k, gj, bounds, kap, kapy, present, nsteps, nsample,
            tol, max_iter, max_step, xs[t], body[t], table, pairs, cvar[t], prm, cout[t])
        counts[t, 1] = passes
        held = _same_modes(modes_prev if t == start else cout[t - 1, :, 3], cout[t, :, 3])
        if not _accepted(conv, det_j, det_h, xs[t], xs[t - 1], lengths, n, det, jump, slack, rate,
                         held):
            break
        theta[t, :] = state_after(slot, cout[t], table, pairs, prm[1], size)
        _record(t, rn, det_j, det_h, it, stats, counts)
        det = det_j
        t += 1
        done[0] = t - start
    return t - start


@njit(cache=True)
def moving_run(Q, start, rotation, same, snapped, xs, det_prev, weights, path_states, tube_len,
               extra, sec_len, sec_kap, sec_kapy, n_sec, h, max_rk4, rigid, k, gj, tol, max_iter,
               max_step, max_turn, jump, slack, rate, alpha, body, stats, counts, done):
    """warm_run for translating steps (rotation[t] False) of a robot without contact effects: each
    step on a grid of its own, built as pointwise.prepare builds it (grid.prepare, the same
    function; the run stops before a grid of more than max_rk4 RK4 steps, where the general path
    raises). tube_len, extra, sec_len, sec_kap, sec_kapy, n_sec: the robot's arrays
    (mechanics.arrays.RobotArrays), h: the RK4 step (pointwise.rk4_step). The rest as warm_run."""
    n = xs.shape[1]
    guess = np.empty(n)
    det = det_prev
    t = start
    done[0] = 0
    while t < Q.shape[0] and not rotation[t]:
        _predict(t, same, snapped, xs, weights, path_states, guess)
        q, q_from = Q[t], Q[t - 1]
        if not _turn(q, q_from, n) <= max_turn:
            break
        a, beta, tips, grid, _ = prepare(q, tube_len, extra, sec_len, sec_kap, sec_kapy, n_sec, h)
        if grid[5].sum() > max_rk4:
            break
        alpha[t, :] = a
        conv, it, rn, det_j, det_h, passes = newton(
            guess, a, beta, tips, rigid, k, gj, grid[0], grid[1], grid[2], grid[3], grid[4],
            grid[5], tol, max_iter, max_step, xs[t], body[t], None, None, None, None, None)
        counts[t, 1] = passes
        if not _accepted(conv, det_j, det_h, xs[t], xs[t - 1], tube_len, n, det, jump, slack, rate,
                         True):
            break
        _record(t, rn, det_j, det_h, it, stats, counts)
        det = det_j
        t += 1
        done[0] = t - start
    return t - start


@njit(cache=True)
def _held_translating(before, after):
    """continuation._det_comparable(before, after, translating=True) on the stick/slip patterns
    before (K0,) and after (K,): the same bytes (a grid of another station count is another
    pattern) and no element slipped (its torsional tangent depends on the step's axial slip)."""
    if before.shape[0] != after.shape[0] or not _same_modes(before, after):
        return False
    for j in range(after.shape[0]):
        if after[j] == SLIP:
            return False
    return True


@njit(cache=True)
def friction_moving_run(Q, start, rotation, same, snapped, xs, det_prev, weights, path_states,
                        tube_len, extra, sec_len, sec_kap, sec_kapy, n_sec, h, max_rk4, rigid, k,
                        gj, tol, max_iter, max_step, max_turn, jump, slack, rate, width, pairs,
                        prm, q_state, modes_prev, theta, cvar, cout, n_stations, alpha, body,
                        stats, counts, done):
    """moving_run on a robot with friction or clearance: each translating step what
    continuation._advance's first try does there, on a grid and stations of its own
    (pointwise.prepare: grid.prepare, contact.station_table with `width` slots a pair; the run
    stops before a grid of more than max_rk4 RK4 steps, as moving_run, or of more stations than
    cout holds), from the friction state of the step before (theta[t − 1] (P · slots,), held at
    joints q_state for step start, Q[t − 1] after; the state is kept per slot, so it carries
    across grids): its cvar (contact.gather_state) into cvar[t, :K + P], the Newton solve with the
    stations into cout[t, :K] (K stations: n_stations[t]), the acceptance test (stable, twist
    within jump, det J continuous only where the stick/slip pattern is the previous step's, as
    many elements and none slipping: _held_translating; modes_prev (K0,) for step start, cout[t −
    1, :n_stations[t − 1], 3] after) and the state after it (contact.state_after) into theta[t].
    pairs (P, 3), prm (4,): friction.Stations' (the robot's and the settings'). The rest as
    moving_run; cvar, cout and n_stations are written for the step that is not accepted as well."""
    n = xs.shape[1]
    n_pairs = n - 1
    size = theta.shape[1]
    guess = np.empty(n)
    det = det_prev
    t = start
    done[0] = 0
    while t < Q.shape[0] and not rotation[t]:
        _predict(t, same, snapped, xs, weights, path_states, guess)
        q, q_from = Q[t], Q[t - 1]
        if not _turn(q, q_from, n) <= max_turn:
            break
        a, beta, tips, grid, code = prepare(q, tube_len, extra, sec_len, sec_kap, sec_kapy, n_sec, h)
        if grid[5].sum() > max_rk4:
            break
        table, slot, _ = station_table(grid[0], grid[3], code, tips, width)
        nst = slot.shape[0]
        if nst > cout.shape[1]:
            break
        cv = gather_state(theta[t - 1], slot, q, q_state if t == start else q_from)
        out = np.empty((nst, cout.shape[2]))
        alpha[t, :] = a
        conv, it, rn, det_j, det_h, passes = newton(
            guess, a, beta, tips, rigid, k, gj, grid[0], grid[1], grid[2], grid[3], grid[4],
            grid[5], tol, max_iter, max_step, xs[t], body[t], table, pairs, cv, prm, out)
        counts[t, 1] = passes
        cvar[t, :nst + n_pairs] = cv
        cout[t, :nst] = out
        n_stations[t] = nst
        held = _held_translating(modes_prev if t == start else cout[t - 1, :n_stations[t - 1], 3],
                                 out[:, 3])
        if not _accepted(conv, det_j, det_h, xs[t], xs[t - 1], tube_len, n, det, jump, slack, rate,
                         held):
            break
        theta[t, :] = state_after(slot, out, table, pairs, prm[1], size)
        _record(t, rn, det_j, det_h, it, stats, counts)
        det = det_j
        t += 1
        done[0] = t - start
    return t - start
