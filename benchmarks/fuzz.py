"""Benchmark: fuzz and fault campaign over the public entry points (issue 9). Goal: 0 crash, 0 silent, 0 hang.

    python benchmarks/fuzz.py                  # ≈ 21,000 seeded inputs, a few minutes on one core
    python benchmarks/fuzz.py --scale 0.02     # a CI-sized slice (tests/test_fuzz.py runs one)
    python benchmarks/fuzz.py --isolate        # each input in a forked process killed at HANG_S
                                               # (for code whose hangs sit in compiled kernels)

Areas: solve, follow, Tube/Robot construction, robot TOML files, learned FK predict and step, IK
predict and step, CSV log import, corrupted dataset folders, corrupted model folders; and (issue 27,
benchmarks/fuzz_folders.py) the output rule of the commands (`output`), folders under file-system
adversity (`fs`: planted links, glob and odd names, leftovers of killed runs, read-only folders, full
disks) and concurrent readers and writers of datasets and model folders (`concurrency`); and (issue 27,
benchmarks/fuzz_inference.py) the inference classes in fk_predict, fk_step and ik (labelled columns,
ragged and empty inputs, interleaved sequence ids, non-unit IK quaternions, absurd start joints, the
ONNX graph's non-finite rows and empty batch) and calls interleaved with a stream's steps
(`interleaved`: batch predicts, a second thread, copies). Every input is drawn from a seeded
generator (--seed) and its outcome classified:

    ok       a result that passes the oracle          clear    a CtrkinError (names what to change)
    flagged  a result marked as doubtful (converged=False, in_workspace=False, projected ...)
    crash    any other exception                      silent   a result that fails the oracle, unflagged
    hang     the input ran longer than HANG_S seconds
    lost     content that was there before (or outside the output) changed or vanished
    mixed    a read that gave neither the old nor the new version of a folder being replaced

Oracles (the issue's sanity checks): a converged equilibrium has a finite tip no farther from the base
than the robot reaches and a unit tip tangent; a single curved tube is on its exact arc (docs/mechanics.md
accuracy); invalid joints (robot limits, NaN, complex) are never accepted; FK step equals FK predict and
recovers after a refused step; IK joints are finite and inside the robot's limits; a CSV import keeps
valid, finite, time-ordered samples and never silently merges or truncates; a corrupted dataset or model
folder either refuses to load or loads exactly the original content.
Prints a table (area × outcome) and, as its last line, a JSON object of the counts.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import math
import os
import shutil
import signal
import sys
import tempfile
import time
import warnings
from collections import Counter, defaultdict
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import tomli_w
import torch

from ctrkin import Robot, Tube, follow, paper_robot, solve
from ctrkin.acquisition.demo import sweep_dataset
from ctrkin.data import Dataset
from ctrkin.data.importer import ImportConfig, import_csv
from ctrkin.data.schema import POSE_COLUMNS
from ctrkin.errors import CtrkinError
from ctrkin.inference import Kinematics
from ctrkin.mechanics.settings import DEFAULT_SETTINGS
from ctrkin.pose import tangent_from_quat
from ctrkin.robots.tube import MAX_STRAIN
from ctrkin.training import TrainConfig, train

sys.path.insert(0, str(Path(__file__).resolve().parent))
import fuzz_folders  # sibling modules of this script
import fuzz_inference

HANG_S = 10.0
OUTCOMES = ("ok", "clear", "flagged", "crash", "silent", "hang", "lost", "mixed")
BAD = ("crash", "silent", "hang", "lost", "mixed")
AREAS = {  # area: inputs at scale 1 (22,340 in all)
    "tube_robot": 7000, "solve": 3000, "toml": 4000, "follow": 200, "fk_predict": 2000, "fk_step": 2000,
    "ik": 1500, "csv": 600, "dataset_folder": 500, "model_folder": 300, **fuzz_folders.COUNTS,
    **fuzz_inference.COUNTS,
}


class Silent(Exception):
    """The oracle rejects a result that came back without a flag."""


class Hang(Exception):
    pass


def _alarm(_sig: int, _frame: object) -> None:
    raise Hang


# --- nasty values ----------------------------------------------------------------------------------

def nasty(rng: np.random.Generator, good: float) -> Any:
    """`good` most of the time, else a value a fuzzer would try."""
    if rng.random() < 0.85:
        return good
    return [0.0, -good, math.nan, math.inf, 1e300, 1e-300, 10**400, good * 1e6, -1e-12, "1.0", None,
            good * (1 + 1e-9)][int(rng.integers(12))]


def plausible_robot(rng: np.random.Generator, n: int | None = None) -> Robot:
    """1-3 nested tubes, curvature 1e-3..3 /mm (log-uniform; 1 in 10 up to 10 /mm), 9 in 10 of them
    held within the wall strain a tube can take (robots.tube.MAX_STRAIN; the others must be refused),
    lengths 5..200 mm."""
    n = n or int(rng.integers(1, 4))
    tubes = []
    od, length = 0.3 + rng.uniform(0, 0.3), 0.0
    lengths = np.sort(rng.uniform(5.0, 200.0, n))[::-1]
    for i in range(n):
        top = 1.0 if rng.random() < 0.1 else 0.5
        kappa = 0.0 if rng.random() < 0.15 else float(10 ** rng.uniform(-3, top))
        if rng.random() < 0.9:
            kappa = min(kappa, 2 * MAX_STRAIN / od)
        total = float(lengths[i]) if i == 0 else min(float(lengths[i]), length)
        curved = float(rng.uniform(0.0, total))
        nu = float(rng.uniform(0, 0.45))
        tubes.append(Tube(od, od * 0.6, total - curved, curved, kappa, poisson_ratio=nu))
        length = total
        od = od / 0.6 + 0.05
    tubes[0] = Tube(tubes[0].od, 0.0 if rng.random() < 0.3 else tubes[0].id, tubes[0].straight_length,
                    tubes[0].curved_length, tubes[0].curvature, poisson_ratio=tubes[0].poisson_ratio)
    return Robot(tuple(tubes), transmission="rigid" if rng.random() < 0.2 else "compliant")


def valid_joints(rng: np.random.Generator, robot: Robot) -> np.ndarray:
    """A uniformly drawn valid q: βN ∈ [−LN, 0], then inward βi ∈ [βi+1 + Li+1 − Li, βi+1]."""
    n, lengths = robot.n_tubes, robot.lengths
    beta = np.zeros(n)
    beta[-1] = rng.uniform(-lengths[-1], 0.0)
    for i in range(n - 2, -1, -1):
        lo = beta[i + 1] + lengths[i + 1] - lengths[i]
        beta[i] = rng.uniform(lo, beta[i + 1])
    return np.r_[rng.uniform(-720, 720, n), beta]


def corrupt_joints(rng: np.random.Generator, q: np.ndarray, robot: Robot) -> tuple[Any, bool]:
    """(joints, still valid?) with one defect most of the time."""
    q = q.copy()
    n = robot.n_tubes
    kind = int(rng.integers(9))
    if kind == 0:
        q[n + int(rng.integers(n))] = rng.uniform(0.1, 50)          # a base in front of the plate
    elif kind == 1:
        q[int(rng.integers(2 * n))] = [math.nan, math.inf, -math.inf][int(rng.integers(3))]
    elif kind == 2:
        return q[:-1], False                                         # wrong length
    elif kind == 3:
        return q.astype(complex) + 1j, False
    elif kind == 4:
        q[n - 1 + int(rng.integers(0, 1))] -= 1.0                    # maybe out of order
    elif kind == 5:
        q[int(rng.integers(n))] = float(rng.choice([1e5, -1e7, 1e200]))
    return q, bool(robot.is_valid(q)[0]) if kind not in (2, 3) else False


def sane_equilibrium(robot: Robot, eq: Any) -> None:
    if not eq.converged:
        return
    n = robot.n_tubes
    reach = float(max((eq.q[n:] + robot.lengths).max(), 0.0))
    tip, tan = np.asarray(eq.tip_position), np.asarray(eq.tip_tangent)
    pose = np.asarray(eq.tip_pose)
    if not (np.isfinite(pose).all() and np.linalg.norm(tip) <= reach * (1 + 1e-6) + 1e-9
            and abs(np.linalg.norm(tan) - 1) < 1e-6 and abs(np.linalg.norm(pose[3:]) - 1) < 1e-6):
        raise Silent(f"insane converged equilibrium: |tip| {np.linalg.norm(tip):.3g} mm, reach {reach:.3g}")


def arc_tip(tube: Tube, beta: float, alpha_deg: float) -> np.ndarray:
    """Exact tip of a single straight-then-curved tube at base β (mm), rotation α (deg)."""
    s0 = max(tube.straight_length + beta, 0.0)
    c = min(tube.curved_length, tube.length + beta)
    k = tube.curvature
    if k == 0.0:
        p = np.array([0.0, 0.0, s0 + c])
    else:
        p = np.array([0.0, -(1 - math.cos(k * c)) / k, s0 + math.sin(k * c) / k])
    a = math.radians(math.fmod(alpha_deg, 360.0))   # α degrees, not radians(α)'s rounded product
    return np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]]) @ p


# --- areas -----------------------------------------------------------------------------------------

def case_tube_robot(rng: np.random.Generator, ctx: dict[str, Any]) -> str:
    kw = {"od": nasty(rng, 1.0), "id": nasty(rng, 0.6), "straight_length": nasty(rng, 40.0),
          "curved_length": nasty(rng, 20.0), "curvature": nasty(rng, float(10 ** rng.uniform(-3, 1.5))),
          "youngs_modulus": nasty(rng, 58.0), "poisson_ratio": nasty(rng, 0.33)}
    tube = Tube(**kw)
    robot = Robot((tube,))
    q = np.r_[rng.uniform(-360, 360), rng.uniform(-tube.length, 0.0)]
    eq = solve(robot, q)
    return _check_single_arc(robot, q, eq)


def _check_single_arc(robot: Robot, q: np.ndarray, eq: Any) -> str:
    sane_equilibrium(robot, eq)
    if not eq.converged:
        return "flagged"
    t = robot.tubes[0]
    if tuple(t.sections) == tuple(Tube(t.od, t.id, t.straight_length, t.curved_length, t.curvature).sections):
        err = float(np.linalg.norm(eq.tip_position - arc_tip(t, q[1], q[0])))
        tol = DEFAULT_SETTINGS.tip_tol or 0.0       # the solver's stated tip tolerance (mm)
        if err > tol + 3e-6 * t.curved_length + 1e-6 * (1 + t.length):
            raise Silent(f"single tube {err:.3g} mm off its exact arc (κ = {t.curvature:.3g}/mm)")
    return "ok"


def case_solve(rng: np.random.Generator, ctx: dict[str, Any]) -> str:
    robot = plausible_robot(rng)
    q = valid_joints(rng, robot)
    valid = True
    if rng.random() < 0.25:
        q, valid = corrupt_joints(rng, q, robot)
    eq = solve(robot, q)
    if not valid:
        raise Silent(f"invalid joints {q!r} accepted")
    if robot.n_tubes == 1:
        return _check_single_arc(robot, np.asarray(q, float), eq)
    sane_equilibrium(robot, eq)
    return "ok" if eq.converged else "flagged"


def case_toml(rng: np.random.Generator, ctx: dict[str, Any]) -> str:
    text = tomli_w.dumps(plausible_robot(rng).to_dict())
    kind = int(rng.integers(8))
    if kind == 0:
        a = int(rng.integers(len(text)))
        text = text[:a] + text[a + int(rng.integers(1, 20)):]
    elif kind == 1:
        text = text.replace("curvature = ", f"curvature = {rng.choice(['-', '1e400', 'nan', '[1,2]'])}", 1)
    elif kind == 2:
        text += "\n[[tubes]]\nod = 1.0\nid = 0.5\nsections = [[10.0]]\n"
    elif kind == 3:
        text = "x = " + "[" * int(rng.integers(100, 5000)) + "]" * 3 + "\n"
    elif kind == 4:
        text = text.replace("od = ", "od = 1e300 #", 1)
    elif kind == 5:
        text = text.replace("straight_length = ", "straight_length = 1e10 #", 1)
    elif kind == 6:
        raw = bytearray(text.encode())
        for _ in range(int(rng.integers(1, 6))):
            raw[int(rng.integers(len(raw)))] = int(rng.integers(256))
        text = raw.decode(errors="replace")
    path = ctx["tmp"] / "robot.toml"
    path.write_text(text)
    robot = Robot.from_toml(path)
    robot.to_toml(ctx["tmp"] / "back.toml")
    if Robot.from_toml(ctx["tmp"] / "back.toml") != robot:
        raise Silent("a loaded robot file does not round-trip")
    return "ok"


def case_follow(rng: np.random.Generator, ctx: dict[str, Any]) -> str:
    robot = paper_robot() if rng.random() < 0.5 else plausible_robot(rng, int(rng.integers(2, 4)))
    q0 = valid_joints(rng, robot)
    steps = int(rng.integers(0, 12)) if rng.random() < 0.1 else int(rng.integers(2, 12))
    Q = [q0]
    for _ in range(steps - 1):
        nxt = Q[-1] + np.r_[rng.normal(0, 5, robot.n_tubes), rng.normal(0, 0.5, robot.n_tubes)]
        Q.append(robot.project_joints(nxt[None])[0])
    Qa = np.array(Q[:steps]).reshape(steps, 2 * robot.n_tubes)
    start, foreign = None, False
    r = rng.random()
    if r < 0.15:
        other = plausible_robot(rng, robot.n_tubes if rng.random() < 0.7 else max(1, robot.n_tubes - 1))
        start, foreign = solve(other, valid_joints(rng, other)), other != robot
    elif r < 0.4:
        start = solve(robot, valid_joints(rng, robot))
    traj = follow(robot, Qa, start=start)
    if foreign:
        raise Silent("a start solved on another robot was accepted")
    if steps == 0:
        raise Silent("an empty trajectory gave a result")
    for eq in traj.equilibria:
        sane_equilibrium(robot, eq)
    return "ok" if traj.converged.all() else "flagged"


def _fk_seq(rng: np.random.Generator, robot: Robot) -> tuple[Any, bool]:
    m = int(rng.integers(1, 25))
    q = valid_joints(rng, robot)
    q[0], q[1] = rng.uniform(0, 400), rng.uniform(0, 80)
    Q = np.repeat(q[None], m, axis=0)
    Q[:, 0] += np.cumsum(rng.normal(0, 4, m))
    if rng.random() < 0.3:
        Q[:, : robot.n_tubes] += 360.0 * rng.integers(-3000, 3000, robot.n_tubes)
    if rng.random() < 0.3:
        row = int(rng.integers(m))
        bad, valid = corrupt_joints(rng, Q[row], robot)
        if np.shape(bad) != Q[row].shape or np.iscomplexobj(bad):
            return bad[None] if np.ndim(bad) == 1 else bad, False
        Q[row] = bad
        return Q, valid
    return Q, True


def case_fk_predict(rng: np.random.Generator, ctx: dict[str, Any]) -> str:
    if rng.random() < 0.3:
        return fuzz_inference.fk_predict_input(rng, ctx)
    fk: Kinematics = ctx["fk"]
    Q, valid = _fk_seq(rng, fk.robot)
    poses = fk.predict(Q)
    if not valid:
        raise Silent("FK predicted a pose for joints the robot cannot take")
    if not np.isfinite(poses).all():
        raise Silent("FK predict returned NaN")
    fk.reset()
    stream = np.array([fk.step(q) for q in Q])
    if np.abs(stream - poses).max() > 1e-4:
        raise Silent(f"FK step differs from predict by {np.abs(stream - poses).max():.3g}")
    return "ok"


def case_fk_step(rng: np.random.Generator, ctx: dict[str, Any]) -> str:
    """Stream a valid sequence with a bad step injected; the steps after it must equal the clean run."""
    if rng.random() < 0.2:
        return fuzz_inference.fk_step_input(rng, ctx)
    fk: Kinematics = ctx["fk"]
    Q, _ = _fk_seq(rng, fk.robot)
    Q = np.asarray(Q)
    if Q.shape[-1:] != (4,) or np.iscomplexobj(Q) or not fk.robot.is_valid(Q).all():
        Q = np.repeat(np.r_[30.0, 0.0, -20.0, -5.0][None], 3, axis=0)
    fk.reset()
    clean = np.array([fk.step(q) for q in Q])
    fk.reset()
    k = int(rng.integers(len(Q)))
    bad, valid = corrupt_joints(rng, Q[k], fk.robot)
    out, refused = [], False
    for t, q in enumerate(Q):
        if t == k:
            try:
                fk.step(bad)
                if not valid:
                    raise Silent(f"FK step accepted invalid joints {bad!r}")
                fk.reset()
                return "ok"                       # a valid variation: nothing more to compare
            except CtrkinError:
                refused = True
        out.append(fk.step(q))
    if np.abs(np.array(out) - clean).max() > 1e-9:
        raise Silent("FK streaming state was changed by a refused step")
    return "clear" if refused else "ok"


def case_ik(rng: np.random.Generator, ctx: dict[str, Any]) -> str:
    if rng.random() < 0.3:
        return fuzz_inference.ik_input(rng, ctx)
    ik: Kinematics = ctx["ik"]
    targets = ctx["ik_targets"]
    m = int(rng.integers(1, 12))
    a = int(rng.integers(len(targets) - m))
    T = targets[a:a + m].copy()
    T[:, :3] += rng.normal(0, [0.1, 1.0, 5.0, 30.0][int(rng.integers(4))], (m, 3))
    if rng.random() < 0.15:
        T[int(rng.integers(m)), int(rng.integers(6))] = [math.nan, math.inf, 1e300][int(rng.integers(3))]
    if rng.random() < 0.5:
        res = ik.predict(T)
        joints, flagged = res.joints, ~np.asarray(res.in_workspace)
        if res.projected is not None:
            flagged |= np.asarray(res.projected)
    else:
        ik.reset()
        steps = [ik.step(t) for t in T]
        joints = np.array([s.joints for s in steps])
        flagged = np.array([(not s.in_workspace) or s.projected for s in steps])
    if not np.isfinite(T).all():
        raise Silent("IK answered a NaN/inf target")
    if not (np.isfinite(joints).all() and ik.robot.is_valid(joints).all()):
        raise Silent("IK returned joints outside the robot's limits")
    return "flagged" if flagged.any() else "ok"


def case_csv(rng: np.random.Generator, ctx: dict[str, Any]) -> str:
    log: pd.DataFrame = ctx["log"].copy()
    text_cells = log.astype(object)
    kind = int(rng.integers(9))
    expect_error = False
    if kind == 0:
        r, c = int(rng.integers(len(log))), str(rng.choice(log.columns))
        text_cells.loc[r, c] = str(rng.choice(["abc", "", "nan", "1e400", "inf", "--1", "1,5", "0x10"]))
    elif kind == 1:
        text_cells["step"] = 2**53 + np.arange(len(log)) // 5
        expect_error = True
    elif kind == 2:
        r = int(rng.integers(len(log)))
        cell = f"({rng.normal():.3f}+{rng.uniform(0.1, 2):.3f}j)"
        text_cells.loc[r, str(rng.choice(["alpha_1", "beta_1", "x"]))] = cell
        expect_error = True
    elif kind == 3:
        order = rng.permutation(len(text_cells))
        text_cells = text_cells.iloc[order].reset_index(drop=True)
    elif kind == 4:
        text_cells = text_cells.drop(columns=[str(rng.choice(log.columns))])
    elif kind == 5:
        text_cells.loc[int(rng.integers(len(log))), "beta_2"] = float(rng.uniform(0.1, 30))
    path = ctx["tmp"] / "log.csv"
    text = text_cells.to_csv(index=False, float_format="%.17g")
    if kind == 6:
        text = text[: int(rng.integers(len(text)))]
    elif kind == 7:
        raw = bytearray(text.encode())
        for _ in range(int(rng.integers(1, 8))):
            raw[int(rng.integers(len(raw)))] = int(rng.integers(256))
        path.write_bytes(bytes(raw))
    if kind != 7:
        path.write_text(text)
    ds = import_csv(path, ctx["robot"], ImportConfig())
    if expect_error:
        raise Silent("a log with steps >= 2^53 or complex values was imported")
    q = ds.joints()
    if not (ctx["robot"].is_valid(q).all() and np.isfinite(ds.poses()).all()):
        raise Silent("imported samples with invalid joints or non-finite poses")
    if len(ds.frame) > len(log):
        raise Silent("more samples than log rows")
    return "flagged" if ds.frame["outlier"].any() else "ok"


def case_dataset_folder(rng: np.random.Generator, ctx: dict[str, Any]) -> str:
    src: Path = ctx["dataset_dir"]
    folder = ctx["tmp"] / "ds"
    if folder.exists():
        shutil.rmtree(folder)
    for p in ctx["tmp"].glob(".ds.*"):
        shutil.rmtree(p) if p.is_dir() else p.unlink()
    shutil.copytree(src, folder)
    kind = int(rng.integers(7))
    if kind == 0:
        f = folder / "data.parquet"
        f.write_bytes(f.read_bytes()[: int(rng.integers(f.stat().st_size))])
    elif kind == 1:
        f = folder / "meta.json"
        f.write_text(f.read_text()[: int(rng.integers(200))])
    elif kind == 2:
        meta = json.loads((folder / "meta.json").read_text())
        meta["robot"]["tubes"][int(rng.integers(2))]["curvature"] *= float(rng.uniform(1.01, 2))
        (folder / "meta.json").write_text(json.dumps(meta))
    elif kind == 3:
        folder.rename(ctx["tmp"] / ".ds.old-0badc0de")        # killed between the swap's renames
    elif kind == 4:
        f = folder / "data.parquet"
        raw = bytearray(f.read_bytes())
        for _ in range(int(rng.integers(1, 16))):
            raw[int(rng.integers(len(raw)))] ^= 1 << int(rng.integers(8))
        f.write_bytes(bytes(raw))
    elif kind == 5:
        (folder / "meta.json").unlink()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ds = Dataset.load(folder)
    ref: Dataset = ctx["dataset"]
    same = (ds.frame.shape == ref.frame.shape and (ds.frame.to_numpy() == ref.frame.to_numpy()).all()
            and ds.robot == ref.robot)
    if not same:
        raise Silent(f"a corrupted dataset folder (kind {kind}) loaded with other content")
    return "ok"


def case_model_folder(rng: np.random.Generator, ctx: dict[str, Any]) -> str:
    src: Path = ctx["fk_dir"]
    folder = ctx["tmp"] / "model"
    if folder.exists():
        shutil.rmtree(folder)
    shutil.copytree(src, folder)
    name = str(rng.choice(["weights.pt", "normalization.json", "config.json", "features.json", "robot.json"]))
    kind = int(rng.integers(5))
    f = folder / name
    if kind == 0:
        f.write_bytes(f.read_bytes()[: int(rng.integers(f.stat().st_size))])
    elif kind == 1:
        shutil.copy2(ctx["fk_other_dir"] / name, f)          # a file of another training
    elif kind == 2 and name.endswith(".json"):
        d = json.loads(f.read_text())
        f.write_text(json.dumps(d, indent=1))                # reformatted only: same content
    elif kind == 3:
        raw = bytearray(f.read_bytes())
        raw[int(rng.integers(len(raw)))] ^= 0x20
        f.write_bytes(bytes(raw))
    kin = Kinematics.load(folder)
    got = kin.predict(ctx["fk_probe"])
    if np.abs(got - ctx["fk_probe_poses"]).max() > 1e-9 or kin.robot != ctx["fk"].robot:
        raise Silent(f"a model folder with a changed {name} (kind {kind}) loaded and predicts otherwise")
    return "ok"


CASES: dict[str, Callable[[np.random.Generator, dict[str, Any]], str]] = {
    "tube_robot": case_tube_robot, "solve": case_solve, "toml": case_toml, "follow": case_follow,
    "fk_predict": case_fk_predict, "fk_step": case_fk_step, "ik": case_ik, "csv": case_csv,
    "dataset_folder": case_dataset_folder, "model_folder": case_model_folder, **fuzz_folders.CASES,
    **fuzz_inference.CASES,
}


# --- set-up and run --------------------------------------------------------------------------------

def setup(tmp: Path, seed: int) -> dict[str, Any]:
    """Small trained FK/IK models, a saved dataset and a CSV log of the paper robot (≈ 15 s)."""
    torch.set_num_threads(1)        # also keeps forked children (--isolate) clear of thread pools
    robot = paper_robot()
    ds = sweep_dataset(robot, translations=(8, 16), outer_alphas=(0, 60), step_deg=6, noise_mm=0.02,
                       seed=seed)
    ctx: dict[str, Any] = {"tmp": tmp, "robot": robot, "dataset": ds, "dataset_dir": tmp / "dataset"}
    ds.save(ctx["dataset_dir"])
    ctx["dataset"] = Dataset.load(ctx["dataset_dir"])
    small = {"structure": "L8|D8"}
    with contextlib.redirect_stdout(io.StringIO()):
        for name, cfg in {"fk": TrainConfig(task="fk", max_epochs=2, threads=1, options=small, seed=seed),
                          "fk_other": TrainConfig(task="fk", max_epochs=2, threads=1, options=small,
                                                  seed=seed + 1, split="random"),
                          "ik": TrainConfig(task="ik", max_epochs=2, threads=1, options=small,
                                            seed=seed)}.items():
            train(ds, cfg, tmp / name, progress=False)
            ctx[f"{name}_dir"] = tmp / name
    ctx["fk"], ctx["ik"] = Kinematics.load(tmp / "fk"), Kinematics.load(tmp / "ik")
    ctx["fk_probe"] = ds.joints()[:20]
    ctx["fk_probe_poses"] = ctx["fk"].predict(ctx["fk_probe"])
    ctx["ik_targets"] = ds.poses()
    poses = ds.poses()[:40]
    q = ds.joints()[:40]
    reps = np.repeat(np.arange(40), 5)
    ctx["log"] = pd.DataFrame({"step": reps, **{c: q[reps, j] for j, c in enumerate(robot.joint_names())},
                               **{c: poses[reps, j] for j, c in enumerate(POSE_COLUMNS)}})
    fuzz_folders.setup(ctx, seed)
    fuzz_inference.setup(ctx, seed)
    assert np.allclose(np.linalg.norm(tangent_from_quat(poses[:, 3:]), axis=1), 1.0)
    return ctx


def run(scale: float, seed: int, log: Callable[[str], None] = print, isolate: bool = False,
        only: tuple[str, ...] = (), slow_s: float | None = None) -> dict[str, Counter[str]]:
    """Counts of outcomes per area; input i of area k draws from its own generator (seed, k, i).
    only: run these areas alone (the same inputs as in a whole run); slow_s: log every input that
    takes longer than this (s), with its index and outcome."""
    counts: dict[str, Counter[str]] = defaultdict(Counter)
    examples: dict[tuple[str, str], str] = {}
    old = signal.signal(signal.SIGALRM, _alarm)
    with tempfile.TemporaryDirectory() as d:
        ctx = setup(Path(d), seed)
        for k, (area, n) in enumerate(AREAS.items()):
            if only and area not in only:
                continue
            t0 = time.perf_counter()
            for i in range(max(1, round(n * scale))):
                rng = np.random.default_rng([seed, k, i])
                t1 = time.perf_counter()
                outcome, note = (_isolated if isolate else _one)(CASES[area], rng, ctx)
                if slow_s is not None and time.perf_counter() - t1 > slow_s:
                    log(f"  {area} input {i}: {outcome} in {time.perf_counter() - t1:.1f} s")
                counts[area][outcome] += 1
                if outcome in BAD:
                    examples.setdefault((area, note[:60]), note)
            log(f"{area:15s} {sum(counts[area].values()):6d} inputs in {time.perf_counter() - t0:6.1f} s")
    signal.signal(signal.SIGALRM, old)
    for (area, _), note in sorted(examples.items())[:40]:
        log(f"  {area}: {note}")
    return counts


def _one(fn: Callable[[np.random.Generator, dict[str, Any]], str], rng: np.random.Generator,
         ctx: dict[str, Any]) -> tuple[str, str]:
    t0 = time.perf_counter()
    signal.setitimer(signal.ITIMER_REAL, HANG_S)
    note = ""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            outcome = fn(rng, ctx)
    except (Hang, fuzz_folders.Hang) as e:
        outcome, note = "hang", str(e)
    except (Silent, fuzz_folders.Silent, fuzz_inference.Silent) as e:
        outcome, note = "silent", str(e)
    except fuzz_folders.Lost as e:
        outcome, note = "lost", str(e)
    except fuzz_folders.Mixed as e:
        outcome, note = "mixed", str(e)
    except fuzz_folders.Crash as e:
        outcome, note = "crash", str(e)
    except CtrkinError:
        outcome = "clear"
    except Exception as e:  # every other exception is what we count as a crash
        outcome, note = "crash", f"{type(e).__name__}: {str(e)[:120]}"
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
    if time.perf_counter() - t0 > HANG_S:
        outcome = "hang"
    return outcome, note


def _isolated(fn: Callable[[np.random.Generator, dict[str, Any]], str], rng: np.random.Generator,
              ctx: dict[str, Any]) -> tuple[str, str]:
    """_one in a forked child, SIGKILLed after HANG_S: a hang inside a compiled kernel, which no
    Python signal interrupts, is counted instead of stopping the campaign."""
    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:                                   # child
        os.close(r)
        try:
            res: tuple[str, str] = _one(fn, rng, ctx)
        except BaseException as e:
            res = ("crash", f"{type(e).__name__}")
        os.write(w, json.dumps(res).encode()[:60000])
        os._exit(0)
    os.close(w)
    deadline = time.monotonic() + HANG_S
    while os.waitpid(pid, os.WNOHANG)[0] == 0:
        if time.monotonic() > deadline:
            os.kill(pid, signal.SIGKILL)
            os.waitpid(pid, 0)
            os.close(r)
            return "hang", f"killed after {HANG_S:g} s"
        time.sleep(0.001)
    data = os.read(r, 65536)
    os.close(r)
    if not data:
        return "crash", "the process died"
    outcome, note = json.loads(data)
    return str(outcome), str(note)


def table(counts: dict[str, Counter[str]]) -> str:
    lines = [f"{'area':15s} " + " ".join(f"{o:>8s}" for o in OUTCOMES) + f" {'total':>8s}"]
    total: Counter[str] = Counter()
    for area in AREAS:
        if area not in counts:
            continue
        c = counts[area]
        total.update(c)
        lines.append(f"{area:15s} " + " ".join(f"{c[o]:8d}" for o in OUTCOMES) + f" {sum(c.values()):8d}")
    cells = " ".join(f"{total[o]:8d}" for o in OUTCOMES)
    lines.append(f"{'all':15s} {cells} {sum(total.values()):8d}")
    return "\n".join(lines)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--scale", type=float, default=1.0, help="fraction of the default input counts")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--isolate", action="store_true", help="one forked process per input")
    ap.add_argument("--areas", default="", help="comma-separated areas to run alone (default: all)")
    ap.add_argument("--slow", type=float, default=None, metavar="S",
                    help="print every input that takes longer than S seconds")
    args = ap.parse_args()
    t0 = time.perf_counter()
    only = tuple(a for a in args.areas.split(",") if a)
    unknown = sorted(set(only) - set(AREAS))
    if unknown:
        ap.error(f"unknown area(s) {unknown}; areas: {list(AREAS)}")
    counts = run(args.scale, args.seed, isolate=args.isolate, only=only, slow_s=args.slow)
    print(table(counts))
    total: Counter[str] = Counter()
    for c in counts.values():
        total.update(c)
    print(f"{sum(total.values())} inputs in {time.perf_counter() - t0:.0f} s")
    print(json.dumps({"inputs": sum(total.values()), **{o: total[o] for o in OUTCOMES},
                      "by_area": {a: dict(c) for a, c in counts.items()}}))
    return 0 if sum(total[o] for o in BAD) == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
