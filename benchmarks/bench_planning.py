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
so "within 1 mm" there measures the model's error, not the planner's.

Then the planner's plans are driven on the virtual robot again, with tracker feedback
(`ctrkin.control.plan_feedback`: at each target corrections from its tracker, every step checked on
the model like a route; tracker noise seeded per path): "within 1 mm" there is the true tip as the
tracker sees it without noise (its frame, its sensor point, its field: the frame the feedback, like
the control loop, closes in), the unplanned snaps of the true robot, and the correction steps per
target. Reachability, the stated rule: a target counts as reachable when (a) the planner reached it
on its model (not reported unreachable on the current branch) and (b) the virtual robot's true tubes
have a stable equilibrium its tracker sees within 1 mm of it: shown by the feedback reaching it, else
searched (`seen_reachable`: the history-free IK on the true mechanics from the plan's joints, the
feedback's last joints and the 3 configurations of a dense sample of 3,000 seen nearest; a local
search, so its "unreachable" is not a proof). within_1mm_fraction is over the reachable targets;
the fraction over all targets and over those the planner reached are printed beside it.

Then the learned half (benchmarks/learned_loop.py, its docstring has the method; `--no-learned`
leaves it out, `--learned-quick` shrinks it): calibrated uncertainty of the learned FK and IK on the
paper robot and on the comet nylon robot (coverage of the 90 % intervals, AUROC of the
out-of-distribution score, streaming cost), and the closed-loop controller on the virtual robot
(cycles per second, steady-state tracking RMS, snaps, the stop on a tracker dropout).

Prints the tables and ends with one JSON line of the issue's keys (within_1mm_fraction: the planner
with feedback on the virtual robot, over the reachable targets; within_1mm_fraction_nominal: the
planner on its own model, all targets; coverage_90: the one furthest
from 0.9 over robots and tasks; ood_auroc: the least over robots, FK and IK), the learned half's
figures under "learned", the virtual robot's per method under "virtual".
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
from ctrkin.control.plan_feedback import execute_plan
from ctrkin.control.virtual_loop import VirtualRig
from ctrkin.inference import Kinematics
from ctrkin.planning import PlanConfig, plan_path
from ctrkin.planning.ik import branch_ik
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


def seen_sample(vr: VirtualRobot, rng: np.random.Generator, n: int = 3000) -> tuple[np.ndarray, np.ndarray]:
    """A dense sample of the virtual robot's configurations: n random tube-base joints (n, 2N) (every
    rotation, the outer tube out by at least 40 % of its length, each inner one anywhere between
    retracted into the next and its stop) of its true tubes, point-wise solved, and their tips as its
    tracker sees them without noise (n, 3) mm; rows that did not converge are dropped."""
    true = vr.true_robot
    nt = true.n_tubes
    q = np.zeros((n, 2 * nt))
    q[:, :nt] = rng.uniform(0.0, 360.0, (n, nt))
    q[:, 2 * nt - 1] = -rng.uniform(0.0, 0.6, n) * true.lengths[-1]
    for i in range(nt - 2, -1, -1):
        q[:, nt + i] = q[:, nt + i + 1] - rng.uniform(0.0, 1.0, n) * (true.lengths[i] - true.lengths[i + 1])
    q = true.project_joints(q)
    eqs = [solve(true, row) for row in q]
    ok = np.array([e.stable for e in eqs])
    poses = np.array([e.tip_pose for e in eqs])
    return q[ok], vr.tracker.registered(poses[ok])[:, :3]


def seen_reachable(vr: VirtualRobot, target: np.ndarray, seeds: list[np.ndarray], cfg: PlanConfig,
                   sample: tuple[np.ndarray, np.ndarray], tol: float = 1.0) -> bool:
    """The reachability rule on the virtual robot (an oracle: it uses the simulator's truth): some
    stable equilibrium of its true tubes is seen by its tracker (noise-free: registration, sensor
    point, field) within tol mm of target (3,). Search: the history-free IK (planning.ik, any stable
    branch) on the true mechanics, its goal moved by what the tracker view still misses (4 rounds),
    from each seed's tube-base joints (2N,) and from the 3 configurations of the dense sample
    (`seen_sample`) seen nearest the target."""
    true = vr.true_robot
    limits = cfg.limits(true)
    near = np.argsort(np.linalg.norm(sample[1] - target, axis=1))[:3]
    for q in [*seeds, *sample[0][near]]:
        goal = np.array(target, float)
        eq = solve(true, true.project_joints(q[None])[0])
        for _ in range(4):
            sol = branch_ik(true, eq, goal, limits, None, 0.0, max_iter=30, history=False)
            miss = target - vr.tracker.registered(sol.equilibrium.tip_pose[None, :])[0, :3]
            if np.linalg.norm(miss) <= tol:
                return True
            goal, eq = goal + miss, sol.equilibrium
    return False


def with_feedback(robot, vr, plan, start, targets, cfg, seed, sample) -> dict:
    """The plan driven on the virtual robot with tracker feedback at every reached target
    (control.plan_feedback): per target the tracker-view error (noise-free), the reachability rule
    (`seen_reachable`, only where the feedback did not show it by reaching), correction steps; the
    true robot's snaps."""
    t0 = time.perf_counter()
    rig = VirtualRig(vr, start, seed=seed)
    ex = execute_plan(robot, plan, targets, rig, config=cfg)
    seconds = time.perf_counter() - t0
    poses = rig.true_poses
    n = robot.n_tubes
    err = np.full(len(targets), np.inf)
    reachable = np.zeros(len(targets), bool)
    for t in plan.targets:
        if not t.reached:
            continue               # not reachable on the branch, by the planner's report: not counted
        k = t.index
        if ex.at[k] >= 0:
            err[k] = float(np.linalg.norm(rig.seen(poses[ex.at[k]][None, :])[0] - targets[k]))
        if err[k] <= 1.0:
            reachable[k] = True
        else:
            seeds = [plan.q[t.step]] + ([ex.q[ex.at[k]]] if ex.at[k] >= 0 else [])
            seeds = [np.r_[q[:n] + vr.alpha_offset, q[n:]] for q in seeds]
            reachable[k] = seen_reachable(vr, targets[k], seeds, cfg, sample)
    return dict(fb_within=int((err <= 1.0).sum()), fb_reachable=int(reachable.sum()),
                fb_within_reachable=int(((err <= 1.0) & reachable).sum()),
                fb_snaps=int(rig.snaps.sum()), fb_steps=ex.steps[ex.at >= 0].tolist(),
                fb_refused=int(ex.refused.sum()), fb_seconds=seconds,
                fb_errors=err[np.isfinite(err)].tolist())


def planned(robot, vr, start, targets, cfg, learned, feedback_seed: int | None = None,
            sample: tuple[np.ndarray, np.ndarray] | None = None) -> dict:
    """The planner's row of one path (module docstring); with feedback_seed also driven with
    tracker feedback (its tracker noise drawn from that seed)."""
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
    fb = ({} if feedback_seed is None or sample is None else
          with_feedback(robot, vr, plan, start, targets, cfg, feedback_seed, sample))
    return dict(**fb, n_reached=len(reached), snaps=int(check.snaps.sum()), within=within,
                margin=float(plan.margin.min()),
                median_margin=float(np.median(plan.margin)), seconds=t_plan,
                unreachable=len(targets) - len(reached),
                offers=sum(t.offer is not None for t in plan.targets if not t.reached),
                v_snaps=v_snaps, v_within=v_within,
                learned_snaps=None if plan.learned is None else int(plan.learned.snap.sum()),
                learned_margin=None if plan.learned is None else float(plan.learned.margin_deg.min()))


def feedback_summary(rs: list[dict], n_t: int) -> dict:
    """The planner's plans driven with tracker feedback, over every path."""
    steps = np.concatenate([r["fb_steps"] for r in rs]) if rs else np.empty(0)
    errs = np.concatenate([r["fb_errors"] for r in rs]) if rs else np.empty(0)
    reach = sum(r["fb_reachable"] for r in rs)
    driven = sum(r["n_reached"] for r in rs)
    return dict(within_raw=sum(r["fb_within"] for r in rs) / n_t,
                within_reachable=sum(r["fb_within_reachable"] for r in rs) / max(reach, 1),
                within_planned=sum(r["fb_within"] for r in rs) / max(sum(r["n_reached"] for r in rs), 1),
                reachable=reach, planner_reached=driven, unreachable_branch=n_t - driven,
                unreachable_virtual=driven - reach, snaps=sum(r["fb_snaps"] for r in rs),
                steps_mean=float(steps.mean()) if len(steps) else 0.0,
                steps_median=float(np.median(steps)) if len(steps) else 0.0,
                steps_max=int(steps.max()) if len(steps) else 0,
                refused=sum(r["fb_refused"] for r in rs),
                error_median_mm=float(np.median(errs)) if len(errs) else float("nan"),
                seconds_per_target=sum(r["fb_seconds"] for r in rs) / max(driven, 1))


def print_feedback(fb: dict, n_t: int) -> None:
    print("\nplanner, driven on the virtual robot with tracker feedback (control.plan_feedback; errors as "
          "its tracker sees the true tip without noise):")
    print(f"  reachable: {fb['reachable']} of {n_t} targets ({fb['unreachable_branch']} reported not "
          f"reachable on the current branch by the planner; {fb['unreachable_virtual']} the virtual "
          f"robot's tubes cannot put within 1 mm of them as its tracker sees them)")
    print(f"  within 1 mm: {fb['within_reachable']:.3f} of the reachable, {fb['within_planned']:.3f} of "
          f"those the planner reached on its model, {fb['within_raw']:.3f} of all; "
          f"median error {fb['error_median_mm']:.2f} mm; unplanned snaps {fb['snaps']}")
    print(f"  correction steps per target: mean {fb['steps_mean']:.2f}, median {fb['steps_median']:.0f}, "
          f"max {fb['steps_max']}; {fb['refused']} targets left where no safe step remained; "
          f"{fb['seconds_per_target']:.2f} s per target (simulation included)")


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
    sample = seen_sample(vr, np.random.default_rng([args.seed, 0x5A3]))
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
        rows["planner"].append(dict(band=band, **planned(robot, vr, start, targets, cfg, None,
                                                          feedback_seed=args.seed * 100_003 + p,
                                                          sample=sample)))
        if kin is not None:
            rows["planner + learned"].append(dict(band=band, **planned(robot, vr, start, targets, cfg,
                                                                       LearnedSnapModel(kin))))
        print(f"path {p:3d} ({'band' if band else 'free'}): " + "; ".join(
            f"{name} {r[-1]['snaps']} snaps {r[-1]['within']}/{len(targets)}, virtual "
            f"{r[-1]['v_snaps']} snaps {r[-1]['v_within']}/{len(targets)}" for name, r in rows.items())
              + f"; feedback {rows['planner'][-1]['fb_snaps']} snaps "
                f"{rows['planner'][-1]['fb_within']}/{len(targets)}", flush=True)
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
    fb = feedback_summary(rows["planner"], n_t)
    print_feedback(fb, n_t)
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
        "within_1mm_fraction": fb["within_reachable"], "within_1mm_fraction_raw": fb["within_raw"],
        "within_1mm_fraction_planner_reached": fb["within_planned"],
        "within_1mm_fraction_nominal": out["planner"]["within"],
        "within_1mm_fraction_naive": out["naive"]["within"],
        "reachable_targets": fb["reachable"], "unreachable_on_branch": fb["unreachable_branch"],
        "unreachable_on_virtual": fb["unreachable_virtual"],
        "unplanned_snaps_feedback": fb["snaps"], "correction_steps_mean": fb["steps_mean"],
        "correction_steps_max": fb["steps_max"],
        "least_margin_planner": out["planner"]["least"], "least_margin_naive": out["naive"]["least"],
        "planning_s_per_target": out["planner"]["sec"], "unreachable_reported": out["planner"]["unreachable"],
        "unplanned_snaps_learned_planner": lp.get("snaps"),
        "within_1mm_fraction_learned_planner": lp.get("within"),
        "planning_s_per_target_learned": lp.get("sec"), "unreachable_reported_learned": lp.get("unreachable"),
        "learned_least_margin_deg": lp.get("learned_margin"),
        "virtual": {name: {"unplanned_snaps": o["v_snaps"], "within_1mm_fraction": o["v_within"]}
                    for name, o in out.items()}
                   | {"planner, feedback": {"unplanned_snaps": fb["snaps"],
                                            "within_1mm_fraction": fb["within_reachable"],
                                            "within_1mm_fraction_raw": fb["within_raw"]}},
        "virtual_robot": "central" if args.central else "defaults", "robot_seed": args.robot_seed,
        "paths": args.paths, "targets": n_t, **keys, "learned": learned}))


if __name__ == "__main__":
    main()
