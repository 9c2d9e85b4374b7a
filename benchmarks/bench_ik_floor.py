"""Benchmark: where the IK's tip error via the robot comes from (issue 21, goal 1's IK figures;
docs/learned_kinematics.md: Where the follow IK's error comes from).

    python benchmarks/bench_ik_floor.py --repro out/gen/default-top          # a finished reproduction
    python benchmarks/bench_ik_floor.py --collect /tmp/ikfloor --set noise_mm=0.4   # record + train first
    python benchmarks/bench_ik_floor.py --repro DIR --ik DIR/models/ik_follow_mlp,/tmp/ik_play

The reproduction's IK experiments (ctrkin.evaluation.experiments_ik) drive the virtual robot through
an IK's joints, each held-out sequence from rest at its first answer. This splits that figure into
what the experiment itself allows and what the models add, on the reproduction's own data:

  recorded       the recorded joints of the held-out (test) sequences driven exactly as an IK's are
                 (`experiments_ik.drive`): what an IK that answered the recording's joints would get;
                 split into the first FIRST steps of each sequence (the robot starts at rest, the
                 recording did not) and the rest
  replayed       the same, each sequence driven after its run replayed from the run's start (every
                 recorded row before it, glitch rows at the last believed joints, joined by the same
                 moves): the robot brought to the state the recording was in, as far as its rows tell
  noise          the recording's own truth against its targets (the tracker's noise)
  IK test / val  each IK folder driven on the test and validation sequences (the reproduction's
                 figure, and the one to choose by); `repl.`: on the test sequences from the recorded
                 state (the run replayed as above, the IK started at the recorded joints); `train`: on
                 the first TRAIN_SEQUENCES sequences of its own training rows, from their recorded
                 start joints
  β error        RMS of the IK's β1 … βN against the recorded joints on the test sequences (a mirror
                 solution differs in α, not in β)
  FK vs robot    the FK folder against the robot's noise-free tip along the IK's driven path and along
                 the recorded joints driven from rest (both as the experiments feed the FK: 1°/0.1 mm
                 moves between rows)
  random         random poses within 1 mm: the recorded joints driven through the whole run, and each IK
  lookup         a reference without a network: each target's joints are those of one of the
                 LOOKUP_K training rows nearest in pose and in the target's motion over the last
                 LOOKUP_LAG steps, the one nearest the previous answer (test and validation)
  iterations     with --iterations K,…: each follow IK's validation figure with the network applied K
                 times per target (Follower.iterations; 1 is the model's own setting): a contraction
                 that is weak gains from more, one towards wrong joints loses
  arrive         with --arrive K,… (and nothing else): each follow IK along squares and triangles that
                 are not the reproduction's (task_path seeds 100-104, VALIDATION_PATH_SEEDS), with K
                 applications at each destination reached through intermediate targets
                 (Follower.arrive; the choice of ARRIVE_ITERATIONS)
  inversion      with --inversion S,… (and nothing else): each follow IK on the validation and test
                 sequences and the random poses with the share S of its identified outer lag inverted
                 as a play (Follower.inversion; the choice of OUTER_INVERSION, made on validation), with
                 no dead zone (as it was chosen)
  dead zone      with --dead-zone A/B,… (and nothing else): the same, with joint changes below A deg
                 (α) and B mm (β) not made (Follower.dead_zone; the choice of DEAD_ZONE) and the
                 share OUTER_INVERSION inverted, and the validation squares and triangles of `arrive`
  cap            with --cap A/B,… (and perhaps --arrive K,…): the same as `dead zone`, with DEAD_ZONE,
                 each application on the way to a destination (the intermediate targets before a far
                 target in a path of far targets) changing the joints by at most A deg (α) and B mm
                 (β), scaled down as a whole (0/0: no cap; Follower.substep_cap, the choice of
                 SUBSTEP_CAP), for each K of --arrive (default ARRIVE_ITERATIONS) applications at a
                 destination
An IK that takes no start joints (the paper's, the refined one) is scored from its own start there.

Ends with one JSON line of the figures (mm unless named otherwise).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial import cKDTree

import ctrkin.families.registry  # noqa: F401  (the families' feature layouts)
from ctrkin.acquisition.task_paths import task_path
from ctrkin.data.dataset import Dataset
from ctrkin.data.schema import sequence_bounds
from ctrkin.evaluation.context import valid_rows
from ctrkin.evaluation.datasets import SEEDS as REPRO_SEEDS
from ctrkin.evaluation.datasets import registered_truth
from ctrkin.evaluation.experiments_ik import drive, joined
from ctrkin.evaluation.table import FK_BRANCH, IK_FOLLOW
from ctrkin.families.follow.stepper import ARRIVE_ITERATIONS, DEAD_ZONE, OUTER_INVERSION
from ctrkin.geometry import tangent_angle_error, tangent_from_quat
from ctrkin.inference import Kinematics
from ctrkin.mechanics import solve
from ctrkin.metrics import wrap_deg
from ctrkin.virtual import VirtualRobot
from ctrkin.virtual.truth import virtual_from_meta

sys.path.insert(0, str(Path(__file__).resolve().parent))   # the benchmark beside this one
from bench_fk_memory import collect_repro

FIRST = 100              # the first steps of a held-out sequence: the start from rest
PATH_TANGENT_MM = 10.0   # the square's and triangle's reach: mm of residual per radian of tangent
PATH_FIT_EVALS = 400     # ... and its least squares' evaluations per start
VALIDATION_PATH_SEEDS = range(100, 105)   # --arrive: squares and triangles that are not the reproduction's
TRAIN_SEQUENCES = 6      # the IK on the first so many sequences of its own training rows
# the lookup reference: candidates, the motion's span (steps) and weight, the weight of the distance
# to the previous answer (10° of α weigh like 1 mm of β) against the pose distance (mm, 10 mm per rad)
LOOKUP_K, LOOKUP_LAG, LOOKUP_MOTION, LOOKUP_CONTINUITY = 20, 30, 0.5, 0.1


def _rmse(e: np.ndarray) -> float:
    return float(np.sqrt(np.mean(e ** 2))) if len(e) else float("nan")


def _miss(reached: np.ndarray, targets: np.ndarray) -> np.ndarray:
    return np.linalg.norm(reached[:, :3] - targets[:, :3], axis=1)


def _part(ds: Dataset, part: str, limit: int | None = None) -> tuple[np.ndarray, list[tuple[int, int]]]:
    """Usable rows of a split part (the first `limit` sequences) and their sequence bounds."""
    rows = valid_rows(ds, getattr(ds.get_split(), part))
    b = sequence_bounds(ds.frame["sequence_id"].to_numpy()[rows])
    if limit is not None:
        b = b[:limit]
        rows = rows[:b[-1][1]]
    return rows, b


def random_within_1mm(virtual: VirtualRobot, rp: Dataset, joints: np.ndarray) -> int:
    """Random-points targets reached within 1 mm with the robot driven through joints (the whole run's
    rows, from rest at its first, as experiments_ik drives an IK's)."""
    bb = rp.sequence_bounds()
    targets = valid_rows(rp, np.nonzero(rp.frame["is_target"].to_numpy())[0])
    reached, _ = drive(virtual, joints, [(bb[0][0], bb[-1][1])])
    return int(np.sum(_miss(reached[targets], rp.poses()[targets]) < 1.0))


def recorded(virtual: VirtualRobot, ds: Dataset) -> dict[str, float]:
    """The recorded test joints driven as an IK's are, against the targets; the noise floor."""
    rows, b = _part(ds, "test")
    targets = ds.poses()[rows]
    reached, _ = drive(virtual, ds.joints()[rows], b)
    e = _miss(reached, targets)
    first = np.zeros(len(rows), bool)
    for a, c in b:
        first[a:min(c, a + FIRST)] = True
    return {"recorded_mm": _rmse(e), "recorded_within_1mm": float(np.mean(e < 1.0)),
            "recorded_first_mm": _rmse(e[first]), "recorded_after_mm": _rmse(e[~first]),
            "noise_mm": _rmse(_miss(registered_truth(ds)[rows], targets))}


def drive_replayed(virtual: VirtualRobot, ds: Dataset, rows: np.ndarray, b: list[tuple[int, int]],
                   joints: np.ndarray) -> np.ndarray:
    """Tips (len(rows), 6) the robot reaches through joints (len(rows), 2N), each sequence [a, b) of
    rows after its run replayed from the run's first row up to the sequence (recorded joints, glitch
    rows at the last believed ones; joined by 1°/0.1 mm moves, as `drive`)."""
    q = ds.joints().copy()
    for g in np.nonzero(ds.frame["outlier"].to_numpy())[0]:
        q[g] = q[g - 1] if g > 0 else q[g]
    runs = ds.frame["run"].to_numpy() if "run" in ds.frame.columns else np.arange(len(q))
    out = np.empty((len(rows), 6))
    for a, c in b:
        first = rows[a]
        start = int(np.flatnonzero(runs[:first + 1] == runs[first])[0])     # the run's first row
        path = np.vstack([q[start:first], joints[a:c]])
        reached, _ = drive(virtual, path, [(0, len(path))])
        out[a:c] = reached[first - start:]
    return out


def replayed(virtual: VirtualRobot, ds: Dataset) -> dict[str, float]:
    """The recorded test joints driven after their run replayed (module docstring), against the targets."""
    rows, b = _part(ds, "test")
    err = _miss(drive_replayed(virtual, ds, rows, b, ds.joints()[rows]), ds.poses()[rows])
    return {"replayed_mm": _rmse(err), "replayed_within_1mm": float(np.mean(err < 1.0))}


def fk_along(virtual: VirtualRobot, fk: Kinematics, joints: np.ndarray, b: list[tuple[int, int]]
             ) -> float:
    """The FK against the robot's noise-free tip, both driven through joints (1°/0.1 mm moves)."""
    reached, _ = drive(virtual, joints, b)
    path, at, sid = joined(fk.alpha_into_range(joints), virtual.nominal.n_tubes, b)
    via_fk = np.asarray(fk.predict(path, sequence_id=sid), float)[at]
    return _rmse(_miss(via_fk, reached))


def _best_pose_joints(virtual: VirtualRobot, target: np.ndarray, starts: np.ndarray, tangent_mm: float
                      ) -> tuple[np.ndarray, np.ndarray]:
    """Valid joints (2N,) whose tip on the true robot (point-wise solve, no friction) is nearest the
    robot-frame `target` (6,) in position plus `tangent_mm` mm per radian of tangent: least squares
    from each of `starts` (K, 2N), the best kept; and that tip's pose (6,)."""
    robot = virtual.nominal
    p_star, t_star = target[:3], tangent_from_quat(target[3:6])

    def tip(q: np.ndarray) -> np.ndarray:
        return solve(virtual.true_robot, virtual.base_joints(robot.project_joints(q[None]))[0]).tip_pose

    def residual(q: np.ndarray) -> np.ndarray:
        pose = tip(q)
        return np.r_[pose[:3] - p_star, tangent_mm * (tangent_from_quat(pose[3:6]) - t_star)]

    fits = [least_squares(residual, q0, diff_step=1e-4, max_nfev=PATH_FIT_EVALS) for q0 in starts]
    best = min(fits, key=lambda f: f.cost)
    return robot.project_joints(best.x[None])[0], tip(best.x)


def path_reach(virtual: VirtualRobot, shape: str, seed: int) -> dict[str, float]:
    """How far the square's or triangle's targets (Fig. 12, `task_paths.task_path` with the
    reproduction's seed) are from poses the robot can take. Their orientations are interpolated between
    the corners, so on the edges a pose need not be reachable. For each target: the valid joints whose
    tip on the true robot (point-wise solve, no friction, no hysteresis) is nearest its pose, position
    plus PATH_TANGENT_MM mm per radian of tangent (the refined IK's weighting; least squares from every
    corner's joints): `mm` and `tangent_deg`, the RMS misses of that fit (an IK that matches the pose
    as well as any joints can misses the position by this before friction); and from there the
    position alone: `position_only_tangent_deg`, what matching the position costs in tangent."""
    path = task_path(virtual, shape, n_points=10, seed=seed)
    fits, position_only = [], []
    for target in path.poses:
        q, pose = _best_pose_joints(virtual, target, path.corner_joints, PATH_TANGENT_MM)
        fits.append(pose)
        position_only.append(_best_pose_joints(virtual, target, q[None], 0.0)[1])
    return {"mm": _rmse(_miss(np.array(fits), path.poses)),
            "tangent_deg": _rmse(tangent_angle_error(np.array(fits), path.poses)),
            "position_only_tangent_deg": _rmse(tangent_angle_error(np.array(position_only), path.poses))}


def path_reaches(virtual: VirtualRobot) -> dict[str, float]:
    """`path_reach` of the square and the triangle, keys ik_{shape}_reach_{figure}."""
    return {f"ik_{shape}_reach_{k}": v for shape in ("square", "triangle")
            for k, v in path_reach(virtual, shape, REPRO_SEEDS[shape]).items()}


def validation_paths(virtual: VirtualRobot, ik: Kinematics, arrives: tuple[int, ...], ds: Dataset,
                     seeds: range = VALIDATION_PATH_SEEDS, sequences: bool = True
                     ) -> dict[int, dict[str, list[float]]]:
    """A follow IK along squares and triangles that are not the reproduction's (task_path seeds
    `seeds`; the reproduction's are 4 and 5), with `Follower.arrive` set to each of `arrives` (its
    applications at a destination reached through intermediate targets): per K and shape the tip's
    position RMSE via the robot (mm) on each path, its first target left out (the sequence start's
    own settling); and with `sequences`, under "validation", the figure on the validation sequences of
    `ds` (close targets, where a step beyond the training steps' 95th percentile also takes them)."""
    follower = ik.predictor.follower        # type: ignore[attr-defined]
    own = follower.arrive
    paths = {(shape, seed): virtual.tracker.registered(task_path(virtual, shape, 10, seed).poses)
             for shape in ("square", "triangle") for seed in seeds}
    out: dict[int, dict[str, list[float]]] = {}
    try:
        for k in arrives:
            follower.arrive = k
            for (shape, _), targets in paths.items():
                reached, _ = drive(virtual, ik.predict(targets).joints, [(0, len(targets))])
                out.setdefault(k, {}).setdefault(shape, []).append(_rmse(_miss(reached[1:], targets[1:])))
            if sequences:
                out[k]["validation"] = [validation_mm(virtual, ik, ds)]
    finally:
        follower.arrive = own
    return out


def validation_mm(virtual: VirtualRobot, ik: Kinematics, ds: Dataset, part: str = "val") -> float:
    """The IK via the robot on the validation (or `part`'s) sequences of `ds` (mm RMSE), each from rest."""
    rows, b = _part(ds, part)
    sid = ds.frame["sequence_id"].to_numpy()[rows]
    reached, _ = drive(virtual, ik.predict(ds.poses()[rows], sequence_id=sid).joints, b)
    return _rmse(_miss(reached, ds.poses()[rows]))


def ik_figures(virtual: VirtualRobot, ds: Dataset, train: Dataset, rp: Dataset, ik: Kinematics,
               fk: Kinematics | None, iterations: tuple[int, ...] = ()) -> dict[str, Any]:
    out: dict[str, Any] = {}
    sid = ds.frame["sequence_id"].to_numpy()
    n = ds.n_tubes
    follower = getattr(ik.predictor, "follower", None)     # a follow IK: it takes start joints

    def started(starts: np.ndarray) -> dict[str, Any]:
        return {} if follower is None else {"start_joints": starts}

    for part in ("test", "val"):
        rows, b = _part(ds, part)
        res = ik.predict(ds.poses()[rows], sequence_id=sid[rows])
        reached, _ = drive(virtual, res.joints, b)
        e = _miss(reached, ds.poses()[rows])
        out[f"ik_{part}_mm"], out[f"ik_{part}_within_1mm"] = _rmse(e), float(np.mean(e < 1.0))
        if part == "test":
            # from the recorded state: the run replayed, the IK told the joints the robot is at
            starts = ds.joints()[rows][[a for a, _ in b]]
            joints = ik.predict(ds.poses()[rows], sequence_id=sid[rows], **started(starts)).joints
            e = _miss(drive_replayed(virtual, ds, rows, b, joints), ds.poses()[rows])
            out["ik_test_replayed_mm"] = _rmse(e)
            dq = res.joints[:, n:] - ds.joints()[rows][:, n:]
            out["beta_error_mm"] = [float(x) for x in np.sqrt(np.mean(dq ** 2, axis=0))]
            if fk is not None:
                out["fk_vs_robot_ik_path_mm"] = fk_along(virtual, fk, res.joints, b)
                out["fk_vs_robot_recorded_mm"] = fk_along(virtual, fk, ds.joints()[rows], b)
    own = None if follower is None else follower.iterations
    for k in iterations if follower is not None else ():
        follower.iterations = k
        out.setdefault("val_by_iterations_mm", {})[k] = validation_mm(virtual, ik, ds)
    if follower is not None:
        follower.iterations = own
    rows, b = _part(train, "train", TRAIN_SEQUENCES)
    tsid = train.frame["sequence_id"].to_numpy()
    starts = train.joints()[rows][[a for a, _ in b]]
    res = ik.predict(train.poses()[rows], sequence_id=tsid[rows], **started(starts))
    reached, _ = drive(virtual, res.joints, b)
    out["ik_train_mm"] = _rmse(_miss(reached, train.poses()[rows]))
    out["random_within_1mm"] = random_within_1mm(virtual, rp, ik.predict(rp).joints)
    return out


def _lookup_features(ds: Dataset, rows: np.ndarray) -> np.ndarray:
    """(len(rows), 9): position (mm), 10 × tangent, LOOKUP_MOTION × the position's change over the
    last LOOKUP_LAG steps of its sequence (from the sequence start for its first rows)."""
    p = ds.poses()
    tan = np.array([tangent_from_quat(q) for q in p[:, 3:6]])
    prev = np.arange(len(p)) - LOOKUP_LAG
    for a, c in ds.sequence_bounds():
        prev[a:min(c, a + LOOKUP_LAG)] = a
    return np.c_[p[:, :3], 10.0 * tan, LOOKUP_MOTION * (p[:, :3] - p[prev, :3])][rows]


def lookup(virtual: VirtualRobot, ds: Dataset, train: Dataset) -> dict[str, float]:
    """The lookup reference (module docstring) via the robot on the test and validation sequences."""
    trows = valid_rows(train, train.get_split().train)
    tree, joints = cKDTree(_lookup_features(train, trows)), train.joints()[trows]
    n = ds.n_tubes
    scale = np.r_[np.full(n, 10.0), np.ones(n)]
    out = {}
    for part in ("test", "val"):
        rows, b = _part(ds, part)
        feats, answer = _lookup_features(ds, rows), np.empty((len(rows), 2 * n))
        for a, c in b:
            for t in range(a, c):
                dist, idx = tree.query(feats[t], k=LOOKUP_K)
                cand = joints[idx].copy()
                if t > a:                       # α as whole turns nearest the previous answer
                    cand[:, :n] = answer[t - 1, :n] + wrap_deg(cand[:, :n] - answer[t - 1, :n])
                    step = np.sum(((cand - answer[t - 1]) / scale) ** 2, axis=1)
                    answer[t] = cand[int(np.argmin(dist ** 2 + LOOKUP_CONTINUITY * step))]
                else:
                    answer[t] = cand[0]
        reached, _ = drive(virtual, answer, b)
        out[f"lookup_{part}_mm"] = _rmse(_miss(reached, ds.poses()[rows]))
    return out


def train_recommended(repro: Path, task: str, folder: Path, extra: list[str]) -> None:
    """`ctrkin train --task TASK` on the reproduction's training set, as a user would (skipped when
    the folder holds a finished model)."""
    if (folder / "metrics.json").is_file():
        return
    cmd = [str(Path(sys.executable).with_name("ctrkin")), "train", "--task", task, "--data",
           str(repro / "data" / "paper+excitation"), "--out", str(folder), *extra]
    print("  ctrkin " + " ".join(cmd[1:]), flush=True)
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, env={**os.environ, "CTRKIN_NO_PROGRESS": "1"})


def main(argv: list[str] | None = None) -> dict[str, Any]:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repro", type=Path, default=None, help="a reproduction folder (data/, models/)")
    ap.add_argument("--collect", type=Path, default=None, help="record the quick reproduction's data on "
                    "the paper robot (the virtual robot's defaults with --set) into COLLECT/data, train "
                    "the recommended IK and FK into COLLECT/models (reused when there), use it as --repro")
    ap.add_argument("--set", dest="settings", action="append", default=[], metavar="KEY=VALUE",
                    help="a virtual robot effect for --collect (VirtualConfig's fields, as `ctrkin collect`)")
    ap.add_argument("--ik", default=None, help="comma-separated IK folders (default: the reproduction's "
                    f"models/{IK_FOLLOW})")
    ap.add_argument("--fk", type=Path, default=None, help=f"the FK folder (default: models/{FK_BRANCH})")
    ap.add_argument("--iterations", default="", help="comma-separated applications per target to score "
                    "each IK's validation figure with (e.g. 1,2,4)")
    ap.add_argument("--inversion", default="", help="comma-separated shares of the outer lag the follow IK "
                    "inverts (e.g. 0,0.25,0.5,1): only score each follow IK on the validation and test "
                    "sequences and the random poses with each")
    ap.add_argument("--dead-zone", default="", help="comma-separated A/B dead zones of the follow IK's "
                    "steps (α deg / β mm, e.g. 0/0,2/0.1): only score each follow IK on the validation and "
                    "test sequences, the random poses and validation squares and triangles with each")
    ap.add_argument("--arrive", default="", help="comma-separated applications at a far target (e.g. "
                    "0,2,5): only score each follow IK along validation squares and triangles (task_path "
                    f"seeds {VALIDATION_PATH_SEEDS.start}-{VALIDATION_PATH_SEEDS.stop - 1}) with each; "
                    "with --cap, the applications to combine each cap with")
    ap.add_argument("--cap", default="", help="comma-separated A/B caps on a joint change on the way to a "
                    "destination (α deg / β mm, 0/0: none, e.g. 0/0,5/0.5,3/0.3): only score each follow "
                    "IK as --dead-zone does, with each cap (and each --arrive count)")
    args = ap.parse_args(argv)
    iterations = tuple(int(k) for k in args.iterations.split(",") if k.strip())
    if any(k < 1 for k in iterations):
        ap.error("--iterations are counts of at least 1")
    if args.collect is not None:
        args.repro, _ = collect_repro(args.collect, "quick", args.settings)
        train_recommended(args.repro, "ik", args.repro / "models" / IK_FOLLOW, [])
        train_recommended(args.repro, "fk", args.repro / "models" / FK_BRANCH, [])
    if args.repro is None:
        ap.error("give --repro or --collect")
    data = args.repro / "data"
    ds = Dataset.load(data / "paper")
    train = Dataset.load(data / "paper+excitation")
    rp = Dataset.load(data / "random-points")
    if ds.split is None or not ds.has_truth:
        ap.error(f"{data / 'paper'} needs its split and true pose columns (a virtual robot's reproduction)")
    virtual = virtual_from_meta(ds)
    iks = [Path(p) for p in (args.ik.split(",") if args.ik else [str(args.repro / "models" / IK_FOLLOW)])]
    fk_dir = args.fk or args.repro / "models" / FK_BRANCH
    fk = Kinematics.load(fk_dir) if fk_dir.is_dir() else None
    if args.cap:
        caps = _slash_pairs(args.cap)
        if any(len(c) != 2 or min(c) < 0 or (min(c) == 0 < max(c)) for c in caps):
            ap.error("--cap takes comma-separated A/B pairs (α deg / β mm, both > 0, or 0/0 for none)")
        arrives = tuple(int(k) for k in args.arrive.split(",")) if args.arrive else (ARRIVE_ITERATIONS,)
        return _cap_report(virtual, iks, tuple(None if max(c) == 0 else c for c in caps), arrives, ds, rp)
    if args.arrive:
        return _arrive_report(virtual, iks, tuple(int(k) for k in args.arrive.split(",")), ds)
    if args.inversion:
        shares = tuple(float(k) for k in args.inversion.split(","))
        if any(not 0.0 <= k <= 2.0 for k in shares):
            ap.error("--inversion shares lie in [0, 2]")
        # as chosen: before the dead zone existed
        return _setting_report(virtual, iks, "inversion", shares, ds, rp, False, {"dead_zone": (0.0, 0.0)})
    if args.dead_zone:
        zones = _slash_pairs(args.dead_zone)
        if any(len(z) != 2 or min(z) < 0 for z in zones):
            ap.error("--dead-zone takes comma-separated A/B pairs (α deg / β mm, each ≥ 0)")
        # as chosen: with the outer inversion already chosen
        return _setting_report(virtual, iks, "dead_zone", zones, ds, rp, True, {"inversion": OUTER_INVERSION})

    floor = recorded(virtual, ds) | replayed(virtual, ds) | lookup(virtual, ds, train)
    floor["recorded_random_within_1mm"] = random_within_1mm(virtual, rp, rp.joints())
    n_random = len(valid_rows(rp, np.nonzero(rp.frame["is_target"].to_numpy())[0]))
    print(f"IK error split on {data} (test sequences: {len(_part(ds, 'test')[1])}; the first {FIRST} steps "
          "of each start from rest)")
    print(f"  recorded joints driven as an IK's: {floor['recorded_mm']:.2f} mm RMSE "
          f"({100 * floor['recorded_within_1mm']:.0f} % within 1 mm; first {FIRST} steps "
          f"{floor['recorded_first_mm']:.2f}, after {floor['recorded_after_mm']:.2f}); tracker noise "
          f"{floor['noise_mm']:.2f}; random poses {floor['recorded_random_within_1mm']}/{n_random}")
    print(f"  the same after their runs replayed from rest: {floor['replayed_mm']:.2f} mm RMSE "
          f"({100 * floor['replayed_within_1mm']:.0f} % within 1 mm)")
    print(f"  lookup of the training joints (no network): test {floor['lookup_test_mm']:.2f}, validation "
          f"{floor['lookup_val_mm']:.2f} mm")
    report: dict[str, Any] = {"repro": str(args.repro), **floor, "iks": {}}
    print(f"  {'IK':38s} {'test':>6s} {'repl.':>6s} {'val':>6s} {'train':>6s} {'β err':>12s} {'rand':>5s} "
          f"{'FK∥IK':>6s} {'FK∥rec':>6s}")
    for folder in iks:
        r = report["iks"][str(folder)] = ik_figures(virtual, ds, train, rp, Kinematics.load(folder), fk,
                                                    iterations)
        beta = "/".join(f"{x:.2f}" for x in r["beta_error_mm"])
        fk_ik, fk_rec = (r.get(k, math.nan) for k in ("fk_vs_robot_ik_path_mm", "fk_vs_robot_recorded_mm"))
        print(f"  {str(folder)[-38:]:38s} {r['ik_test_mm']:6.2f} {r['ik_test_replayed_mm']:6.2f} "
              f"{r['ik_val_mm']:6.2f} {r['ik_train_mm']:6.2f} {beta:>12s} {r['random_within_1mm']:5d} "
              f"{fk_ik:6.2f} {fk_rec:6.2f}", flush=True)
        if "val_by_iterations_mm" in r:
            print(f"  {'':38s} validation by applications per target: " + ", ".join(
                f"{k}: {v:.2f}" for k, v in r["val_by_iterations_mm"].items()), flush=True)
    print(json.dumps(report, default=float))
    return report


def _slash_pairs(text: str) -> tuple[tuple[float, ...], ...]:
    """"A/B,C/D,…" (--dead-zone, --cap) as ((A, B), (C, D), …); a malformed item gives a tuple of
    another length, which the caller refuses."""
    return tuple(tuple(float(x) for x in item.split("/")) for item in text.split(","))


def setting_figures(virtual: VirtualRobot, ik: Kinematics, name: str, values: tuple[Any, ...], ds: Dataset,
                    rp: Dataset, paths: bool = False, base: dict[str, Any] | None = None
                    ) -> dict[Any, dict[str, float]]:
    """A follow IK with its stepper's setting `name` (a Follower attribute) at each of `values` (and the
    settings `base` fixed): via the robot on the validation and test sequences (mm RMSE, each from rest),
    the random poses within 1 mm, and with `paths` the mean RMSE along the validation squares and
    triangles (`validation_paths`). The follower's own settings are restored afterwards."""
    follower = ik.predictor.follower        # type: ignore[attr-defined]
    base = base or {}
    own = {k: getattr(follower, k) for k in (name, *base)}
    out: dict[Any, dict[str, float]] = {}
    try:
        for k, v in base.items():
            setattr(follower, k, v)
        for v in values:
            setattr(follower, name, v)
            row = out.setdefault(v, {f"ik_{part}_mm": validation_mm(virtual, ik, ds, part)
                                     for part in ("val", "test")})
            row["random_within_1mm"] = random_within_1mm(virtual, rp, ik.predict(rp).joints)
            if paths:
                got = validation_paths(virtual, ik, (follower.arrive,), ds, sequences=False)[follower.arrive]
                row.update({f"val_{k}_mm": float(np.mean(got[k])) for k in ("square", "triangle")})
    finally:
        for k, v in own.items():
            setattr(follower, k, v)
    return out


def _setting_report(virtual: VirtualRobot, iks: list[Path], name: str, values: tuple[Any, ...], ds: Dataset,
                    rp: Dataset, paths: bool, base: dict[str, Any]) -> dict[str, Any]:
    """--inversion / --dead-zone: one row per follow IK and value, then the JSON line."""
    report = _setting_rows(virtual, iks, name, values, ds, rp, paths, base)
    print(json.dumps(report, default=float))
    return report


def _cap_report(virtual: VirtualRobot, iks: list[Path], caps: tuple[Any, ...], arrives: tuple[int, ...],
                ds: Dataset, rp: Dataset) -> dict[str, Any]:
    """--cap: `_setting_rows` of the substep cap for each applications count at a destination, with
    the outer inversion and the dead zone as chosen; then the JSON line."""
    report: dict[str, Any] = {"substep_cap": {}}
    for k in arrives:
        print(f"applications at a destination: {k}")
        got = _setting_rows(virtual, iks, "substep_cap", caps, ds, rp, True,
                            {"inversion": OUTER_INVERSION, "dead_zone": DEAD_ZONE, "arrive": k})
        report["substep_cap"][str(k)] = got["substep_cap"]
    print(json.dumps(report, default=float))
    return report


def _setting_rows(virtual: VirtualRobot, iks: list[Path], name: str, values: tuple[Any, ...], ds: Dataset,
                  rp: Dataset, paths: bool, base: dict[str, Any]) -> dict[str, Any]:
    """One printed row per follow IK and value of `setting_figures`; {name: {folder: {value: row}}}."""
    report: dict[str, Any] = {name: {}}
    print(f"follow IK with its {name} at each value (mm RMSE via the robot; random poses within 1 mm"
          + ("; validation squares / triangles, task_path seeds 100-104)" if paths else ")"))
    print(f"  {'IK':38s} {'λ (a, b)':>14s} {name:>12s} {'val':>6s} {'test':>6s} {'rand':>5s}"
          + (f" {'val sq':>6s} {'val tri':>7s}" if paths else ""))
    for folder in iks:
        ik = Kinematics.load(folder)
        got = setting_figures(virtual, ik, name, values, ds, rp, paths, base)
        report[name][str(folder)] = {str(v): r for v, r in got.items()}
        a, b = ik.predictor.follower.lag                   # type: ignore[attr-defined]
        lag = f"{a:.2f}, {b:.3f}"
        for v, r in got.items():
            value = ("none" if v is None else "/".join(f"{x:g}" for x in v) if isinstance(v, tuple)
                     else f"{v:g}")
            print(f"  {str(folder)[-38:]:38s} {lag:>14s} {value:>12s} {r['ik_val_mm']:6.2f} "
                  f"{r['ik_test_mm']:6.2f} {r['random_within_1mm']:5d}"
                  + (f" {r['val_square_mm']:6.2f} {r['val_triangle_mm']:7.2f}" if paths else ""), flush=True)
    return report


def _arrive_report(virtual: VirtualRobot, iks: list[Path], arrives: tuple[int, ...], ds: Dataset
                   ) -> dict[str, Any]:
    """--arrive: the validation paths' table (mean over the paths, then each path) and JSON line."""
    report: dict[str, Any] = {"arrive": {}}
    print(f"follow IK along validation paths (seeds {VALIDATION_PATH_SEEDS.start}-"
          f"{VALIDATION_PATH_SEEDS.stop - 1}; mm RMSE via the robot, first target left out) and on the "
          "validation sequences")
    for folder in iks:
        got = validation_paths(virtual, Kinematics.load(folder), arrives, ds)
        report["arrive"][str(folder)] = got
        for k, shapes in got.items():
            cells = "  ".join(f"{shape} {np.mean(v):.2f} ({', '.join(f'{x:.2f}' for x in v)})"
                              for shape, v in shapes.items())
            print(f"  {str(folder)[-38:]:38s} arrive {k:2d}: {cells}", flush=True)
    print(json.dumps(report, default=float))
    return report


if __name__ == "__main__":
    main()
