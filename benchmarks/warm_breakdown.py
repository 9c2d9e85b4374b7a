"""Where a warm continuation step's time goes (issue 26, goal 1), by measurement:
`python benchmarks/bench_mechanics.py --breakdown` (this tree's code, or an older tree's with
PYTHONPATH=<its src>: the parts it lacks read 0).

The paper robot's 1° sweeps (bench_mechanics' warm figure) are followed with the parts of a step
wrapped in timers, each adding its own time to a bucket of the step it runs in:

    the kernel calls       the compiled code as called from Python, numba's dispatch of the
                           arguments included: the warm step (mechanics.warm.warm_step: α, the
                           Newton solve, the acceptance test) and the general path's Newton solves
                           (kernels.newton: passes, allocation, Newton logic)
    the warm step's Python continuation._warm less its kernel: output arrays, Problem, Equilibrium
    the Newton wrapper     pointwise.newton less the kernel: contact arrays, NewtonResult
    the problem            continuation._problem_at: with_alpha (α in radians, a Problem)
    the equilibrium        pointwise.equilibrium: an Equilibrium of the result
    the rest               follow's and _advance's Python: predictor, checks, flags, the timers

Inside the kernel calls, numba's dispatch is measured apart (a compiled function that does nothing,
called with warm_step's 27 arguments) and so are the integration passes (passes per step, counted,
times one pass with the variation and one final pass as a Newton solve makes them, each timed
inside one compiled call). The timers' own cost is measured (an empty function, timed the same
way) and taken out of the rest. Thread CPU time; medians over the steps, and means (the parts of
the mean add up to the mean total).
"""

from __future__ import annotations

import contextlib
import itertools
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from numba import njit

from ctrkin import Robot, SolverSettings, follow, solve
from ctrkin.mechanics import continuation, kernels, pointwise

CLOCK = time.thread_time
BUCKETS = ("kernel", "warm", "wrapper", "problem", "equilibrium")


@njit(cache=True)
def _nothing(q, q_from, guess, x_prev, det_prev, lengths, beta, tips, rigid, k, gj, bounds, kap,
             kapy, present, nsteps, nsample, tol, max_iter, max_step, max_turn, jump, slack, rate,
             alpha, x_out, body_out):
    """warm.warm_step's signature, doing nothing: its call time is numba's dispatch."""
    return True, 0, 0.0, 1.0, 1.0, 2


def _passes_fn() -> Any:
    """A compiled loop of R passes as a Newton solve makes them: passes.flat_pass where this tree
    has it, else kernels._integrate (the code before it)."""
    try:
        from ctrkin.mechanics.passes import flat_pass, flat_work
    except ImportError:
        flat_pass = None

    if flat_pass is not None:
        @njit
        def passes(reps, with_var, with_body, x, alpha, beta, tips, rigid, k, gj, bounds, kap,
                   kapy, present, nsteps, nsample):
            n = k.shape[0]
            fw = flat_work(n)
            r, jac = np.empty(n), np.empty((n, n))
            d = 0.0
            for _ in range(reps):
                d = flat_pass(x, alpha, beta, tips, rigid, k, gj, bounds, kap, kapy, present,
                              nsteps, nsample, with_var, with_body, fw, r, jac)
            return d
        return passes

    @njit
    def passes_old(reps, with_var, with_body, x, alpha, beta, tips, rigid, k, gj, bounds, kap,
                   kapy, present, nsteps, nsample):
        n = k.shape[0]
        y, phi, zb, w = np.empty(2 * n), np.empty((2 * n, n)), np.empty(kernels.NB), kernels._work(n)
        r, jac = np.empty(n), np.empty((n, n))
        rs, ps, qs, us = np.empty(1), np.empty((1, 3)), np.empty((1, 1)), np.empty((1, 1))
        d = 0.0
        for _ in range(reps):
            d = kernels._integrate(x, alpha, beta, tips, rigid, k, gj, bounds, kap, kapy, present,
                                   nsteps, nsample, with_var, with_body, y, phi, zb, w, r, jac,
                                   False, rs, ps, qs, us, None, None, None, None, None)
        return d
    return passes_old


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
    """Median µs of a call of _nothing with a warm step's arguments."""
    eq = solve(robot, q, settings=settings)
    pb = eq.problem
    a = pb.arrays
    n = eq.x.shape[0]
    args = (eq.q, eq.q, eq.x, eq.x, 1.0, a.lengths, pb.beta, pb.tips, a.rigid, a.k, a.gj, *pb.grid,
            settings.tol, settings.max_iter, settings.max_step, 30.0, 0.35, 0.05, 0.5, np.empty(n),
            np.empty(n), np.empty(7))
    _nothing(*args)
    t = np.empty(reps)
    for i in range(reps):
        t0 = CLOCK()
        _nothing(*args)
        t[i] = CLOCK() - t0
    return float(np.median(t) * 1e6)


def _timer_us(reps: int = 2000) -> float:
    """Median µs a _timed wrapper adds to a call (its clock reads and bookkeeping)."""
    acc = {"x": 0.0}
    f = _timed(lambda: None, acc, "x")
    t = np.empty(reps)
    for i in range(reps):
        t0 = CLOCK()
        f()
        t[i] = CLOCK() - t0
    return float(np.median(t) * 1e6)


def _pass_us(robot: Robot, q: np.ndarray, settings: SolverSettings) -> tuple[float, float]:
    """µs of one pass with the variation and of one final pass at q's equilibrium (medians of 201
    calls of 20 passes each, alternating)."""
    eq = solve(robot, q, settings=settings)
    pb = eq.problem
    a = pb.arrays
    common = (eq.x, pb.alpha, pb.beta, pb.tips, a.rigid, a.k, a.gj, *pb.grid)
    passes = _passes_fn()
    passes(1, True, False, *common)
    passes(1, False, True, *common)
    tv, tf = np.empty(201), np.empty(201)
    for i in range(201):
        t0 = CLOCK()
        passes(20, True, False, *common)
        t1 = CLOCK()
        passes(20, False, True, *common)
        t2 = CLOCK()
        tv[i], tf[i] = (t1 - t0) / 20, (t2 - t1) / 20
    return float(np.median(tv) * 1e6), float(np.median(tf) * 1e6)


def breakdown(robot: Robot, sweeps: list[np.ndarray], settings: SolverSettings,
              plain_us: float) -> dict[str, float]:
    """Print the table of a warm step's parts (module docstring) and return its figures (µs);
    plain_us: the uninstrumented median step (bench_warm's)."""
    counters = ("calls", "passes", "timed", "dispatch")
    acc = dict.fromkeys((*BUCKETS, *counters), 0.0)
    warm = getattr(continuation, "warm", None)  # the compiled warm step, where this tree has one
    saved = [(kernels, "newton"), (continuation, "newton"), (continuation, "_problem_at"),
             (continuation, "equilibrium")] + ([(warm, "warm_step"), (continuation, "_warm")]
                                                if warm is not None else [])
    originals = [getattr(m, name) for m, name in saved]

    def counted(fn: Callable[..., Any], passes_at: int | None) -> Callable[..., Any]:
        def call(*args: Any) -> Any:
            out = fn(*args)
            acc["calls"] += passes_at is not None
            acc["dispatch"] += passes_at is not None
            acc["passes"] += out[passes_at] if passes_at is not None else 0
            acc["timed"] += 1
            return out
        return call

    kernels.newton = _timed(counted(kernels.newton, 5), acc, "kernel")
    continuation.newton = _timed(counted(pointwise.newton, None), acc, "wrapper", ("kernel",))
    continuation._problem_at = _timed(counted(continuation._problem_at, None), acc, "problem")
    continuation.equilibrium = _timed(counted(continuation.equilibrium, None), acc, "equilibrium",
                                      ("kernel",))
    runs: list[tuple[int, int]] = []  # (first step, steps) of each compiled run of steps
    run_fn = None if warm is None else getattr(warm, "warm_run", None)
    if warm is not None:
        warm.warm_step = _timed(counted(warm.warm_step, 5), acc, "kernel")
        continuation._warm = _timed(counted(continuation._warm, None), acc, "warm", ("kernel",))
    runs_at: Any = continuation  # the Python of follow's compiled runs: continuation in older trees
    with contextlib.suppress(ImportError):
        from ctrkin.mechanics import compiled_runs as runs_at
    if run_fn is not None:
        saved += [(warm, "warm_run"), (runs_at, "_warm_run")]
        originals += [run_fn, runs_at._warm_run]

        def run(*args: Any) -> int:
            counts = args[-2]
            before = counts[:, 1].sum()
            m = run_fn(*args)
            acc["calls"] += m + (m < counts.shape[0] - args[1])  # the steps tried
            acc["passes"] += counts[:, 1].sum() - before
            acc["timed"] += 1
            acc["dispatch"] += 1
            runs.append((int(args[1]), m))
            return m

        warm.warm_run = _timed(run, acc, "kernel")
        runs_at._warm_run = _timed(runs_at._warm_run, acc, "warm", ("kernel",))
    rows: dict[str, list[float]] = {k: [] for k in ("total", *BUCKETS, *counters)}
    try:
        for Qs in sweeps:
            marks: list[tuple[float, dict[str, float]]] = []
            runs.clear()

            def mark(_t: int, marks: list[tuple[float, dict[str, float]]] = marks) -> None:
                marks.append((CLOCK(), dict(acc)))

            follow(robot, Qs, settings=settings, progress=mark)
            part: dict[str, list[float]] = {k: [] for k in rows}
            for (t0, a0), (t1, a1) in itertools.pairwise(marks):
                part["total"].append(t1 - t0)
                for k in (*BUCKETS, *counters):
                    part[k].append(a1[k] - a0[k])
            for k, v in part.items():  # a run's steps share its time and counts equally
                arr = np.array(v)
                for start, m in runs:
                    if m:
                        arr[start - 1:start + m - 1] = arr[start - 1:start + m - 1].sum() / m
                rows[k].extend(arr.tolist())
    finally:
        for (m, name), fn in zip(saved, originals, strict=True):
            setattr(m, name, fn)
    r = {k: np.array(v) for k, v in rows.items()}
    q = sweeps[len(sweeps) // 2][40]
    disp = _dispatch_us(robot, q, settings)
    timer = _timer_us()
    var_us, fin_us = _pass_us(robot, q, settings)
    calls, passes = r["calls"].mean(), r["passes"].mean()
    dispatches = r["dispatch"].mean()  # compiled calls a step (a run's one shared by its steps)
    us = {k: r[k] * 1e6 for k in ("total", *BUCKETS)}
    kernel_mean = us["kernel"].mean()
    pass_mean = (passes - calls) * var_us + calls * fin_us  # one final pass per converged solve
    rest = us["total"] - sum(us[k] for k in BUCKETS) - r["timed"] * timer
    total_mean = us["total"].mean() - r["timed"].mean() * timer

    def row(name: str, v: np.ndarray) -> tuple[str, float, float]:
        return name, float(np.median(v)), float(v.mean())

    lines: list[tuple[str, float | None, float]] = [
        ("step, uninstrumented (bench_warm's median)", plain_us, plain_us),
        ("step, instrumented, less the timers' own cost", float(np.median(us["total"] - r["timed"] * timer)),
         total_mean),
        row("  the kernel calls", us["kernel"]),
        (f"    numba dispatch ({dispatches:.3f} calls × {disp:.2f})", dispatches * disp,
         dispatches * disp),
        (f"    integration passes ({passes - calls:.2f} × {var_us:.2f} with the variation, "
         f"{calls:.2f} × {fin_us:.2f} final)", None, pass_mean),
        ("    the kernels' own (allocation, Newton logic, acceptance)", None,
         kernel_mean - dispatches * disp - pass_mean),
        row("  the warm steps' Python (continuation._warm, _warm_run: arrays, Problem, Equilibrium)",
            us["warm"]),
        row("  Newton wrapper (pointwise.newton)", us["wrapper"]),
        row("  problem (_problem_at: with_alpha)", us["problem"]),
        row("  equilibrium (pointwise.equilibrium)", us["equilibrium"]),
        row("  the rest (follow, _advance: predictor, checks, flags)", rest),
    ]
    print(f"  where a warm step goes ({len(us['total'])} steps; thread CPU µs; timers "
          f"{r['timed'].mean():.2f} a step × {timer:.2f} µs taken out):")
    print(f"    {'part':<78} {'median':>8} {'mean':>8}")
    for name, med, mean in lines:
        ms = "" if med is None else f"{med:8.2f}"
        print(f"    {name:<78} {ms:>8} {mean:8.2f}")
    python_mean = total_mean - kernel_mean
    print(f"  Python around the kernels: {python_mean:.2f} µs of the instrumented mean "
          f"{total_mean:.2f} ({python_mean / total_mean:.0%}); the kernel calls: {kernel_mean:.2f}")
    return {"breakdown_step_us": float(np.median(us["total"] - r["timed"] * timer)),
            "breakdown_kernel_us": kernel_mean, "breakdown_python_us": python_mean,
            "breakdown_dispatch_us": dispatches * disp, "breakdown_passes_us": pass_mean,
            "breakdown_pass_var_us": var_us, "breakdown_pass_final_us": fin_us}
