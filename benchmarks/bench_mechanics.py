"""Mechanics benchmark: TCM speed and accuracy on the paper robot (issue 2 goals) and on the
three-tube robot of the public C++ TCM of TIMClab-CAMI (issue 11, `ctrkin.robots.timclab_robot`).

    python benchmarks/bench_mechanics.py            # 1,000 cold solves, 2×721 warm steps, accuracy
    python benchmarks/bench_mechanics.py --n 200    # quicker
    python benchmarks/bench_mechanics.py --breakdown  # where the paper robot's warm step goes
    python benchmarks/bench_mechanics.py --n 200 --n-ref 5 --baseline a389fb6   # old and new

Prints, per robot: cold solve from the default guess (paper: median ≤ 1 ms goal, the paper's TCM took
1.47 s a point; TIMClab: ≤ 100 µs), warm continuation step inside `follow` and the public warm path
`solve(q, guess=previous)` along 1° sweeps (paper ≤ 35 µs, TIMClab ≤ 60 µs) with the integration
passes a step makes (counted in an untimed run), the paper robot's warm step on a path that rotates
and translates at once (a new grid every step; keys paper_warm_simultaneous_*), and the tip-position
deviation from a tight-tolerance reference integration (scipy DOP853, rtol 1e-12; goal ≤ 1e-3 mm).
The default step is chosen from SolverSettings.tip_tol = 1e-3 mm; the TIMClab robot is run again at
the fixed 3 mm step of earlier versions (tip_tol=None, step=3, angle_step=0.15; keys
timclab_3mm_*). The friction step (issue 20: ≤ 5× the frictionless one): the paper robot's sweeps
followed with μ = FRICTION_MU and without, alternately, ROUNDS times in one process, so the ratio
(median of the rounds' ratios of median step times) holds under load (keys paper_friction_*).
One integration pass with the variation (what a Newton iteration integrates) beside its floor, a
bare RK4 pass of the same arithmetic on the same grid (benchmarks/bare_pass.py), alternating in
this process, residuals checked bit for bit (keys pass_us, bare_pass_us, pass_ratio: TIMClab robot,
+15 mm sweep at α1 = 40°; paper_pass_*: paper robot, d = 12 mm at α1 = 40°).
Times are this thread's CPU time (time.thread_time), so they hold on a loaded machine.
Runs on one core. Ends with one JSON line of the headline figures (medians in µs, errors in mm).
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import os
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np

from ctrkin import Robot, SolverSettings, follow, paper_robot, solve
from ctrkin.acquisition.trajectories import rotation_sweep
from ctrkin.mechanics import continuation
from ctrkin.mechanics.arrays import robot_arrays
from ctrkin.mechanics.pointwise import NewtonResult, Problem, rk4_step
from ctrkin.robots import timclab_robot

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
sys.path.insert(0, str(Path(__file__).resolve().parent))
from bare_pass import bare_passes, bare_work, real_passes
from mechanics.reference_tcm import reference_tip

warm = getattr(continuation, "warm", None)  # the compiled warm step (None in a tree before it)
REPO = Path(__file__).resolve().parents[1]
BASELINE = "a389fb6"  # main before the compiled run of warm steps (issue 26)

# What every solve of the run gave (tip poses, snap flags, stability, base states, in run order):
# its digest ends the JSON line (`results_sha`), so that --baseline shows whether old and new code
# computed the same numbers, bit for bit.
RESULTS = hashlib.sha256()


def record(*arrays: np.ndarray) -> None:
    for a in arrays:
        RESULTS.update(np.ascontiguousarray(a).tobytes())


# Every time is this thread's CPU time: on the shared, loaded machine a wall clock also counts the
# other processes that preempt this one (equal to the wall time on an idle machine).
CLOCK = time.thread_time


def random_configs(n: int, seed: int = 0) -> np.ndarray:
    """Uniform valid configurations of the paper robot: β2 ∈ [−20, 0], d = β2 − β1 ∈ [0, 20.5]."""
    rng = np.random.default_rng(seed)
    b2 = rng.uniform(-20, 0, n)
    return np.c_[rng.uniform(0, 360, n), rng.uniform(0, 360, n), b2 - rng.uniform(0, 20.5, n), b2]


def timclab_configs(n: int, seed: int = 0) -> np.ndarray:
    """Uniform valid configurations of the TIMClab robot: α ∈ [0, 360)³, β3 ∈ [−150, 0] and each
    inner tube retracted behind the next by up to its full excess length (L1 − L2, L2 − L3), so every
    overlap of the three curved parts occurs."""
    rng = np.random.default_rng(seed)
    lengths = timclab_robot().lengths
    b3 = -rng.uniform(0, 150, n)
    b2 = b3 - rng.uniform(0, lengths[1] - lengths[2], n)
    b1 = b2 - rng.uniform(0, lengths[0] - lengths[1], n)
    return np.c_[rng.uniform(0, 360, (n, 3)), b1, b2, b3]


def timclab_sweeps() -> list[np.ndarray]:
    """Inner tube rotated 0 → 360 → 0° in 1° steps, the others at α = 0, outer tube at β = 0, with
    every curved part overlapping: all tips flush (strongest coupling, snaps), and each inner tip
    15 and 30 mm beyond the next one's."""
    lengths = timclab_robot().lengths
    out = []
    for ext in (0.0, 15.0, 30.0):
        b2 = lengths[2] - lengths[1] + ext
        b1 = b2 + lengths[1] - lengths[0] + ext
        q = rotation_sweep(2, 0.0)
        out.append(np.c_[q[:, 0], np.zeros((len(q), 2)), np.full(len(q), b1),
                         np.full(len(q), b2), np.zeros(len(q))])
    return out


def simultaneous_sweeps() -> list[np.ndarray]:
    """Paper robot, inner tube rotated 0 → 360° in 1° steps while it translates from d = 20 to
    2 mm (0.05 mm a step, built with linspace), and back: every step changes β, so every step
    needs a new integration grid (a rotation sweep keeps it)."""
    a = np.linspace(0.0, 360.0, 361)
    b1 = np.linspace(-20.0, -2.0, 361)
    fwd = np.c_[a, np.zeros_like(a), b1, np.zeros_like(a)]
    return [fwd, fwd[::-1]]


class StepClock:
    """Per-step times and passes of `follow`, for this tree's code and an older one's alike.

    follow calls `progress` once per step, in order; where a compiled run of steps solves several
    in one call (mechanics.warm's warm_run, friction_run, moving_run and friction_moving_run, those
    this tree has) their calls come together when the run returns, so a step's time is not the
    time between two calls: the steps of a run share its time equally (from the call before the
    run to the run's last, the failed try of the step after it included), every other step gets
    the time since the previous call. Passes: those of each Newton solve of the general path
    (continuation.newton) go to the step being solved, those of a run to the steps it tried (its
    `counts`). Use as a context manager around follow calls made with progress=clock.progress,
    clock.begin() before each."""

    def __init__(self, count_passes: bool = False) -> None:
        self.times: list[float] = []
        self.passes: list[int] = []
        self.count_passes = count_passes
        self._stamps: list[float] = []
        self._runs: list[tuple[int, int]] = []
        self._per: dict[int, int] = {}

    def begin(self) -> None:
        self._flush()
        self._stamps, self._runs, self._per = [], [], {}

    def progress(self, _t: int) -> None:
        self._stamps.append(CLOCK())

    def _flush(self) -> None:
        st = self._stamps
        if len(st) < 2:
            return
        times = np.diff(st)
        for start, m in self._runs:
            if m:
                times[start - 1:start + m - 1] = (st[start + m - 1] - st[start - 1]) / m
        self.times.extend(times.tolist())
        if self.count_passes:
            self.passes.extend(self._per.get(t, 0) for t in range(1, len(st)))

    # mechanics.warm's compiled runs of steps
    RUNS = ("warm_run", "friction_run", "moving_run", "friction_moving_run")

    def __enter__(self) -> StepClock:
        self._inner_newton = continuation.newton
        self._inner_runs = {} if warm is None else {
            name: getattr(warm, name) for name in self.RUNS if hasattr(warm, name)}
        self._inner_step = None if warm is None else warm.warm_step
        clock = self

        def counting(pb: Problem, x0: np.ndarray, st: SolverSettings, work: list[int] | None = None
                     ) -> NewtonResult:
            w = [0]
            sol = clock._inner_newton(pb, x0, st, w)
            t = len(clock._stamps)
            clock._per[t] = clock._per.get(t, 0) + w[0] // pb.n_rk4
            if work is not None:
                work[0] += w[0]
            return sol

        def counting_step(*args: object) -> tuple[bool, int, float, float, float, int]:
            out = clock._inner_step(*args)  # type: ignore[misc]
            t = len(clock._stamps)
            clock._per[t] = clock._per.get(t, 0) + out[5]
            return out

        def wrapped(inner: Callable[..., int]) -> Callable[..., int]:
            def run(*args: object) -> int:
                start = int(args[1])  # type: ignore[call-overload]
                counts = args[-2]  # every run's (T, 2) iterations and passes per step
                before = counts[:, 1].copy() if clock.count_passes else None  # type: ignore[index]
                m = inner(*args)
                clock._runs.append((start, m))
                if before is not None:
                    for t in np.flatnonzero(counts[:, 1] != before).tolist():  # type: ignore[index]
                        clock._per[t] = clock._per.get(t, 0) + int(counts[t, 1])  # type: ignore[index]
                return m
            return run

        if self.count_passes:
            continuation.newton = counting
            if warm is not None:
                warm.warm_step = counting_step
        for name, inner in self._inner_runs.items():
            setattr(warm, name, wrapped(inner))
        return self

    def __exit__(self, *exc: object) -> None:
        self._flush()
        self._stamps = []
        continuation.newton = self._inner_newton
        if warm is not None:
            warm.warm_step = self._inner_step
            for name, inner in self._inner_runs.items():
                setattr(warm, name, inner)


def passes_per_step(robot: Robot, sweeps: list[np.ndarray], settings: SolverSettings) -> np.ndarray:
    """Integration passes of each step of follow (all its Newton solves: sub-steps and fold
    searches included), counted in an untimed run (StepClock)."""
    with StepClock(count_passes=True) as clock:
        for Qs in sweeps:
            clock.begin()
            follow(robot, Qs, settings=settings, progress=clock.progress)
    p = np.array(clock.passes)
    print(f"  integration passes per warm step: median {np.median(p):.0f}, mean {p.mean():.2f} "
          f"({np.mean(p <= 2):.0%} of steps in one pass with the variation and the final one)")
    return p


def stats(t: np.ndarray) -> str:
    return (f"median {np.median(t) * 1e6:.1f} µs, p95 {np.percentile(t, 95) * 1e6:.1f} µs, "
            f"mean {t.mean() * 1e6:.1f} ± {t.std() * 1e6:.1f} µs")


def bench_cold(robot: Robot, Q: np.ndarray, settings: SolverSettings) -> np.ndarray:
    times = np.empty(len(Q))
    stable = 0
    for i, q in enumerate(Q):
        t0 = CLOCK()
        eq = solve(robot, q, settings=settings)
        times[i] = CLOCK() - t0
        stable += eq.stable
        record(eq.tip_pose, eq.x, np.array([eq.stability, eq.conjugate]))
    print(f"  cold solve ({len(Q)} random configurations, default guess): {stats(times)}; "
          f"{stable}/{len(Q)} stable")
    return times


def bench_warm(robot: Robot, sweeps: list[np.ndarray], labels: list[str],
               settings: SolverSettings, n_warm: int = 200) -> tuple[np.ndarray, np.ndarray]:
    """Per-step times inside `follow` and of solve(q, guess=previous) on the first n_warm steps."""
    step_times: list[float] = []
    warm_times: list[float] = []
    for Qs, label in zip(sweeps, labels, strict=True):
        with StepClock() as clock:
            t0 = CLOCK()
            traj = follow(robot, Qs, settings=settings, progress=clock.progress)
            total = CLOCK() - t0
        step_times.extend(clock.times)
        record(traj.tip_poses, traj.snaps, traj.stable, np.array([e.x for e in traj.equilibria]),
               np.array([e.stability for e in traj.equilibria]))
        prev = traj.equilibria[0]
        for q in Qs[1:n_warm]:  # the public warm-start path, timed one by one
            t1 = CLOCK()
            prev = solve(robot, q, guess=prev, settings=settings)
            warm_times.append(CLOCK() - t1)
        print(f"  follow, 1° sweep {label} ({len(Qs)} steps, {traj.n_snaps} snaps): "
              f"{total / len(Qs) * 1e6:.1f} µs per step on average, snap search included")
    st, wt = np.array(step_times), np.array(warm_times)
    print(f"  warm continuation step inside follow: {stats(st)}")
    if n_warm:
        print(f"  warm solve(q, guess=previous equilibrium), 1° steps: {stats(wt)}")
    return st, wt


FRICTION_MU = 0.2   # the virtual robot's default (docs/virtual_robot.md)
ROUNDS = 5


def _step_times(robot: Robot, sweeps: list[np.ndarray], settings: SolverSettings) -> np.ndarray:
    with StepClock() as clock:
        for Qs in sweeps:
            clock.begin()
            follow(robot, Qs, settings=settings, progress=clock.progress)
    return np.array(clock.times)


def bench_friction(robot: Robot, sweeps: list[np.ndarray], settings: SolverSettings
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Warm steps with and without friction, alternated ROUNDS times: (frictionless medians,
    friction medians, ratios) per round, and the passes per friction step."""
    rough = dataclasses.replace(robot, friction=FRICTION_MU)
    follow(rough, sweeps[0][::20], settings=settings)  # compile the friction kernels
    free, fric = [], []
    for _ in range(ROUNDS):
        free.append(np.median(_step_times(robot, sweeps, settings)))
        fric.append(np.median(_step_times(rough, sweeps, settings)))
    f0, f1 = np.array(free), np.array(fric)
    ratio = f1 / f0
    print(f"  friction μ = {FRICTION_MU}, warm step inside follow ({ROUNDS} rounds alternating): "
          f"frictionless {np.median(f0) * 1e6:.1f} µs, friction {np.median(f1) * 1e6:.1f} µs, "
          f"ratio median {np.median(ratio):.2f} (rounds {', '.join(f'{v:.2f}' for v in ratio)})")
    return f0, f1, ratio


PASS_REPS = 20      # passes per compiled call (well inside a scheduler time slice)
PASS_ROUNDS = 301   # calls of each, alternating


def bench_pass(robot: Robot, q: np.ndarray, settings: SolverSettings) -> tuple[float, float, int]:
    """One integration pass with the variation (a Newton iteration's), at the equilibrium of q:
    the library's (kernels._integrate) and the bare pass of the same arithmetic (bare_pass.py),
    PASS_REPS passes per compiled call, PASS_ROUNDS calls of each alternating in this process,
    timed in this thread's CPU time (time.thread_time: a call preempted by another process does not
    count the other's time, so the figure holds on a loaded machine); medians.
    The residuals, Jacobian and det H of the two must agree bit for bit (raises otherwise).
    Returns (pass µs, bare pass µs, RK4 steps of the pass)."""
    eq = solve(robot, q, settings=settings)
    pb = eq.problem
    a = pb.arrays
    n = eq.x.shape[0]
    common = (eq.x, pb.alpha, pb.beta, pb.tips, a.rigid, a.k, a.gj, *pb.grid)
    r0, j0, r1, j1 = np.empty(n), np.empty((n, n)), np.empty(n), np.empty((n, n))
    work = bare_work(n)
    d0 = real_passes(1, *common, r0, j0)  # compile both
    d1 = bare_passes(1, *common, r1, j1, *work)
    same = (np.array_equal(r0, r1) and np.array_equal(j0, j1)
            and np.array_equal(np.float64(d0), np.float64(d1)))
    if not same:
        raise AssertionError(f"bare pass differs from the library's: residuals {r0} vs {r1}, "
                             f"Jacobian {j0.ravel()} vs {j1.ravel()}, det H {d0} vs {d1}")
    t_real, t_bare = np.empty(PASS_ROUNDS), np.empty(PASS_ROUNDS)
    clock = CLOCK
    for i in range(PASS_ROUNDS):
        t0 = clock()
        real_passes(PASS_REPS, *common, r0, j0)
        t1 = clock()
        bare_passes(PASS_REPS, *common, r1, j1, *work)
        t2 = clock()
        t_real[i] = (t1 - t0) / PASS_REPS
        t_bare[i] = (t2 - t1) / PASS_REPS
    p, b = float(np.median(t_real)), float(np.median(t_bare))
    print(f"  one integration pass with the variation ({pb.n_rk4} RK4 steps, q = {np.round(q, 1).tolist()}): "
          f"{p * 1e6:.2f} µs (min {t_real.min() * 1e6:.2f}); bare RK4 pass of the same arithmetic "
          f"{b * 1e6:.2f} µs (min {t_bare.min() * 1e6:.2f}; residuals, Jacobian and det H "
          f"bit-identical); ratio {p / b:.2f} (thread CPU time, medians of {PASS_ROUNDS} alternating "
          "calls)")
    return p * 1e6, b * 1e6, pb.n_rk4


def bench_accuracy(robot: Robot, Q: np.ndarray, settings: SolverSettings) -> np.ndarray:
    errs = []
    for q in Q:
        eq = solve(robot, q, settings=settings)
        tip, _, _ = reference_tip(robot, q, eq.x)
        errs.append(np.linalg.norm(eq.tip_position - tip))
    e = np.array(errs)
    print(f"  tip position vs reference integration ({len(e)} configurations): "
          f"max {e.max():.2e} mm, median {np.median(e):.2e} mm")
    return e


def warm_up(robot: Robot, q: np.ndarray, settings: SolverSettings,
            sweep: Callable[[], np.ndarray]) -> None:
    solve(robot, q, settings=settings)  # compile / load the numba cache
    follow(robot, sweep(), settings=settings)


def breakdown(settings: SolverSettings) -> None:
    """`--breakdown`: the paper robot's warm step inside follow, uninstrumented and split into
    its parts (warm_breakdown.py); prints `uptime` and ends with the JSON line of its figures."""
    import warm_breakdown

    robot = paper_robot()
    print(f"paper robot (2 tubes), load: {os.getloadavg()[0]:.2f} (1-minute load average)")
    warm_up(robot, np.array([0, 0, -10, -5.0]), settings, lambda: rotation_sweep(2, 20.0, step_deg=30.0))
    ds = (4.0, 8.0, 12.0, 16.0, 20.0)
    sweeps = [rotation_sweep(2, d) for d in ds]
    step, _ = bench_warm(robot, sweeps, [f"at d = {d:4.1f} mm" for d in ds], settings, n_warm=0)
    figures = warm_breakdown.breakdown(robot, sweeps, settings, float(np.median(step) * 1e6))
    print(json.dumps({"paper_warm_us": float(f"{np.median(step) * 1e6:.4g}")}
                     | {k: float(f"{v:.4g}") for k, v in figures.items()}))


COMPARED = (("paper_warm_us", "paper warm step inside follow (µs)"),
            ("paper_warm_solve_us", "paper solve(q, guess=previous) (µs)"),
            ("paper_cold_us", "paper cold solve (µs)"),
            ("paper_warm_simultaneous_us", "paper warm step, rotating and translating (µs)"),
            ("paper_pass_us", "paper pass with the variation (µs)"),
            ("paper_bare_pass_us", "paper bare pass, bare_pass.py (µs)"),
            ("paper_friction_warm_us", "paper warm step, friction μ = 0.2 (µs)"),
            ("paper_friction_ratio", "friction step ÷ frictionless step"),
            ("paper_warm_passes_mean", "paper passes per warm step (mean)"),
            ("timclab_robot_warm_us", "TIMClab warm step inside follow (µs)"),
            ("timclab_robot_warm_solve_us", "TIMClab solve(q, guess=previous) (µs)"),
            ("timclab_robot_cold_us", "TIMClab cold solve (µs)"),
            ("pass_us", "TIMClab pass with the variation (µs)"),
            ("bare_pass_us", "TIMClab bare pass, bare_pass.py (µs)"),
            ("timclab_3mm_warm_us", "TIMClab warm step, fixed 3 mm step (µs)"),
            ("timclab_3mm_cold_us", "TIMClab cold solve, fixed 3 mm step (µs)"),
            ("paper_max_tip_error_mm", "paper max tip error vs DOP853 (mm)"),
            ("timclab_max_tip_error_mm", "TIMClab max tip error vs DOP853 (mm)"))
CPP_WARM_US, CPP_COLD_US = 84.0, 118.0  # the C++ TCM of TIMClab-CAMI, issue 11 (not on this machine)


def compare(args: argparse.Namespace) -> None:
    """`--baseline REV`: this benchmark run whole, `--rounds` times alternating, on REV's src
    (git archive, bench_streaming.baseline_tree) and on this tree's, each a process of its own
    (same arguments); prints the medians over rounds of each side's figures with `uptime`, the
    TIMClab figures against the C++ code's, and one JSON line {"old": …, "new": …}."""
    from bench_streaming import baseline_tree

    trees = {"old": baseline_tree(args.baseline), "new": REPO / "src"}
    cmd = [sys.executable, str(Path(__file__).resolve()), "--n", str(args.n), "--n-ref", str(args.n_ref)]
    if args.step is not None:
        cmd += ["--step", str(args.step)]
    runs: dict[str, list[dict[str, float]]] = {"old": [], "new": []}
    loads = []
    for rnd in range(args.rounds):
        for side in ("old", "new"):
            env = dict(os.environ, PYTHONPATH=os.pathsep.join(
                [str(trees[side]), *filter(None, [os.environ.get("PYTHONPATH")])]))
            loads.append(os.getloadavg()[0])
            out = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True).stdout
            runs[side].append(json.loads(out.strip().splitlines()[-1]))
            print(f"round {rnd + 1} {side}: paper warm {runs[side][-1]['paper_warm_us']:.1f} µs, "
                  f"TIMClab warm {runs[side][-1]['timclab_robot_warm_us']:.1f} µs (load "
                  f"{loads[-1]:.2f})", flush=True)
    shas = {side: {r.pop("results_sha", "") for r in rs} for side, rs in runs.items()}
    med = {side: {k: float(np.median([r[k] for r in rs])) for k in rs[0]} for side, rs in runs.items()}
    print(f"\nold = {args.baseline}, new = this tree; medians of {args.rounds} rounds, thread CPU "
          f"time; 1-minute load {min(loads):.2f}–{max(loads):.2f}")
    print(f"  {'figure':<50} {'old':>10} {'new':>10} {'new/old':>8}")
    for key, label in COMPARED:
        o, n = med["old"].get(key, float("nan")), med["new"].get(key, float("nan"))
        print(f"  {label:<50} {o:10.4g} {n:10.4g} {n / o:8.2f}")
    for side in ("old", "new"):
        m = med[side]
        print(f"  {side}: TIMClab warm {m['timclab_robot_warm_us'] / CPP_WARM_US:.2f}× and cold "
              f"{m['timclab_robot_cold_us'] / CPP_COLD_US:.2f}× the C++ code's {CPP_WARM_US:.0f} / "
              f"{CPP_COLD_US:.0f} µs (issue 11; goals ≤ 0.3× / ≤ 0.5×)")
    same = len(shas["old"] | shas["new"]) == 1 and "" not in shas["old"]
    print(f"  results (tip poses, snaps, stability, states of every solve; `results_sha`): "
          f"{'bit for bit the same' if same else 'DIFFER'} (old {sorted(shas['old'])}, new "
          f"{sorted(shas['new'])})")
    print(json.dumps({"baseline": args.baseline, "load_min": min(loads), "load_max": max(loads),
                      "results_same": same}
                     | {side: {k: float(f"{v:.4g}") for k, v in m.items()} for side, m in med.items()}))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=1000, help="random configurations for cold solves")
    ap.add_argument("--n-ref", type=int, default=40, help="configurations checked against the reference")
    ap.add_argument("--step", type=float, default=None, help="largest RK4 step (mm), default: the settings'")
    ap.add_argument("--baseline", default=None, metavar="REV",
                    help=f"old and new: run this benchmark on REV's code (e.g. {BASELINE}, main before "
                         "the compiled runs of steps) and on this tree's, alternating (compare())")
    ap.add_argument("--rounds", type=int, default=2, help="--baseline: rounds of old and new")
    ap.add_argument("--breakdown", action="store_true",
                    help="only the paper robot's warm step, split into its parts (warm_breakdown.py)")
    args = ap.parse_args()
    settings = SolverSettings() if args.step is None else SolverSettings(step=args.step)
    out: dict[str, float] = {}
    if args.breakdown:
        breakdown(settings)
        return
    if args.baseline:
        compare(args)
        return

    robot = paper_robot()
    print("paper robot (2 tubes)")
    warm_up(robot, np.array([0, 0, -10, -5.0]), settings, lambda: rotation_sweep(2, 20.0, step_deg=30.0))
    cold = bench_cold(robot, random_configs(args.n), settings)
    ds = (4.0, 8.0, 12.0, 16.0, 20.0)
    sweeps = [rotation_sweep(2, d) for d in ds]
    step, warm = bench_warm(robot, sweeps, [f"at d = {d:4.1f} mm" for d in ds], settings)
    passes = passes_per_step(robot, sweeps, settings)
    print("paper robot, rotating and translating at once (a new grid every step)")
    sim = simultaneous_sweeps()
    follow(robot, sim[0][:10], settings=settings)  # compile / load the translating steps' kernels
    step_sim, _ = bench_warm(robot, sim, ["d 20 → 2 mm", "d 2 → 20 mm"], settings, n_warm=0)
    passes_sim = passes_per_step(robot, sim, settings)
    err = bench_accuracy(robot, random_configs(args.n_ref, seed=1), settings)
    p_us, b_us, _ = bench_pass(robot, sweeps[2][40], settings)
    out |= {"paper_pass_us": p_us, "paper_bare_pass_us": b_us, "paper_pass_ratio": p_us / b_us}
    f0, f1, ratio = bench_friction(robot, sweeps, settings)
    passes_f = passes_per_step(dataclasses.replace(robot, friction=FRICTION_MU), sweeps, settings)
    out |= {"paper_friction_free_warm_us": np.median(f0) * 1e6,
            "paper_friction_warm_us": np.median(f1) * 1e6,
            "paper_friction_ratio": np.median(ratio), "paper_friction_ratio_max": ratio.max(),
            "paper_friction_passes_mean": passes_f.mean()}
    out |= {"paper_cold_us": np.median(cold) * 1e6, "paper_warm_us": np.median(step) * 1e6,
            "paper_warm_solve_us": np.median(warm) * 1e6,
            "paper_warm_passes_median": np.median(passes), "paper_warm_passes_mean": passes.mean(),
            "paper_warm_simultaneous_us": np.median(step_sim) * 1e6,
            "paper_warm_simultaneous_passes_mean": passes_sim.mean(),
            "paper_max_tip_error_mm": err.max()}

    robot = timclab_robot()
    print("TIMClab robot (3 tubes)")
    sweeps = timclab_sweeps()
    warm_up(robot, timclab_configs(1)[0], settings, lambda: sweeps[0][::30])
    cold = bench_cold(robot, timclab_configs(args.n), settings)
    step, warm = bench_warm(robot, sweeps, ["flush", "+15 mm", "+30 mm"], settings)
    passes = passes_per_step(robot, sweeps, settings)
    p_us, b_us, steps = bench_pass(robot, sweeps[1][40], settings)
    out |= {"pass_us": p_us, "bare_pass_us": b_us, "pass_ratio": p_us / b_us, "pass_rk4_steps": steps}
    err_t = bench_accuracy(robot, timclab_configs(args.n_ref, seed=1), settings)
    out |= {"timclab_robot_cold_us": np.median(cold) * 1e6,
            "timclab_robot_warm_us": np.median(step) * 1e6,
            "timclab_robot_warm_solve_us": np.median(warm) * 1e6,
            "timclab_warm_passes_median": np.median(passes), "timclab_warm_passes_mean": passes.mean(),
            "timclab_max_tip_error_mm": err_t.max(), "max_tip_error_mm": max(err.max(), err_t.max())}

    fixed = SolverSettings(tip_tol=None, step=3.0, angle_step=0.15)
    print(f"TIMClab robot, the fixed step of earlier versions ({rk4_step(robot_arrays(robot), fixed):.1f} mm "
          "where curved)")
    cold = bench_cold(robot, timclab_configs(args.n), fixed)
    step, warm = bench_warm(robot, sweeps, ["flush", "+15 mm", "+30 mm"], fixed)
    err_f = bench_accuracy(robot, timclab_configs(args.n_ref, seed=1), fixed)
    out |= {"timclab_3mm_cold_us": np.median(cold) * 1e6, "timclab_3mm_warm_us": np.median(step) * 1e6,
            "timclab_3mm_warm_solve_us": np.median(warm) * 1e6, "timclab_3mm_max_tip_error_mm": err_f.max()}
    print(json.dumps({k: float(f"{v:.4g}") for k, v in out.items()}
                     | {"results_sha": RESULTS.hexdigest()[:16]}))


if __name__ == "__main__":
    main()
