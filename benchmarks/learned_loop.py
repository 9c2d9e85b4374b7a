"""The learned half of the planning benchmark (issue 24, goals 2 and 3), imported by bench_planning.py
(`--learned`), or alone:

    python benchmarks/learned_loop.py                  # paper robot and the comet nylon robot
    python benchmarks/learned_loop.py --quick          # fewer walks, shorter training and loop
    python benchmarks/learned_loop.py --quick --robot paper --keep DIR   # one robot; keep the models
    python benchmarks/learned_loop.py --quick --robot examples/robots/comet_nylon_ndi.toml

This is bench_planning.py's goal-2 part alone (coverage, OOD AUROC, streaming cost, and the control
loop): the same figures and JSON keys without the planning paths.

Data: random joint walks on the virtual robot (friction, backlash, true tubes, tracker noise and
registration), recorded as a dataset (measured poses in the tracker frame, true poses beside them).
A walk starts at random joints of a region and moves every joint each step (α up to 3°, β up to
0.15 mm a step, momentum 0.8, reflected at the region's edges). The training region: d from the
robot's curved-overlap onset to 60 % of the way to full overlap, the outer tube retracted 0-5 mm,
less the corner d in the region's top third with the outer tube retracted more than half (held back
for the "unseen combination" test).

Walks: 60 of 150 steps to train on (24 of 120 with --quick); held-out and OOD walks are shorter and
more (120 of 50 steps held out, 30 of each OOD kind; --quick 48 and 12 of 40), so that a half of them
holds many independent stretches of the region (rows of one walk are correlated).

- Uncertainty: the paper's LSTM-MLP FK and IK (L64|D64, IB 2, batch 128, lr 2e-3; the FK in the
  outer tube's frame with the phase angle encoding) trained on the training walks (their own
  by-sequence split), then calibrated (ctrkin.inference.uncertainty) on half of a separate set of
  held-out walks and tested on the other half, over 200 random halvings: mean coverage of the 90 %
  intervals (FK tip ball, IK joint box). OOD: AUROC of the OOD score, held-out in-range rows against
  rows of walks (a) beyond the trained d range (15-35 % of its span above it: joint ranges),
  (b) in the held-back corner (each joint within its trained range: unseen combinations),
  (c) in the region with 4× larger steps, and with the rotation reversing every step (unseen
  histories). The IK's score takes the target pose and the robot's joints when it was asked (the
  recorded joints of the row before; ctrkin.models.ood). Streaming cost: Kinematics.step against
  step_uncertain on a held-out walk (the IK's joints: its own previous answers), alternating blocks,
  medians.
- Control (on every robot; the goal keys are the first robot's): ctrkin.control.Controller on the
  FK, closed around the same virtual robot (another seed of tracker noise): a 2 mm-radius circle at
  4 s a turn (3.1 mm/s) from a start in the robot's own training region (α0 = 0°, the curvatures
  aligned, furthest from the bistable band about 180°; d and the outer retraction in the middle of
  the robot's ranges, `regions`: no joint at a stop). At α0 = 90°, the start before, the comet nylon
  robot's true tubes had no equilibrium at all 15 cycles in (VirtualRobot.move leaves the step NaN,
  and the next move refuses to continue from it: ConvergenceError),
  steady-state RMS of the true tip (as the tracker sees it without noise) against the target after the
  first quarter, snaps of the true robot, the controller's cycles per second, and the stop when the
  tracker drops out.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ctrkin.acquisition.ranges import ProtocolRanges
from ctrkin.data.dataset import Dataset
from ctrkin.data.schema import POSE_COLUMNS, TRUE_POSE_COLUMNS
from ctrkin.robots import load_robot, paper_robot
from ctrkin.robots.robot import Robot
from ctrkin.virtual.robot import VirtualRobot

ROBOTS = ("paper", "examples/robots/comet_nylon_ndi.toml")


def regions(robot: Robot) -> dict[str, dict[str, Any]]:
    """The walks' regions (module docstring): d range (mm), outer retraction range (mm), step scale,
    and whether steps reverse every time (jitter)."""
    r = ProtocolRanges.of(robot)
    lo, hi = r.onset_mm, r.onset_mm + 0.6 * (r.full_mm - r.onset_mm)
    span = hi - lo
    out_hi = min(hi + 0.35 * span, r.reach_mm)
    corner = (hi - span / 3, hi)
    return {
        "train": dict(d=(lo, hi), ret=(0.0, 5.0), scale=1.0, jitter=False, exclude=corner),
        "range": dict(d=(hi + 0.15 * span, out_hi), ret=(0.0, 5.0), scale=1.0, jitter=False, exclude=None),
        "combination": dict(d=corner, ret=(2.5, 5.0), scale=1.0, jitter=False, exclude=None),
        "steps": dict(d=(lo, hi), ret=(0.0, 5.0), scale=4.0, jitter=False, exclude=corner),
        "reversals": dict(d=(lo, hi), ret=(0.0, 5.0), scale=1.0, jitter=True, exclude=corner),
    }


def walk(robot: Robot, rng: np.random.Generator, steps: int, d: tuple[float, float], ret: tuple[float, float],
         scale: float, jitter: bool, exclude: tuple[float, float] | None) -> np.ndarray:
    """One random joint walk (steps, 2N) in a region (module docstring); N = 2 or more (the middle
    tubes move with the outer one, as in the paper's protocols)."""
    n = robot.n_tubes
    amax = np.array([3.0, 3.0, 0.15, 0.15]) * scale

    def inside(dd: float, rr: float) -> bool:
        return not (exclude is not None and exclude[0] <= dd <= exclude[1] and rr > 2.5)

    while True:
        x = np.array([rng.uniform(-180, 180), rng.uniform(-180, 180), rng.uniform(*d), rng.uniform(*ret)])
        if inside(x[2], x[3]):
            break
    v = np.zeros(4)
    rows = []
    for t in range(steps):
        v = 0.8 * v + 0.2 * rng.uniform(-1, 1, 4) * amax
        if jitter:
            v[0] = amax[0] * (1 if t % 2 else -1)
        nxt = x + v
        for j, (a, b) in ((2, d), (3, ret)):
            if not a <= nxt[j] <= b:
                v[j] = -v[j]
                nxt[j] = x[j] + v[j]
        if not inside(nxt[2], nxt[3]):
            v[2:] = -v[2:]
            nxt[2:] = x[2:] + v[2:]
        x = nxt
        q = np.zeros(2 * n)
        q[0], q[1:n] = x[0], x[1]
        q[2 * n - 1] = -x[3]
        q[n:2 * n - 1] = -x[3]
        q[n] = -x[3] - x[2]
        rows.append(q)
    return np.array(rows)


def record_walks(vr: VirtualRobot, Qs: list[np.ndarray], seed: int, first_id: int = 0) -> Dataset:
    """The walks driven on the virtual robot and recorded (measured and true tracker-frame poses)."""
    rng = np.random.default_rng(seed)
    frames = []
    for k, Q in enumerate(Qs):
        motion, _ = vr.move(vr.rest(Q[0]), Q)
        meas = vr.tracker.measure(motion.true_poses, rng)
        true = vr.tracker.registered(motion.true_poses)
        f = pd.DataFrame({"sequence_id": first_id + k, "step": np.arange(len(Q))})
        for j, c in enumerate(vr.nominal.joint_names()):
            f[c] = Q[:, j]
        for j, c in enumerate(POSE_COLUMNS):
            f[c] = meas[:, j]
        for j, c in enumerate(TRUE_POSE_COLUMNS):
            f[c] = true[:, j]
        f["snap"] = np.asarray(motion.snaps, bool)
        f["outlier"] = False
        frames.append(f[np.all(np.isfinite(meas), axis=1)])
    return Dataset(pd.concat(frames, ignore_index=True), vr.nominal, {"protocol": "walks", "seed": seed})


def auroc(inside: np.ndarray, outside: np.ndarray) -> float:
    """Area under the ROC curve of a score that should be larger outside (Mann-Whitney U, ties half)."""
    s = np.r_[inside, outside]
    ranks = pd.Series(s).rank().to_numpy()
    r_out = ranks[len(inside):].sum()
    return float((r_out - len(outside) * (len(outside) + 1) / 2) / (len(inside) * len(outside)))


def region_walks(robot: Robot, rng: np.random.Generator, region: dict[str, Any], count: int,
           steps: int) -> list[np.ndarray]:
    return [walk(robot, rng, steps, **region) for _ in range(count)]


def stream_cost(kin: Any, xs: np.ndarray, rounds: int = 5) -> dict[str, float]:
    """Median µs of Kinematics.step and of step_uncertain over the inputs xs (T, ·) of one sequence,
    in alternating rounds (load falls on both alike), and their ratio."""
    plain, unc = [], []
    clock = time.perf_counter
    for _ in range(rounds):
        for fn, into in ((kin.step, plain), (kin.step_uncertain, unc)):
            kin.reset()
            for x in xs:
                t0 = clock()
                fn(x)
                into.append(clock() - t0)
    a, b = float(np.median(plain)) * 1e6, float(np.median(unc)) * 1e6
    return {"step_us": a, "step_uncertain_us": b, "ratio": b / a}


def uncertainty_study(robot: Robot, vr: VirtualRobot, rng: np.random.Generator, quick: bool, root: Path,
                      seed: int) -> dict[str, Any]:
    """Coverage over 200 halvings of the held-out walks, AUROC per OOD kind, streaming cost; FK and IK
    (module docstring). The FK folder (with its uncertainty) is left in root for the control loop."""
    from ctrkin import Kinematics
    from ctrkin.inference.uncertainty import calibrate, ood_scores, predict_rows, row_runs
    from ctrkin.models.uncertainty import interval, scores
    from ctrkin.training import TrainConfig, train

    reg = regions(robot)
    n_train, steps, n_held, short = (24, 120, 48, 40) if quick else (60, 150, 120, 50)
    t0 = time.perf_counter()
    train_ds = record_walks(vr, region_walks(robot, rng, reg["train"], n_train, steps), seed + 1)
    held = record_walks(vr, region_walks(robot, rng, reg["train"], n_held, short), seed + 2, first_id=10_000)
    ood = {name: record_walks(vr, region_walks(robot, rng, reg[name], n_held // 4, short), seed + 3 + i)
           for i, name in enumerate(("range", "combination", "steps", "reversals"))}
    both = Dataset(pd.concat([train_ds.frame, held.frame], ignore_index=True), robot, {"protocol": "walks"})
    train_rows = np.arange(len(train_ds.frame))
    held_rows = np.arange(len(train_ds.frame), len(both.frame))
    sid = both.frame["sequence_id"].to_numpy()
    out: dict[str, Any] = {"robot": robot.name, "record_s": time.perf_counter() - t0,
                           "rows": {"train": len(train_rows), "held_out": len(held_rows),
                                    **{k: len(v.frame) for k, v in ood.items()}}}
    for task in ("fk", "ik"):
        frame = {"target_frame": "outer", "angle_encoding": "phase"} if task == "fk" else {}
        cfg = TrainConfig(task=task, max_epochs=30 if quick else 60, threads=1, batch_size=128, lr=2e-3,
                          options={"structure": "L64|D64"}, **frame)
        folder = root / f"{robot.name}_{task}"
        train(train_ds, cfg, folder, progress=False)
        kin = Kinematics.load(folder)
        pred, truth = predict_rows(kin, both)
        err = pred - truth
        halves = np.random.default_rng(seed)
        covs = []
        for _ in range(200):                       # calibrate on half of the held-out walks, test on the rest
            seqs = np.unique(sid[held_rows])
            cal = np.isin(sid[held_rows], halves.permutation(seqs)[:len(seqs) // 2])
            rows = held_rows[cal]
            radius, scale = interval(task, robot.n_tubes, err[rows], 0.9, row_runs(sid, rows))
            covs.append(float(np.mean(scores(task, robot.n_tubes, err[held_rows[~cal]], scale) <= radius)))
        unc = calibrate(kin, both, train_rows, held_rows[cal])
        unc.save(folder)
        inside = ood_scores(unc, kin, both, held_rows[~cal])
        outside = {name: ood_scores(unc, kin, ds) for name, ds in ood.items()}
        every = np.concatenate(list(outside.values()))
        first = held_rows[sid[held_rows] == sid[held_rows][0]]          # one held-out walk
        held_x = (both.joints() if task == "fk" else both.poses())[first]
        out[task] = {"coverage_90": float(np.mean(covs)),
                     "coverage_90_p5_p95": [float(v) for v in np.quantile(covs, [0.05, 0.95])],
                     "half_width": [float(v) for v in unc.half_widths()],
                     "ood_auroc": auroc(inside, every),
                     "ood_auroc_by_kind": {k: auroc(inside, v) for k, v in outside.items()},
                     "false_alarm_held_out": float(np.mean(inside > unc.threshold)),
                     "flagged_ood": float(np.mean(every > unc.threshold)),
                     "stream": stream_cost(Kinematics.load(folder), held_x)}
    return out


def control_start(robot: Robot) -> np.ndarray:
    """(2N,) the control loop's start joints (deg, mm), from the robot's own training region
    (`regions`): every α 0 (α0 = 0°: the curvatures aligned, the one stable equilibrium, furthest
    from the bistable band), d and the outer retraction at the middle of their ranges (no joint at a
    stop); the middle tubes move with the outer one, as in the walks."""
    reg = regions(robot)["train"]
    d = 0.5 * (reg["d"][0] + reg["d"][1])
    retract = 0.5 * (reg["ret"][0] + reg["ret"][1])
    n = robot.n_tubes
    start = np.zeros(2 * n)
    start[n:] = -retract
    start[n] = -retract - d
    return start


def control_study(robot: Robot, vr: VirtualRobot, folder: Path, quick: bool, seed: int) -> dict[str, Any]:
    """The controller on the FK of `folder` around the virtual robot (module docstring)."""
    from ctrkin import Kinematics
    from ctrkin.control import Controller, circle_path, run_virtual
    from ctrkin.geometry import tip_pose

    start = control_start(robot)
    eq = vr.rest(start).equilibrium
    p0 = vr.tracker.registered(tip_pose(eq.tip_position[None], eq.tip_tangent[None]))[0, :3]
    cycles = 2000 if quick else 4000
    targets, vel = circle_path(p0, 2.0, 4.0, cycles, 1000.0)
    kin = Kinematics.load(folder)
    res = run_virtual(Controller(kin), vr, targets, vel, start, seed=seed + 7)
    drop = run_virtual(Controller(Kinematics.load(folder)), vr, targets[:300], vel[:300], start,
                       seed=seed + 8, drop_from=200)
    held = bool(np.all(drop.joints[200:] == drop.joints[199]))
    return {"control_hz": res.rate_hz(), "tracking_rmse_mm": res.rmse_mm(cycles // 4),
            "tracking_max_mm": float(res.errors_mm()[cycles // 4:].max()), "snaps": int(res.snaps.sum()),
            "cycles": cycles, "path_diameter_mm": float(np.ptp(targets, axis=0).max()),
            "dropout_stopped_at": drop.stopped_at, "dropout_held_still": held}


def run(quick: bool, seed: int = 0, robots: tuple[str, ...] = ROBOTS, keep: Path | None = None,
        control: bool = True) -> dict[str, Any]:
    """Every study on every robot (the control loop too, unless control is False: in each robot's
    figures, and the first robot's again as "control", the goal keys'); one dict of figures. keep: a
    folder to leave the calibrated models in (ROBOT_fk, ROBOT_ik), else they go with a temporary
    folder."""
    out: dict[str, Any] = {}
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp) if keep is None else keep
        root.mkdir(parents=True, exist_ok=True)
        for k, spec in enumerate(robots):
            robot = paper_robot() if spec == "paper" else load_robot(spec)
            vr = VirtualRobot(robot, seed=seed)
            rng = np.random.default_rng(seed)
            out[robot.name] = uncertainty_study(robot, vr, rng, quick, root, seed)
            if control:
                out[robot.name]["control"] = control_study(robot, vr, root / f"{robot.name}_fk", quick, seed)
                if k == 0:
                    out["control"] = out[robot.name]["control"]
    return out


def summary(res: dict[str, Any]) -> dict[str, Any]:
    """The goal-4 keys: coverage the furthest from 0.9 over robots and tasks; ood_auroc the least over
    robots and tasks (the IK's score takes the robot's joints beside the pose, ctrkin.models.ood), the
    FK's and the IK's least beside it; the control figures."""
    studies = [v for k, v in res.items() if k != "control"]
    control = res.get("control", dict.fromkeys(("control_hz", "tracking_rmse_mm", "snaps")))
    return {"coverage_90": max((s[t]["coverage_90"] for s in studies for t in ("fk", "ik")),
                               key=lambda c: abs(c - 0.9)),
            "ood_auroc": min(s[t]["ood_auroc"] for s in studies for t in ("fk", "ik")),
            "ood_auroc_fk": min(s["fk"]["ood_auroc"] for s in studies),
            "ood_auroc_ik": min(s["ik"]["ood_auroc"] for s in studies),
            "stream_cost_ratio": max(s[t]["stream"]["ratio"] for s in studies for t in ("fk", "ik")),
            "control_hz": control["control_hz"],
            "tracking_rmse_mm": control["tracking_rmse_mm"],
            "control_snaps": control["snaps"]}


def print_table(res: dict[str, Any]) -> None:
    print(f"{'robot':18s} {'task':4s} {'coverage 90 %':>13s} {'(5-95 %)':>13s} {'AUROC':>6s} "
          f"{'range':>6s} {'combo':>6s} {'steps':>6s} {'revers':>6s} {'false al.':>9s} {'x cost':>7s}")
    for name, s in res.items():
        if name == "control":
            continue
        for t in ("fk", "ik"):
            r = s[t]
            by = r["ood_auroc_by_kind"]
            lo, hi = r["coverage_90_p5_p95"]
            print(f"{name:18s} {t:4s} {r['coverage_90']:13.3f} {lo:6.3f}-{hi:6.3f} {r['ood_auroc']:6.3f} "
                  f"{by['range']:6.3f} {by['combination']:6.3f} {by['steps']:6.3f} {by['reversals']:6.3f} "
                  f"{r['false_alarm_held_out']:9.3f} {r['stream']['ratio']:7.2f}")
    for name, s in res.items():
        if name == "control" or "control" not in s:
            continue
        c = s["control"]
        print(f"control, {name}: {c['control_hz']:.0f} cycles/s, steady-state RMS "
              f"{c['tracking_rmse_mm']:.3f} mm (max {c['tracking_max_mm']:.3f}), {c['snaps']} snaps over "
              f"{c['cycles']} cycles, path "
              f"{c['path_diameter_mm']:.1f} mm across; tracker dropped at cycle 200: stopped at "
              f"{c['dropout_stopped_at']}, held still {c['dropout_held_still']}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--robot", action="append", default=None,
                    help=f"paper or a robot file, repeatable (default: {', '.join(ROBOTS)})")
    ap.add_argument("--keep", type=Path, default=None, help="leave the calibrated model folders here")
    ap.add_argument("--no-control", action="store_true", help="leave out the control loop (run on every "
                    "robot from the middle of its own training region, α0 = 0°)")
    args = ap.parse_args()
    res = run(args.quick, args.seed, tuple(args.robot or ROBOTS), args.keep, not args.no_control)
    print_table(res)
    print(json.dumps({**summary(res), "detail": res}))


if __name__ == "__main__":
    main()
