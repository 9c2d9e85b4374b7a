"""Planning benchmark (issue 24 goal 4): random target paths, the naive plan against the planner, on
the mechanics and on the virtual robot.

    python benchmarks/bench_planning.py                 # 200 paths of 4 targets on the paper robot
    python benchmarks/bench_planning.py --paths 40      # quicker
    python benchmarks/bench_planning.py --model models/fk_branch   # + the planner with a learned snap model

Each path (seeded) starts at random joints and visits 4 targets: tips of point-wise (least-energy)
solves at a random joint walk; half the paths walk at high curved overlap with the relative rotation
α0 crossing 180° (the bistable band), the others anywhere in the workspace. So every target is the
tip of some configuration, though not always of one on the branch the robot is on.

- naive: per target, IK by point-wise solves (no history), then the straight joint line, executed
  by continuation (`ctrkin.planning.naive`): the snaps it makes are unplanned;
- planner: `ctrkin.planning.plan_path` (PlanConfig defaults: 1 mm, margin 0.25, no snaps allowed).
  Its plan is checked independently: its joints are followed again from the start on the same robot
  and the snaps counted, and the tips of that run compared with the targets;
- planner + learned (`--model FOLDER`, a snap-aware FK, lstm_mlp_branch, of the robot): the same with
  the learned snap model streamed along every route (`ctrkin.planning.learned`, defaults: a route with
  a predicted snap rejected, ≥ 5° of inner rotation left before one at every step).

Every plan (and the naive plan's legs) is then executed open loop on the virtual robot (`VirtualRobot`
of the robot, seed `--robot-seed`, its defaults: every effect at the top of its published range;
`--central` for the central values): the unplanned snaps it makes there (folds of the true robot
crossed) and the targets its true tip reaches within 1 mm. The plan is made on the nominal mechanics,
so "within 1 mm" there measures the model's error, not the planner's (no feedback: the control loop
below closes it).

Then the learned half (benchmarks/learned_loop.py, its docstring has the method; `--no-learned`
leaves it out, `--learned-quick` shrinks it): calibrated uncertainty of the learned FK and IK on the
paper robot and on the comet nylon robot (coverage of the 90 % intervals, AUROC of the
out-of-distribution score, streaming cost), and the closed-loop controller on the virtual robot
(cycles per second, steady-state tracking RMS, snaps, the stop on a tracker dropout).

Prints the tables and ends with one JSON line of the issue's keys (coverage_90: the one furthest
from 0.9 over robots and tasks; ood_auroc: the least), the learned half's figures under "learned",
the virtual robot's per method under "virtual".
"""

from __future__ import annotations

import argparse
import json
import os
import time

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np

import learned_loop  # benchmarks/, beside this file
from ctrkin import follow, paper_robot, solve
from ctrkin.inference import Kinematics
from ctrkin.planning import PlanConfig, plan_path
from ctrkin.planning.learned import LearnedSnapModel
from ctrkin.planning.naive import naive_path
from ctrkin.robots import load_robot
from ctrkin.virtual import VirtualConfig
from ctrkin.virtual.robot import VirtualRobot


def random_path(robot, rng: np.random.Generator, band: bool, k: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """Start joints (2N,) and targets (k, 3) mm: module docstring."""
    n = robot.n_tubes
    lengths = robot.lengths

    def joints(alpha1: float) -> np.ndarray:
        while True:
            q = np.zeros(2 * n)
            q[0] = alpha1
            q[1:n] = rng.uniform(-20.0, 20.0, n - 1) if not band else 0.0
            if band:                # tips nearly together: the curved sections on each other
                q[2 * n - 1] = -rng.uniform(0.0, 3.0)
                q[n:2 * n - 1] = q[2 * n - 1] - (lengths[:-1] - lengths[-1]) + rng.uniform(0.3, 1.0, n - 1)
            else:
                q[2 * n - 1] = -rng.uniform(0.0, 0.5 * lengths[-1])
                q[n:2 * n - 1] = q[2 * n - 1] - rng.uniform(0.0, lengths[0] - lengths[-1], n - 1)
            if robot.is_valid(q)[0]:
                return q

    if band:
        a0 = rng.uniform(130.0, 160.0) * rng.choice([-1, 1])
        alphas = a0 + np.sign(a0) * np.linspace(15.0, 110.0, k)   # through α0 = ±180°
    else:
        a0 = rng.uniform(-180.0, 180.0)
        alphas = a0 + np.cumsum(rng.uniform(-60.0, 60.0, k))
    start = joints(a0)
    targets = np.array([solve(robot, joints(a)).tip_position for a in alphas])
    return start, targets


def on_virtual(vr: VirtualRobot, start: np.ndarray, q: np.ndarray, at: np.ndarray, targets: np.ndarray
               ) -> tuple[int, int]:
    """Execute joints q (T, 2N) open loop on the virtual robot from rest at start: (snaps of the true
    robot, targets (K, 3) mm whose true tip at step at (K,) is within 1 mm)."""
    if len(q) == 0:
        return 0, 0
    motion, _ = vr.move(vr.rest(start), q)
    tips = motion.true_poses[at, :3]
    return int(motion.snaps.sum()), int((np.linalg.norm(tips - targets, axis=1) <= 1.0).sum())


def planned(robot, vr, start, targets, cfg, learned) -> dict:
    """The planner's row of one path (module docstring)."""
    t0 = time.perf_counter()
    plan = plan_path(robot, start, targets, config=cfg, learned=learned)
    t_plan = (time.perf_counter() - t0) / len(targets)
    check = follow(robot, plan.q)             # the plan's joints again, from the start
    reached = [t for t in plan.targets if t.reached]
    at = np.array([t.step for t in reached], int)
    got = check.tip_positions[at] if reached else np.empty((0, 3))
    goal = targets[[t.index for t in reached]] if reached else np.empty((0, 3))
    within = int((np.linalg.norm(got - goal, axis=1) <= 1.0).sum())
    v_snaps, v_within = on_virtual(vr, start, plan.q[1:], at - 1, goal)
    return dict(snaps=int(check.snaps.sum()), within=within, margin=float(plan.margin.min()),
                median_margin=float(np.median(plan.margin)), seconds=t_plan,
                unreachable=len(targets) - len(reached),
                offers=sum(t.offer is not None for t in plan.targets if not t.reached),
                v_snaps=v_snaps, v_within=v_within,
                learned_snaps=None if plan.learned is None else int(plan.learned.snap.sum()),
                learned_margin=None if plan.learned is None else float(plan.learned.margin_deg.min()))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--paths", type=int, default=200)
    ap.add_argument("--targets", type=int, default=4, help="targets per path")
    ap.add_argument("--robot", default="paper")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--robot-seed", type=int, default=0, help="the virtual robot's draw")
    ap.add_argument("--central", action="store_true",
                    help="the virtual robot at the central values (VirtualConfig().central())")
    ap.add_argument("--model", default=None,
                    help="a snap-aware FK folder of the robot: adds the planner with the learned snap model")
    ap.add_argument("--no-learned", action="store_true", help="leave out uncertainty and control")
    ap.add_argument("--learned-quick", action="store_true", help="fewer walks, shorter training and loop")
    args = ap.parse_args()
    robot = paper_robot() if args.robot == "paper" else load_robot(args.robot)
    vcfg = VirtualConfig().central() if args.central else VirtualConfig()
    vr = VirtualRobot(robot, vcfg, seed=args.robot_seed)
    kin = None
    if args.model:
        kin = Kinematics.load(args.model)
        kin.check_robot(robot)
    rng = np.random.default_rng(args.seed)
    cfg = PlanConfig()
    rows: dict[str, list[dict]] = {"naive": [], "planner": []}
    if kin is not None:
        rows["planner + learned"] = []
    for p in range(args.paths):
        band = p % 2 == 0
        start, targets = random_path(robot, rng, band, args.targets)
        t0 = time.perf_counter()
        legs = naive_path(robot, start, targets, config=cfg)
        t_naive = (time.perf_counter() - t0) / len(targets)
        naive_err = np.array([np.linalg.norm(leg.tips[-1] - g) for leg, g in zip(legs, targets, strict=True)])
        ends = np.cumsum([len(leg.q) for leg in legs]) - 1
        v_snaps, v_within = on_virtual(vr, start, np.concatenate([leg.q for leg in legs]), ends, targets)
        rows["naive"].append(dict(
            band=band, snaps=sum(int(leg.snaps.sum()) for leg in legs), within=int((naive_err <= 1.0).sum()),
            margin=min(float(leg.margin.min()) for leg in legs),
            median_margin=float(np.median(np.concatenate([leg.margin for leg in legs]))), seconds=t_naive,
            v_snaps=v_snaps, v_within=v_within))
        rows["planner"].append(dict(band=band, **planned(robot, vr, start, targets, cfg, None)))
        if kin is not None:
            rows["planner + learned"].append(dict(band=band, **planned(robot, vr, start, targets, cfg,
                                                                       LearnedSnapModel(kin))))
        print(f"path {p:3d} ({'band' if band else 'free'}): " + "; ".join(
            f"{name} {r[-1]['snaps']} snaps {r[-1]['within']}/{len(targets)}, virtual "
            f"{r[-1]['v_snaps']} snaps {r[-1]['v_within']}/{len(targets)}" for name, r in rows.items()),
              flush=True)
    n_t = args.paths * args.targets
    print(f"\n{args.paths} paths x {args.targets} targets on the {robot.name} robot, seed {args.seed} "
          f"(half through the bistable band); within = tip within 1 mm on the robot planned for (nominal "
          f"mechanics); virtual: executed open loop on the virtual robot (robot seed {args.robot_seed}, "
          f"{'central values' if args.central else 'defaults: every effect at the top of its range'})")
    print(f"{'':18s} {'unplanned snaps':>16s} {'within 1 mm':>12s} {'least margin':>13s} "
          f"{'median margin':>14s} {'s / target':>11s} {'virtual snaps':>14s} {'virtual 1 mm':>13s}")
    out = {}
    for name, rs in rows.items():
        snaps = sum(r["snaps"] for r in rs)
        within = sum(r["within"] for r in rs) / n_t
        least = min(r["margin"] for r in rs)
        med = float(np.median([r["median_margin"] for r in rs]))
        sec = float(np.median([r["seconds"] for r in rs]))
        v_snaps = sum(r["v_snaps"] for r in rs)
        v_within = sum(r["v_within"] for r in rs) / n_t
        print(f"{name:18s} {snaps:16d} {within:12.3f} {least:13.3f} {med:14.3f} {sec:11.3f} {v_snaps:14d} "
              f"{v_within:13.3f}")
        out[name] = dict(snaps=snaps, within=within, least=least, sec=sec, v_snaps=v_snaps, v_within=v_within)
        for part, sel in (("band", True), ("free", False)):
            sub = [r for r in rs if r["band"] == sel]
            if sub:
                print(f"  {part:16s} {sum(r['snaps'] for r in sub):16d} "
                      f"{sum(r['within'] for r in sub) / (len(sub) * args.targets):12.3f} {'':41s} "
                      f"{sum(r['v_snaps'] for r in sub):14d} "
                      f"{sum(r['v_within'] for r in sub) / (len(sub) * args.targets):13.3f}")
    for name in [n for n in rows if n != "naive"]:
        unreach = sum(r["unreachable"] for r in rows[name])
        offers = sum(r["offers"] for r in rows[name])
        print(f"{name}: {unreach} targets reported unreachable on the current branch ({offers} with a "
              f"deliberate snap offered)")
        out[name]["unreachable"] = unreach
    if kin is not None:
        lr = rows["planner + learned"]
        out["planner + learned"]["learned_snaps"] = sum(r["learned_snaps"] for r in lr)
        out["planner + learned"]["learned_margin"] = min(r["learned_margin"] for r in lr)
        print(f"planner + learned: {out['planner + learned']['learned_snaps']} snaps predicted by the model "
              f"on its plans, least learned margin {out['planner + learned']['learned_margin']:.1f} deg")
    learned: dict = {}
    keys = dict.fromkeys(("control_hz", "tracking_rmse_mm", "coverage_90", "ood_auroc"))
    if not args.no_learned:
        learned = learned_loop.run(args.learned_quick, args.seed)
        print()
        learned_loop.print_table(learned)
        keys = learned_loop.summary(learned)
    lp = out.get("planner + learned", {})
    print(json.dumps({
        "unplanned_snaps_naive": out["naive"]["snaps"], "unplanned_snaps_planner": out["planner"]["snaps"],
        "within_1mm_fraction": out["planner"]["within"], "within_1mm_fraction_naive": out["naive"]["within"],
        "least_margin_planner": out["planner"]["least"], "least_margin_naive": out["naive"]["least"],
        "planning_s_per_target": out["planner"]["sec"], "unreachable_reported": out["planner"]["unreachable"],
        "unplanned_snaps_learned_planner": lp.get("snaps"),
        "within_1mm_fraction_learned_planner": lp.get("within"),
        "planning_s_per_target_learned": lp.get("sec"), "unreachable_reported_learned": lp.get("unreachable"),
        "learned_least_margin_deg": lp.get("learned_margin"),
        "virtual": {name: {"unplanned_snaps": o["v_snaps"], "within_1mm_fraction": o["v_within"]}
                    for name, o in out.items()},
        "virtual_robot": "central" if args.central else "defaults", "robot_seed": args.robot_seed,
        "paths": args.paths, "targets": n_t, **keys, "learned": learned}))


if __name__ == "__main__":
    main()
