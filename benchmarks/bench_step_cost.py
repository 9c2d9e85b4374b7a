"""Benchmark: what one step of the virtual robot costs on a robot and effect mix (issue 21, goal 4:
the three-tube row; docs/reproduction.md: Other robots).

    python benchmarks/bench_step_cost.py --case three-tube --segments 8
    python benchmarks/bench_step_cost.py --case three-tube --segments 8 --set presliding_mm=0.0002   # slow
    python benchmarks/bench_step_cost.py --case three-tube-central --runs 4
    python benchmarks/bench_step_cost.py --case default-top --set tube_friction=0.2

A case is one of bench_generalisation's robots and effect mixes (its `ROBOTS`: the robot, its hardware
seed and its `--set` effects); `--set KEY=VALUE` overrides an effect on top. The first `--runs` runs
of the quick paper protocol are driven through `VirtualRobot.move` one segment at a time, in this
process on one core, the kernels compiled (or loaded from the numba cache) before the clock starts.
Prints a row per run (steps, seconds, µs a step, the steps whose continuation `follow` gave up and
`move` solved again, the snaps) and the spread of the segments' cost, then one JSON line:
`us_per_step`, `given_up_share`, `steps`, `segments`, `wall_s`, `segment_us_p50/p90/max`. A step that follow
gives up spends its whole continuation budget (SolverSettings.max_search_steps) before it is solved
again, so `given_up_share` is where the time goes when a robot records slowly.

`--path moving` drives instead one path of `--steps` steps on which every joint moves each step, as a
follow IK's answers do (`moving_path`: each α drifts 0.5° a step with 0.2° of seeded noise, each β
follows a slow sine through the quick protocol's range of it with 0.002 mm of noise, projected onto
the robot's stops): the translating steps with friction that the protocol's sweeps seldom take.

`--against KEY=VALUE` (repeatable) drives the same segments a second time on the same hardware draw
with those effects changed too, and adds how far its true tip is from the first one's (RMS, 99th
percentile and largest, mm) and what its steps cost: `against`, `against_us_per_step`,
`against_given_up_share`, `tip_diff_rms_mm`, `tip_diff_p99_mm`, `tip_diff_max_mm`. It measures what an
effect that is also a numerical setting (presliding_mm) changes in the robot's motion:

    python benchmarks/bench_step_cost.py --case default-top --runs 4 --set presliding_mm=0.0002 \
        --against presliding_mm=0.002
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

from ctrkin.acquisition import protocols
from ctrkin.cli.from_config import parse_key_values
from ctrkin.virtual import VirtualConfig, VirtualRobot

sys.path.insert(0, str(Path(__file__).resolve().parent))   # the benchmark beside this one
from bench_generalisation import ROBOTS, _robot


def _drive(virtual: VirtualRobot, runs: list, n_segments: int | None
           ) -> tuple[list[float], list[tuple[int, float, int, int]], np.ndarray]:
    """Drive runs (their first n_segments segments) one segment at a time: each segment's µs a
    step, per run (steps, seconds, given-up steps, snaps), and the true tip positions (T, 3). The
    kernels are compiled (or loaded from the numba cache) before the clock starts."""
    virtual.move(virtual.rest(runs[0].start), runs[0].segments[0].q[:2])
    seg_cost, per_run, tips = [], [], []
    for run in runs:
        state = virtual.rest(run.start)
        steps, wall, given_up, snaps = 0, 0.0, 0, 0
        for seg in run.segments[:n_segments]:
            t0 = time.perf_counter()
            motion, state = virtual.move(state, seg.q)
            dt = time.perf_counter() - t0
            seg_cost.append(1e6 * dt / seg.q.shape[0])
            steps += seg.q.shape[0]
            wall += dt
            given_up += int(motion.given_up.sum())
            snaps += int(motion.snaps.sum())
            tips.append(motion.true_poses[:, :3])
        per_run.append((steps, wall, given_up, snaps))
    return seg_cost, per_run, np.concatenate(tips)


MOVING_SEED = 0


def _case_robot(name: str, overrides: dict) -> tuple:
    """Case `name` of bench_generalisation, its nominal robot, its effects updated by `overrides` and
    the virtual robot of them on its hardware draw."""
    case = ROBOTS[name]
    robot = _robot(case)
    effects = {**case.settings, **overrides}
    return case, robot, effects, VirtualRobot(robot, dataclasses.replace(VirtualConfig(), **effects),
                                              seed=case.seed)


def moving_path(robot, plan, steps: int, seed: int = MOVING_SEED) -> np.ndarray:
    """(steps, 2N) joints on which every joint moves each step (module docstring): from the first run's
    start, α drifting 0.5 ± 0.2° a step, β_i on a sine of period 2π·(300, 170, 230, …)[i] steps across
    the middle 80 % of the protocol's range of β_i, with 0.002 mm of noise; projected onto the stops."""
    rng = np.random.default_rng(seed)
    n = robot.n_tubes
    q0 = plan.runs[0].start
    Q = np.concatenate([seg.q for run in plan.runs for seg in run.segments])
    lo, hi = Q[:, n:].min(axis=0), Q[:, n:].max(axis=0)
    t = np.arange(steps)[:, None]
    periods = np.array([300.0, 170.0, 230.0, 190.0, 260.0])[:n]
    out = np.empty((steps, 2 * n))
    out[:, :n] = q0[:n] + np.cumsum(0.5 + 0.2 * rng.standard_normal((steps, n)), axis=0)
    out[:, n:] = ((lo + hi) / 2 + 0.4 * (hi - lo) * np.sin(t / periods)
                  + 0.002 * rng.standard_normal((steps, n)))
    return robot.project_joints(out)


def moving_cost(name: str, overrides: dict, steps: int, repeats: int = 3) -> dict:
    """Drive moving_path (steps) on case `name` from rest at its first row, in one move, `repeats`
    times; print the rows and return the figures (the median drive's; the first 50 steps driven
    before the clock starts, to load the kernels)."""
    case, robot, effects, virtual = _case_robot(name, overrides)
    Q = moving_path(robot, protocols.build("paper", robot, scale="quick", seed=0), steps)
    state = virtual.rest(Q[0])
    virtual.move(state, Q[:50])
    walls = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        motion, _ = virtual.move(state, Q)
        walls.append(time.perf_counter() - t0)
    wall = float(np.median(walls))
    digest = hashlib.sha256(np.ascontiguousarray(motion.true_poses).tobytes()).hexdigest()[:16]
    figures = {"case": name, "path": "moving", "effects": effects, "steps": steps, "wall_s": round(wall, 3),
               "us_per_step": round(1e6 * wall / steps, 1), "repeats": repeats,
               "us_per_step_min": round(1e6 * min(walls) / steps, 1), "load": round(os.getloadavg()[0], 2),
               "given_up_share": round(float(motion.given_up.mean()), 4), "snaps": int(motion.snaps.sum()),
               "tip_digest": digest}
    print(f"{name}: {robot.name}, {robot.n_tubes} tubes, hardware seed {case.seed}, tube_friction "
          f"{virtual.config.tube_friction}; a moving path of {steps} steps (every joint each step)")
    print(f"{'steps':>7} {'s':>8} {'µs/step':>9} {'given up':>9} {'snaps':>6}  tips (median of {repeats} "
          f"drives; fastest {figures['us_per_step_min']:.0f} µs a step; load {figures['load']})")
    print(f"{steps:>7} {wall:>8.2f} {figures['us_per_step']:>9.0f} {int(motion.given_up.sum()):>9} "
          f"{figures['snaps']:>6}  {figures['tip_digest']}")
    print(json.dumps(figures))
    return figures


def step_cost(name: str, overrides: dict, n_runs: int, n_segments: int | None,
              against: dict | None = None) -> dict:
    """Drive the first n_runs runs (their first n_segments segments) of the quick paper protocol on
    case `name` with its effects updated by `overrides`; print the table and return the figures.
    against: effects changed on top for a second drive of the same segments on the same hardware
    draw (the tip difference and its cost are added)."""
    case, robot, effects, virtual = _case_robot(name, overrides)
    plan = protocols.build("paper", robot, scale="quick", seed=0)
    runs = plan.runs[:n_runs]
    print(f"{name}: {robot.name}, {robot.n_tubes} tubes, hardware seed {case.seed}, "
          f"tube_friction {virtual.config.tube_friction}; {len(runs)} of {len(plan.runs)} quick runs")
    print(f"{'run':>4} {'steps':>7} {'s':>8} {'µs/step':>9} {'given up':>9} {'snaps':>6}")
    seg_cost, per_run, tips = _drive(virtual, runs, n_segments)
    for i, (steps, wall, given_up, snaps) in enumerate(per_run):
        print(f"{i:>4} {steps:>7} {wall:>8.1f} {1e6 * wall / steps:>9.0f} {given_up:>9} {snaps:>6}")
    total_steps = sum(r[0] for r in per_run)
    total_s = sum(r[1] for r in per_run)
    total_given_up = sum(r[2] for r in per_run)
    p50, p90, top = np.percentile(seg_cost, [50, 90, 100])
    print(f"segments' µs a step: median {p50:.0f}, 90th percentile {p90:.0f}, largest {top:.0f} "
          f"({len(seg_cost)} segments)")
    figures = {"case": name, "effects": effects, "runs": len(runs), "segments": len(seg_cost),
               "steps": total_steps, "wall_s": round(total_s, 2),
               "us_per_step": round(1e6 * total_s / total_steps, 1),
               "given_up_share": round(total_given_up / total_steps, 4),
               "segment_us_p50": round(float(p50), 1), "segment_us_p90": round(float(p90), 1),
               "segment_us_max": round(float(top), 1)}
    if against:
        other = VirtualRobot(robot, dataclasses.replace(virtual.config, **against), seed=case.seed)
        _, other_runs, other_tips = _drive(other, runs, n_segments)
        d = np.linalg.norm(other_tips - tips, axis=1)
        figures.update({
            "against": against,
            "against_us_per_step": round(1e6 * sum(r[1] for r in other_runs) / total_steps, 1),
            "against_given_up_share": round(sum(r[2] for r in other_runs) / total_steps, 4),
            "tip_diff_rms_mm": round(float(np.sqrt(np.mean(d * d))), 4),
            "tip_diff_p99_mm": round(float(np.percentile(d, 99)), 4),
            "tip_diff_max_mm": round(float(d.max()), 4)})
        print(f"against {against}: {figures['against_us_per_step']:.0f} µs a step, "
              f"{figures['against_given_up_share']:.1%} given up; true tip "
              f"{figures['tip_diff_rms_mm']:.3f} mm RMS (99th percentile {figures['tip_diff_p99_mm']:.3f}, "
              f"largest {figures['tip_diff_max_mm']:.3f} mm) from the case's")
    print(json.dumps(figures))
    return figures


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--case", choices=list(ROBOTS), default="three-tube",
                    help="a robot and effect mix of bench_generalisation (default three-tube)")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="override an effect of the case (VirtualConfig's keys; repeatable)")
    ap.add_argument("--runs", type=int, default=1, help="runs of the quick paper protocol (default 1); with "
                    "--path moving, drives of the path (the median is reported; give 3 or more)")
    ap.add_argument("--segments", type=int, default=None,
                    help="only the first K segments of each run (default all; a run of the quick "
                    "protocol has 35)")
    ap.add_argument("--against", action="append", default=[], metavar="KEY=VALUE",
                    help="drive the same segments again with these effects changed too (repeatable) "
                    "and print how far the true tip moves")
    ap.add_argument("--path", choices=("protocol", "moving"), default="protocol",
                    help="protocol: the quick paper protocol's runs (default); moving: one path on which "
                    "every joint moves each step (moving_path)")
    ap.add_argument("--steps", type=int, default=3000, help="steps of --path moving (default 3000)")
    args = ap.parse_args()
    if args.runs < 1 or (args.segments is not None and args.segments < 1) or args.steps < 4:
        ap.error("--runs and --segments must be >= 1, --steps >= 4")
    if args.path == "moving":
        if args.against:
            ap.error("--against drives the protocol's segments: use it with --path protocol")
        moving_cost(args.case, parse_key_values(args.set, "--set", VirtualConfig), args.steps, args.runs)
        return 0
    step_cost(args.case, parse_key_values(args.set, "--set", VirtualConfig), args.runs, args.segments,
              parse_key_values(args.against, "--against", VirtualConfig) or None)
    return 0


if __name__ == "__main__":
    sys.exit(main())
