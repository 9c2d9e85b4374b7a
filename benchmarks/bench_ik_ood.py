"""The out-of-distribution score's form, chosen on validation walks (issue 24, goal 2): AUROC of
held-out in-range walks against each out-of-distribution kind, for the IK's score on the target pose
alone (the IK's score before, an uncertainty file of format 1), the joint-aware IK score (the pose and
the robot's joints when it was asked, ctrkin.models.ood) with its splits into k-NN parts, and the FK's
score (the joints) with its splits; and how far the "unseen combination" walks lie from the training
rows.

    python benchmarks/bench_ik_ood.py                          # paper robot (~10 min at load 2)
    python benchmarks/bench_ik_ood.py --robot design-b         # bench_generalisation's second design
    python benchmarks/bench_ik_ood.py --robot examples/robots/comet_nylon_ndi.toml
    python benchmarks/bench_ik_ood.py --validation-walks 12 --test-walks 12   # the earlier, smaller sets
    python benchmarks/bench_ik_ood.py --walks-cache DIR      # keep the recorded walks in DIR, reuse them

The walks, regions and AUROC are benchmarks/learned_loop.py's (24 training walks of 120 steps; in each
of a validation and a test set, other seeds: 4 × W held-out in-range walks of 40 steps and W of each
OOD kind, W = 48 by default), recorded on the virtual robot at its defaults. The score is the
library's (ctrkin.inference.uncertainty.scored_inputs: from a recording, the joints when a pose was
asked are the row before's). No model is trained: the score reads only the inputs (a model's errors
set its interval, not its OOD score), so the errors passed are zeros.

Each task's form (IK: the joint-aware splits; FK: its splits) is the one with the larger validation
AUROC over every kind; how sure the choice is comes from a paired bootstrap over the validation walks
(each resample draws walks with replacement within the in-range set and within each kind, the same
walks for every form): the difference's 5-95 % and the share of resamples the chosen form wins. The
test walks report every form; the chosen ones are marked. Calibrated on the first half of each
held-out set, scored on the other half. Ends with one JSON line. The splits (ctrkin.models.ood.part_spans):
"config-history" two parts, "blocks" one part a feature block, "fine" the joints' configuration split
into rotations and translations, "blocks+translations" the blocks and the translations again in a
part of their own (the library's default since this benchmark chose it on both robots).
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path
from typing import Any

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np

import learned_loop  # benchmarks/, beside this file
from ctrkin.data.dataset import Dataset
from ctrkin.inference.uncertainty import row_runs
from ctrkin.models.ood import joints_before, part_scores, sequence_features
from ctrkin.models.uncertainty import Uncertainty
from ctrkin.robots import load_robot, paper_robot
from ctrkin.robots.robot import Robot
from ctrkin.virtual.robot import VirtualRobot

KINDS = ("range", "combination", "steps", "reversals")
FORMS = {"pose (before)": ("pose", "config-history"),
         "pose + joints, config-history": ("pose+joints", "config-history"),
         "pose + joints, blocks": ("pose+joints", "blocks"),
         "pose + joints, fine": ("pose+joints", "fine"),
         "pose + joints, blocks+translations": ("pose+joints", "blocks+translations"),
         "FK joints, blocks": ("joints", "blocks"),
         "FK joints, fine": ("joints", "fine"),
         "FK joints, blocks+translations": ("joints", "blocks+translations")}
CANDIDATES = {"ik": [f for f, (i, _) in FORMS.items() if i == "pose+joints"],
              "fk": [f for f, (i, _) in FORMS.items() if i == "joints"]}


def bounds(ds: Dataset) -> list[tuple[int, int]]:
    return row_runs(ds.frame["sequence_id"].to_numpy(), np.arange(len(ds.frame)))


def scored(ds: Dataset, inputs: str) -> np.ndarray:
    """The scored inputs of every row (ctrkin.inference.uncertainty.scored_inputs without a model)."""
    if inputs == "joints":
        return ds.joints()
    pose = ds.poses()
    return pose if inputs == "pose" else np.hstack([pose, joints_before(ds.joints(), ds.sequence_bounds())])


def robot_of(spec: str) -> Robot:
    if spec == "paper":
        return paper_robot()
    if spec == "design-b":
        from bench_generalisation import design_b

        return design_b()
    return load_robot(spec)


def record(robot: Robot, vr: VirtualRobot, rng: np.random.Generator, seed: int, first_id: int, per_kind: int
           ) -> tuple[Dataset, dict[str, Dataset]]:
    """Held-out in-range walks (4 × per_kind: half calibrate, half are scored) and per_kind walks of
    each OOD kind (one set: validation or test)."""
    reg = learned_loop.regions(robot)
    walks = learned_loop.region_walks(robot, rng, reg["train"], 4 * per_kind, 40)
    held = learned_loop.record_walks(vr, walks, seed, first_id=first_id)
    ood = {k: learned_loop.record_walks(vr, learned_loop.region_walks(robot, rng, reg[k], per_kind, 40),
                                        seed + 1 + i, first_id=first_id + 10_000 * (i + 1))
           for i, k in enumerate(KINDS)}
    return held, ood


def per_walk(scores: np.ndarray, runs: list[tuple[int, int]]) -> list[np.ndarray]:
    return [scores[a:b] for a, b in runs]


def walk_scores(robot: Robot, train: Dataset, held: Dataset, ood: dict[str, Dataset], inputs: str, split: str
                ) -> tuple[dict[str, list[np.ndarray]], Uncertainty]:
    """The form's scores walk by walk ("inside": the scored half of the held-out walks; then each
    kind), calibrated on the first half of the held-out walks."""
    hb = bounds(held)
    half = len(hb) // 2
    cut = hb[half][0]
    test_bounds = [(a - cut, b - cut) for a, b in hb[half:]]
    x = scored(held, inputs)
    task = "fk" if inputs == "joints" else "ik"
    unc = Uncertainty.fit(task, robot.n_tubes, scored(train, inputs), bounds(train), x[:cut], hb[:half],
                          np.zeros((cut, 3 if task == "fk" else robot.n_joints)), inputs=inputs, split=split)
    out = {"inside": per_walk(unc.ood_scores(x[cut:], test_bounds), test_bounds)}
    for k, d in ood.items():
        out[k] = per_walk(unc.ood_scores(scored(d, inputs), bounds(d)), bounds(d))
    return out, unc


def aurocs_of(walks: dict[str, list[np.ndarray]]) -> dict[str, float]:
    """AUROC of held-out in-range rows against every kind ("all") and each kind."""
    inside = np.concatenate(walks["inside"])
    outside = {k: np.concatenate(walks[k]) for k in KINDS}
    row = {"all": learned_loop.auroc(inside, np.concatenate(list(outside.values())))}
    return row | {k: learned_loop.auroc(inside, v) for k, v in outside.items()}


def bootstrap_all(forms: dict[str, dict[str, list[np.ndarray]]], rounds: int, seed: int
                  ) -> dict[str, np.ndarray]:
    """(rounds,) "all" AUROC of each form on the same resamples of walks (paired: every form sees the
    same walks drawn with replacement, within the in-range set and within each kind)."""
    rng = np.random.default_rng(seed)
    first = next(iter(forms.values()))
    out: dict[str, list[float]] = {f: [] for f in forms}
    for _ in range(rounds):
        pick = {k: rng.integers(0, len(w), len(w)) for k, w in first.items()}
        for f, walks in forms.items():
            inside = np.concatenate([walks["inside"][i] for i in pick["inside"]])
            outside = np.concatenate([walks[k][i] for k in KINDS for i in pick[k]])
            out[f].append(learned_loop.auroc(inside, outside))
    return {f: np.asarray(v) for f, v in out.items()}


def choose(val: dict[str, dict[str, list[np.ndarray]]], res: dict[str, dict[str, float]],
           candidates: list[str], rounds: int, seed: int) -> dict[str, Any]:
    """The candidate with the largest validation AUROC over every kind, and how sure: against each
    other candidate, the bootstrap's difference (5-95 %) and the share of resamples it wins."""
    chosen = max(candidates, key=lambda f: res[f]["all"])
    boot = bootstrap_all({f: val[f] for f in candidates}, rounds, seed)
    against = {}
    for f in candidates:
        if f != chosen:
            d = boot[chosen] - boot[f]
            against[f] = {"difference": res[chosen]["all"] - res[f]["all"],
                          "difference_p5_p95": [float(v) for v in np.quantile(d, [0.05, 0.95])],
                          "wins_share": float(np.mean(d > 0))}
    return {"chosen": chosen, "against": against}


def combination_distance(robot: Robot, train: Dataset, held: Dataset, combo: Dataset,
                         unc: Uncertainty) -> dict[str, Any]:
    """How far the unseen-combination walks lie from the training rows, against held-out walks: the
    nearest training row in the two translations (mm), and the k-NN distance of the narrowest part that
    holds the translations over its calibration median (the score's own measure of that part)."""
    n = robot.n_tubes
    tb = train.joints()[:, n:]

    def nearest_mm(q: np.ndarray) -> np.ndarray:
        d = np.linalg.norm(q[:, n:][:, None, :] - tb[None, ::3, :], axis=2)
        return d.min(axis=1)

    def part(ds: Dataset) -> np.ndarray:
        z = (sequence_features(unc.inputs, n, scored(ds, unc.inputs), bounds(ds)) - unc.center) / unc.spread
        col = 6 + 2 * (n - 1)                               # the first translation's column
        holding = [p for p, (lo, hi) in enumerate(unc.parts) if lo <= col < hi]
        p = min(holding, key=lambda p: unc.parts[p, 1] - unc.parts[p, 0])      # the narrowest
        lo, hi = int(unc.parts[p, 0]), int(unc.parts[p, 1])
        return part_scores(np.ascontiguousarray(z), unc.reference, lo, hi, unc.k) / unc.tau[p]

    out: dict[str, Any] = {}
    held_p90 = float(np.quantile(nearest_mm(held.joints()), 0.9))
    for name, ds in (("held_out", held), ("combination", combo)):
        mm, sc = nearest_mm(ds.joints()), part(ds)
        out[f"{name}_share_nearer_than_held_out_p90"] = float(np.mean(mm <= held_p90))
        out[name] = {"nearest_beta_mm_median": float(np.median(mm)),
                     "nearest_beta_mm_p90": float(np.quantile(mm, 0.9)),
                     "joint_part_median": float(np.median(sc)), "joint_part_p90": float(np.quantile(sc, 0.9))}
    reg = learned_loop.regions(robot)["train"]
    out["train_region"] = {"d_mm": list(reg["d"]), "retraction_mm": list(reg["ret"]),
                           "held_back_corner_d_mm": list(reg["exclude"]), "held_back_retraction_over_mm": 2.5}
    return out


SetPair = tuple[Dataset, dict[str, Dataset]]


def recorded(robot: Robot, seed: int, validation_walks: int, test_walks: int, cache: Path | None
             ) -> tuple[Dataset, dict[str, SetPair]]:
    """The training walks and the validation and test sets (`record`), recorded on the virtual robot,
    or read from `cache` where an earlier run with the same robot, seed and walk counts saved them
    (the recording is seeded: the same walks either way; it is the slow part on a slow robot)."""
    label = f"{robot.name}_{robot.fingerprint()[:12]}_s{seed}_v{validation_walks}_t{test_walks}"
    folder = None if cache is None else cache / label
    names = ["train"] + [f"{s}_{k}" for s in ("validation", "test") for k in ("held", *KINDS)]
    if folder is not None and all((folder / n).is_dir() for n in names):
        got = {n: Dataset.load(folder / n, robot) for n in names}
        return got["train"], {s: (got[f"{s}_held"], {k: got[f"{s}_{k}"] for k in KINDS})
                              for s in ("validation", "test")}
    vr = VirtualRobot(robot, seed=seed)
    rng = np.random.default_rng(seed)
    reg = learned_loop.regions(robot)
    train = learned_loop.record_walks(vr, learned_loop.region_walks(robot, rng, reg["train"], 24, 120),
                                      seed + 1)
    sets = {"validation": record(robot, vr, rng, seed + 10, 100_000, validation_walks),
            "test": record(robot, vr, rng, seed + 20, 200_000, test_walks)}
    if folder is not None:
        train.save(folder / "train")
        for s, (held, ood) in sets.items():
            held.save(folder / f"{s}_held")
            for k, d in ood.items():
                d.save(folder / f"{s}_{k}")
    return train, sets


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--robot", default="paper", help="paper, design-b, or a robot file")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--validation-walks", type=int, default=48, help="walks of each OOD kind (validation)")
    ap.add_argument("--test-walks", type=int, default=48, help="walks of each OOD kind (test)")
    ap.add_argument("--bootstrap", type=int, default=500, help="resamples of the validation walks")
    ap.add_argument("--walks-cache", type=Path, default=None, help="a folder to keep the recorded walks in "
                    "and read them from on a rerun with the same robot, seed and walk counts")
    args = ap.parse_args()
    robot = robot_of(args.robot)
    train, sets = recorded(robot, args.seed, args.validation_walks, args.test_walks, args.walks_cache)
    res: dict[str, dict[str, dict[str, float]]] = {}
    walks: dict[str, dict[str, dict[str, list[np.ndarray]]]] = {}
    fitted: dict[str, Uncertainty] = {}
    for part_name, (held, ood) in sets.items():
        res[part_name], walks[part_name] = {}, {}
        for name, (inputs, split) in FORMS.items():
            w, unc = walk_scores(robot, train, held, ood, inputs, split)
            res[part_name][name], walks[part_name][name], fitted[f"{part_name}/{name}"] = aurocs_of(w), w, unc
    picks = {task: choose(walks["validation"], res["validation"], forms, args.bootstrap, args.seed)
             for task, forms in CANDIDATES.items()}
    chosen = {p["chosen"] for p in picks.values()}
    print(f"OOD score on the {robot.name} robot (virtual, defaults, seed {args.seed}; "
          f"{args.validation_walks} validation and {args.test_walks} test walks of each kind): AUROC, "
          "held-out in-range walks against each kind; * the form chosen on validation (FK, IK)")
    print(f"{'walks':10s} {'scored input, parts':40s} {'all':>6s} " + " ".join(f"{k:>11s}" for k in KINDS))
    for part_name, rows in res.items():
        for name, row in rows.items():
            mark = " *" if name in chosen else ""
            print(f"{part_name:10s} {name + mark:40s} {row['all']:6.3f} "
                  + " ".join(f"{row[k]:11.3f}" for k in KINDS))
    for task, p in picks.items():
        for f, a in p["against"].items():
            lo, hi = a["difference_p5_p95"]
            print(f"{task.upper()} validation: {p['chosen']} minus {f}: {a['difference']:+.3f} (bootstrap "
                  f"over walks, 5-95 %: {lo:+.3f} to {hi:+.3f}; wins {a['wins_share']:.2f} of "
                  f"{args.bootstrap})")
    held, ood = sets["test"]
    ik_chosen = picks["ik"]["chosen"]
    dist = combination_distance(robot, train, held, ood["combination"], fitted[f"test/{ik_chosen}"])
    print("unseen combination against held-out walks (test): nearest training row in (β1, β2), mm, median / "
          "90th percentile; the k-NN distance of the IK's part holding the translations over its median")
    for name in ("held_out", "combination"):
        d = dist[name]
        print(f"  {name:12s} {d['nearest_beta_mm_median']:.3f} / {d['nearest_beta_mm_p90']:.3f} mm   "
              f"part {d['joint_part_median']:.2f} / {d['joint_part_p90']:.2f}; rows nearer than the held-out "
              f"rows' 90th percentile {dist[name + '_share_nearer_than_held_out_p90']:.2f}")
    print(json.dumps({"robot": robot.name, "seed": args.seed, "walks_per_kind": {
        "validation": args.validation_walks, "test": args.test_walks}, "chosen": {t: p["chosen"] for t, p in
                                                                               picks.items()},
        "choice": picks, "auroc": res, "combination_distance": dist}))


if __name__ == "__main__":
    main()
