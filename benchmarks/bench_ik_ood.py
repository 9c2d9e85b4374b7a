"""The IK's out-of-distribution score (issue 24, goal 2): AUROC of held-out in-range walks against
each out-of-distribution kind, for the score on the target pose alone (the IK's score before, an
uncertainty file of format 1) and the joint-aware score (the pose and the robot's joints when it
was asked, ctrkin.models.ood) with its two splits into k-NN parts; and how far the "unseen
combination" walks lie from the training rows.

    python benchmarks/bench_ik_ood.py                          # paper robot, quick walks (~2 min)
    python benchmarks/bench_ik_ood.py --robot design-b         # bench_generalisation's second design
    python benchmarks/bench_ik_ood.py --robot examples/robots/comet_nylon_ndi.toml

The walks, regions and AUROC are benchmarks/learned_loop.py's (quick sizes: 24 training walks of 120
steps, 48 held-out walks of 40, 12 of each OOD kind), recorded on the virtual robot at its defaults.
The score is the library's (ctrkin.inference.uncertainty.scored_inputs: from a recording, the joints
when a pose was asked are the row before's). No model is trained: the score reads only the inputs
(the IK's errors set its interval, not its OOD score), so the errors passed are zeros.

The form is chosen on validation walks (a second held-out set and a second set of each OOD kind,
other seeds): the form with the larger validation AUROC over every kind. The test walks report every
form; the chosen one is marked. Calibrated on the first half of each held-out set, scored on the
other half. Ends with one JSON line.
"""

from __future__ import annotations

import argparse
import json
import os
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
         "pose + joints, fine": ("pose+joints", "fine")}


def bounds(ds: Dataset) -> list[tuple[int, int]]:
    return row_runs(ds.frame["sequence_id"].to_numpy(), np.arange(len(ds.frame)))


def scored(ds: Dataset, inputs: str) -> np.ndarray:
    """The scored inputs of every row (ctrkin.inference.uncertainty.scored_inputs without a model)."""
    pose = ds.poses()
    return pose if inputs == "pose" else np.hstack([pose, joints_before(ds.joints(), ds.sequence_bounds())])


def robot_of(spec: str) -> Robot:
    if spec == "paper":
        return paper_robot()
    if spec == "design-b":
        from bench_generalisation import design_b

        return design_b()
    return load_robot(spec)


def record(robot: Robot, vr: VirtualRobot, rng: np.random.Generator, seed: int, first_id: int
           ) -> tuple[Dataset, dict[str, Dataset]]:
    """Held-out in-range walks and walks of each OOD kind (one set: validation or test)."""
    reg = learned_loop.regions(robot)
    held = learned_loop.record_walks(vr, learned_loop.region_walks(robot, rng, reg["train"], 48, 40), seed,
                                     first_id=first_id)
    ood = {k: learned_loop.record_walks(vr, learned_loop.region_walks(robot, rng, reg[k], 12, 40),
                                        seed + 1 + i, first_id=first_id + 1000 * (i + 1))
           for i, k in enumerate(KINDS)}
    return held, ood


def aurocs(robot: Robot, train: Dataset, held: Dataset, ood: dict[str, Dataset], inputs: str, split: str
           ) -> tuple[dict[str, float], Uncertainty]:
    """AUROC of the form, calibrated on the first half of the held-out walks, against each kind."""
    hb = bounds(held)
    half = len(hb) // 2
    cut = hb[half][0]
    test_bounds = [(a - cut, b - cut) for a, b in hb[half:]]
    x = scored(held, inputs)
    unc = Uncertainty.fit("ik", robot.n_tubes, scored(train, inputs), bounds(train), x[:cut], hb[:half],
                          np.zeros((cut, robot.n_joints)), inputs=inputs, split=split)
    inside = unc.ood_scores(x[cut:], test_bounds)
    outside = {k: unc.ood_scores(scored(d, inputs), bounds(d)) for k, d in ood.items()}
    row = {"all": learned_loop.auroc(inside, np.concatenate(list(outside.values())))}
    return row | {k: learned_loop.auroc(inside, v) for k, v in outside.items()}, unc


def combination_distance(robot: Robot, train: Dataset, held: Dataset, combo: Dataset,
                         unc: Uncertainty) -> dict[str, Any]:
    """How far the unseen-combination walks lie from the training rows, against held-out walks: the
    nearest training row in the two translations (mm), and the k-NN distance of the part that holds
    the translations over its calibration median (the score's own measure of that part)."""
    n = robot.n_tubes
    tb = train.joints()[:, n:]

    def nearest_mm(q: np.ndarray) -> np.ndarray:
        d = np.linalg.norm(q[:, n:][:, None, :] - tb[None, ::3, :], axis=2)
        return d.min(axis=1)

    def part(ds: Dataset) -> np.ndarray:
        z = (sequence_features(unc.inputs, n, scored(ds, unc.inputs), bounds(ds)) - unc.center) / unc.spread
        col = 6 + 2 * (n - 1)                               # the first translation's column
        p = int(np.searchsorted(unc.parts, col, side="right")) - 1
        lo, hi = int(unc.parts[p]), int(unc.parts[p + 1])
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


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--robot", default="paper", help="paper, design-b, or a robot file")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    robot = robot_of(args.robot)
    vr = VirtualRobot(robot, seed=args.seed)
    rng = np.random.default_rng(args.seed)
    reg = learned_loop.regions(robot)
    train = learned_loop.record_walks(vr, learned_loop.region_walks(robot, rng, reg["train"], 24, 120),
                                      args.seed + 1)
    sets = {"validation": record(robot, vr, rng, args.seed + 10, 10_000),
            "test": record(robot, vr, rng, args.seed + 20, 20_000)}
    res: dict[str, dict[str, dict[str, float]]] = {}
    fitted: dict[str, Uncertainty] = {}
    for part_name, (held, ood) in sets.items():
        res[part_name] = {}
        for name, (inputs, split) in FORMS.items():
            row, unc = aurocs(robot, train, held, ood, inputs, split)
            res[part_name][name], fitted[f"{part_name}/{name}"] = row, unc
    joint_forms = [f for f in FORMS if FORMS[f][0] == "pose+joints"]
    chosen = max(joint_forms, key=lambda f: res["validation"][f]["all"])
    print(f"IK OOD score on the {robot.name} robot (virtual, defaults, seed {args.seed}): AUROC, held-out "
          f"in-range walks against each kind; the joint-aware form chosen on validation: {chosen}")
    print(f"{'walks':10s} {'scored input, parts':32s} {'all':>6s} " + " ".join(f"{k:>11s}" for k in KINDS))
    for part_name, rows in res.items():
        for name, row in rows.items():
            mark = " *" if name == chosen else ""
            print(f"{part_name:10s} {name + mark:32s} {row['all']:6.3f} "
                  + " ".join(f"{row[k]:11.3f}" for k in KINDS))
    held, ood = sets["test"]
    dist = combination_distance(robot, train, held, ood["combination"], fitted[f"test/{chosen}"])
    print("unseen combination against held-out walks (test): nearest training row in (β1, β2), mm, median / "
          "90th percentile; the k-NN distance of the part holding the translations over its median")
    for name in ("held_out", "combination"):
        d = dist[name]
        print(f"  {name:12s} {d['nearest_beta_mm_median']:.3f} / {d['nearest_beta_mm_p90']:.3f} mm   "
              f"part {d['joint_part_median']:.2f} / {d['joint_part_p90']:.2f}; rows nearer than the held-out "
              f"rows' 90th percentile {dist[name + '_share_nearer_than_held_out_p90']:.2f}")
    print(json.dumps({"robot": robot.name, "seed": args.seed, "chosen": chosen, "auroc": res,
                      "combination_distance": dist}))


if __name__ == "__main__":
    main()
