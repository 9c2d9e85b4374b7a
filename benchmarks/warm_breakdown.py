"""Where a warm continuation step's time goes (issue 26, goal 1), by measurement:
`python benchmarks/bench_mechanics.py --breakdown` (the current tree's code only).

The paper robot's 1° sweeps (bench_mechanics' warm figure) are followed with the parts of a step
wrapped in timers, each adding its own time to a bucket of the step it runs in:

    the Newton kernel      the compiled solve (its passes, allocations, Newton logic) and numba's
                           dispatch of its arguments, as a call from Python
    the Newton wrapper     pointwise.newton less the kernel: contact arrays, NewtonResult
    the problem            continuation._problem_at: with_alpha (α in radians, a Problem)
    the equilibrium        pointwise.equilibrium: an Equilibrium of the result
    the rest               follow's and _advance's Python: predictor, acceptance checks, flags

Inside the kernel call, numba's dispatch is measured apart (a compiled function that does nothing,
called with the same arguments) and so are the integration passes (passes per step, counted, times
one library pass with the variation and one final pass, each timed inside one compiled call, as
bench_pass does). Each timer costs the step about a microsecond (the instrumented total is printed
beside the uninstrumented median). Thread CPU time; medians over the steps, and means (the parts of
the mean add up to the mean total).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np
from numba import njit

from ctrkin import Robot, SolverSettings, follow, solve
from ctrkin.mechanics import continuation, kernels, pointwise

CLOCK = time.thread_time
BUCKETS = ("kernel", "wrapper", "problem", "equilibrium")


@njit(cache=True)
def _nothing(x0, alpha, beta, tips, rigid, k, gj, bounds, kap, kapy, present, nsteps, nsample,
             tol, max_iter, max_step, x_out, body_out, cst=None, cpr=None, cvar=None, cprm=None,
             cout=None):
    """kernels.newton's signature, doing nothing: its call time is numba's dispatch."""
    return True, 0, 0.0, 1.0, 1.0, 2


@njit(cache=True)
def _final_passes(reps, x, alpha, beta, tips, rigid, k, gj, bounds, kap, kapy, present, nsteps,
                  nsample):
    """reps final passes (backbone and energy, no variation), as kernels.newton makes them."""
    n = k.shape[0]
    y = np.empty(2 * n)
    phi = np.empty((2 * n, n))
    zb = np.empty(kernels.NB)
    w = kernels._work(n)
    r, jac = np.empty(n), np.empty((n, n))
    rs, ps, qs, us = np.empty(1), np.empty((1, 3)), np.empty((1, 1)), np.empty((1, 1))
    for _ in range(reps):
        kernels._integrate(x, alpha, beta, tips, rigid, k, gj, bounds, kap, kapy, present, nsteps,
                           nsample, False, True, y, phi, zb, w, r, jac, False, rs, ps, qs, us,
                           None, None, None, None, None)
    return zb[12]


def _timed(fn: Callable[..., Any], acc: dict[str, float], key: str,
           inner: tuple[str, ...] = ()) -> Callable[..., Any]:
    """fn, adding its thread CPU time to acc[key] less what the buckets `inner` gained meanwhile."""
    clock = CLOCK

    def wrapper(*args: Any, **kw: Any) -> Any:
        before = [acc[k] for k in inner]
        t0 = clock()
        out = fn(*args, **kw)
        dt = clock() - t0
        acc[key] += dt - sum(acc[k] - b for k, b in zip(inner, before, strict=True))
        return out

    return wrapper


def _dispatch_us(robot: Robot, q: np.ndarray, settings: SolverSettings, reps: int = 2000) -> float:
    """Median µs of a call of _nothing with kernels.newton's arguments (a warm step's)."""
    eq = solve(robot, q, settings=settings)
    pb = eq.problem
    a = pb.arrays
    args = (eq.x, pb.alpha, pb.beta, pb.tips, a.rigid, a.k, a.gj, *pb.grid, settings.tol,
            settings.max_iter, settings.max_step, np.empty(2), np.empty(7),
            *pointwise.contact_arrays(pb))
    _nothing(*args)
    t = np.empty(reps)
    for i in range(reps):
        t0 = CLOCK()
        _nothing(*args)
        t[i] = CLOCK() - t0
    return float(np.median(t) * 1e6)


def _pass_us(robot: Robot, q: np.ndarray, settings: SolverSettings) -> tuple[float, float]:
    """µs of one pass with the variation and of one final pass at q's equilibrium (medians of 201
    calls of 20 passes each, alternating)."""
    from bare_pass import real_passes

    eq = solve(robot, q, settings=settings)
    pb = eq.problem
    a = pb.arrays
    n = eq.x.shape[0]
    common = (eq.x, pb.alpha, pb.beta, pb.tips, a.rigid, a.k, a.gj, *pb.grid)
    r, j = np.empty(n), np.empty((n, n))
    real_passes(1, *common, r, j)
    _final_passes(1, *common)
    tv, tf = np.empty(201), np.empty(201)
    for i in range(201):
        t0 = CLOCK()
        real_passes(20, *common, r, j)
        t1 = CLOCK()
        _final_passes(20, *common)
        t2 = CLOCK()
        tv[i], tf[i] = (t1 - t0) / 20, (t2 - t1) / 20
    return float(np.median(tv) * 1e6), float(np.median(tf) * 1e6)


def breakdown(robot: Robot, sweeps: list[np.ndarray], settings: SolverSettings,
              plain_us: float) -> dict[str, float]:
    """Print the table of a warm step's parts (module docstring) and return its figures (µs);
    plain_us: the uninstrumented median step (bench_warm's)."""
    acc = dict.fromkeys((*BUCKETS, "calls", "passes"), 0.0)
    saved = (kernels.newton, continuation.newton, continuation._problem_at,
             continuation.equilibrium)
    real_kernel = kernels.newton

    def kernel(*args: Any) -> Any:
        out = real_kernel(*args)
        acc["calls"] += 1
        acc["passes"] += out[5]
        return out

    kernels.newton = _timed(kernel, acc, "kernel")
    continuation.newton = _timed(pointwise.newton, acc, "wrapper", ("kernel",))
    continuation._problem_at = _timed(continuation._problem_at, acc, "problem")
    continuation.equilibrium = _timed(continuation.equilibrium, acc, "equilibrium", ("kernel",))
    rows: dict[str, list[float]] = {k: [] for k in ("total", *BUCKETS, "calls", "passes")}
    try:
        for Qs in sweeps:
            marks: list[tuple[float, dict[str, float]]] = []

            def mark(_t: int) -> None:
                marks.append((CLOCK(), dict(acc)))

            follow(robot, Qs, settings=settings, progress=mark)
            for (t0, a0), (t1, a1) in zip(marks[:-1], marks[1:], strict=True):
                rows["total"].append(t1 - t0)
                for k in (*BUCKETS, "calls", "passes"):
                    rows[k].append(a1[k] - a0[k])
    finally:
        (kernels.newton, continuation.newton, continuation._problem_at,
         continuation.equilibrium) = saved
    r = {k: np.array(v) for k, v in rows.items()}
    q = sweeps[len(sweeps) // 2][40]
    disp = _dispatch_us(robot, q, settings)
    var_us, fin_us = _pass_us(robot, q, settings)
    calls, passes = r["calls"].mean(), r["passes"].mean()
    kernel_mean = r["kernel"].mean() * 1e6
    pass_mean = (passes - calls) * var_us + calls * fin_us  # one final pass per converged solve
    rest = r["total"] - sum(r[k] for k in BUCKETS)
    lines = [
        ("step, uninstrumented (bench_warm's median)", plain_us, plain_us),
        ("step, instrumented", np.median(r["total"]) * 1e6, r["total"].mean() * 1e6),
        ("  Newton kernel call", np.median(r["kernel"]) * 1e6, kernel_mean),
        (f"    numba dispatch ({calls:.2f} calls × {disp:.2f})", calls * disp, calls * disp),
        (f"    integration passes ({passes - calls:.2f} × {var_us:.2f} with the variation, "
         f"{calls:.2f} × {fin_us:.2f} final)", None, pass_mean),
        ("    the kernel's own (allocation, Newton logic)", None, kernel_mean - calls * disp - pass_mean),
        ("  Newton wrapper (pointwise.newton)", np.median(r["wrapper"]) * 1e6, r["wrapper"].mean() * 1e6),
        ("  problem (with_alpha)", np.median(r["problem"]) * 1e6, r["problem"].mean() * 1e6),
        ("  equilibrium", np.median(r["equilibrium"]) * 1e6, r["equilibrium"].mean() * 1e6),
        ("  the rest (follow, _advance: predictor, checks, timers)", np.median(rest) * 1e6,
         rest.mean() * 1e6),
    ]
    print(f"  where a warm step goes ({len(r['total'])} steps; thread CPU µs):")
    print(f"    {'part':<78} {'median':>8} {'mean':>8}")
    for name, med, mean in lines:
        ms = "" if med is None else f"{med:8.2f}"
        print(f"    {name:<78} {ms:>8} {mean:8.2f}")
    python_mean = r["total"].mean() * 1e6 - kernel_mean
    print(f"  Python around the kernel: {python_mean:.2f} µs of the instrumented mean "
          f"{r['total'].mean() * 1e6:.2f} ({python_mean / (r['total'].mean() * 1e6):.0%}); inside "
          f"the kernel call: {kernel_mean:.2f}")
    return {"breakdown_step_us": float(np.median(r["total"]) * 1e6),
            "breakdown_kernel_us": kernel_mean, "breakdown_python_us": python_mean,
            "breakdown_dispatch_us": calls * disp, "breakdown_passes_us": pass_mean,
            "breakdown_pass_var_us": var_us, "breakdown_pass_final_us": fin_us}
