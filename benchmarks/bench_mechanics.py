"""Mechanics benchmark: TCM speed and accuracy on the paper robot (issue 2 goals).

    python benchmarks/bench_mechanics.py            # 1,000 cold solves, 2×721 warm steps, accuracy
    python benchmarks/bench_mechanics.py --n 200    # quicker

Prints: cold solve from the default guess (median ≤ 1 ms goal; the paper's TCM took 1.47 s a point),
warm continuation step (median ≤ 0.1 ms goal), and the tip-position deviation from a tight-tolerance
reference integration (scipy DOP853, rtol 1e-12; ≤ 1e-3 mm goal). Runs on one core.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np

from ctrkin import SolverSettings, follow, paper_robot, solve
from ctrkin.acquisition.trajectories import rotation_sweep

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from mechanics.reference_tcm import reference_tip


def random_configs(n: int, seed: int = 0) -> np.ndarray:
    """Uniform valid configurations of the paper robot: β2 ∈ [−20, 0], d = β2 − β1 ∈ [0, 20.5]."""
    rng = np.random.default_rng(seed)
    b2 = rng.uniform(-20, 0, n)
    return np.c_[rng.uniform(0, 360, n), rng.uniform(0, 360, n), b2 - rng.uniform(0, 20.5, n), b2]


def stats(t: np.ndarray) -> str:
    return (f"median {np.median(t) * 1e3:.3f} ms, p95 {np.percentile(t, 95) * 1e3:.3f} ms, "
            f"mean {t.mean() * 1e3:.3f} ± {t.std() * 1e3:.3f} ms")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=1000, help="random configurations for cold solves")
    ap.add_argument("--n-ref", type=int, default=40, help="configurations checked against the reference")
    ap.add_argument("--step", type=float, default=SolverSettings().step, help="RK4 step (mm)")
    args = ap.parse_args()
    robot = paper_robot()
    settings = SolverSettings(step=args.step)
    solve(robot, [0, 0, -10, -5], settings=settings)  # compile / load the numba cache
    follow(robot, rotation_sweep(2, 20.0, step_deg=30.0), settings=settings)

    Q = random_configs(args.n)
    times = np.empty(len(Q))
    stable = 0
    for i, q in enumerate(Q):
        t0 = time.perf_counter()
        eq = solve(robot, q, settings=settings)
        times[i] = time.perf_counter() - t0
        stable += eq.stable
    print(f"cold solve ({len(Q)} random configurations, default guess): {stats(times)}; "
          f"{stable}/{len(Q)} stable")

    step_times, warm_times = [], []
    for d in (4.0, 8.0, 12.0, 16.0, 20.0):
        Qs = rotation_sweep(2, d)
        stamps: list[float] = []

        def stamp(_t: int, stamps: list[float] = stamps) -> None:
            stamps.append(time.perf_counter())

        t0 = time.perf_counter()
        traj = follow(robot, Qs, settings=settings, progress=stamp)
        total = time.perf_counter() - t0
        step_times.extend(np.diff(stamps))
        prev = traj.equilibria[0]
        for q in Qs[1:200]:  # the public warm-start path, timed one by one
            t1 = time.perf_counter()
            prev = solve(robot, q, guess=prev, settings=settings)
            warm_times.append(time.perf_counter() - t1)
        print(f"follow, 1° sweep at d = {d:4.1f} mm ({len(Qs)} steps, {traj.n_snaps} snaps): "
              f"{total / len(Qs) * 1e3:.3f} ms per step on average, snap search included")
    print(f"warm continuation step inside follow (5 sweeps): {stats(np.array(step_times))}")
    print(f"warm solve(q, guess=previous equilibrium), 1° steps: {stats(np.array(warm_times))}")

    errs = []
    for q in random_configs(args.n_ref, seed=1):
        eq = solve(robot, q, settings=settings)
        tip, _, _ = reference_tip(robot, q, eq.x)
        errs.append(np.linalg.norm(eq.tip_position - tip))
    e = np.array(errs)
    print(f"tip position vs reference integration ({len(e)} configurations, step {args.step} mm): "
          f"max {e.max():.2e} mm, median {np.median(e):.2e} mm (goal ≤ 1e-3 mm)")


if __name__ == "__main__":
    main()
