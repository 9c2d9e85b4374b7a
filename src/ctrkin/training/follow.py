"""Training of the follow IK (ctrkin.models.follow): MAE on the joint change from perturbed current
joints to the true next joints, a fresh perturbation every epoch, early stopping on a fixed
perturbed validation draw. Writes the same model folder as ctrkin.training.loop (plus workspace.npz
and the outer-tube frame); a finished folder of the same configuration and data is reused. The
network is rolled out and scored by its stepper in the model package (ctrkin.models.follower), the
one inference runs: training produces a model folder and imports nothing of ctrkin.inference.

Unlike the generic loop it keeps no per-epoch checkpoint: a killed run starts over (the quick
budget trains in about a minute), and the previous model stays in place until the new one is swapped in.
"""

from __future__ import annotations

import csv
import shutil
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import torch
from tqdm.auto import tqdm

from ctrkin.data.dataset import Dataset
from ctrkin.data.schema import sequence_bounds
from ctrkin.errors import ModelError
from ctrkin.metrics import metrics_json_joint_errors
from ctrkin.models.features import check_raw
from ctrkin.models.follow import follow_features, joint_noise, previous_rows
from ctrkin.models.follower import Follower
from ctrkin.models.normalize import MinMax
from ctrkin.models.store import CONFIG, ModelBundle, read_json, write_json
from ctrkin.models.workspace import Workspace
from ctrkin.training.config import TrainConfig
from ctrkin.training.curves import plot_curves
from ctrkin.training.data import data_signature, inputs_and_targets, outer_frame, split_rows
from ctrkin.training.loop import (
    TrainResult,
    _epoch,
    _epoch_gathered,
    _learning_rate,
    _optimizer,
    _write_history,
    setup_differences,
    split_signature,
)
from ctrkin.util.folders import swap_in, write_manifest
from ctrkin.util.ownership import write_marker
from ctrkin.util.progress import progress_bar

SETTLE_ITERATIONS = 5        # net applications at a sequence start (from the nearest training joints)
STEP_QUANTILE = 0.95         # sub-step length: this quantile of the training targets' step lengths
# rollouts (DAgger-like): at these fractions of the epochs the network follows the training sequences
# and from then on part of each epoch starts from the joints it reached, where it stayed near the
# recorded branch: training then covers the states its own errors lead to
ROLLOUT_AT = (0.5, 0.75)
ONPOLICY_FRACTION = 0.5
ONPOLICY_DEG, ONPOLICY_MM = 20.0, 2.0


def train_follow(ds: Dataset, cfg: TrainConfig, out: Path, overwrite: bool, progress: bool,
                 log: Any) -> TrainResult:
    """Train the follow IK `cfg` on `ds` into `out` (caller holds the folder lock)."""
    say = log or (lambda _m: None)
    if cfg.val_smoothing or cfg.max_seconds is not None:
        raise ModelError("the follow IK's training takes no val_smoothing or max_seconds (its epochs "
                         "are cheap; set max_epochs and patience)")
    torch.set_num_threads(cfg.threads)
    n = ds.n_tubes
    split, rows = split_rows(ds, cfg)
    signature, split_sig = data_signature(ds), split_signature(rows)
    reused = _reusable(out, cfg, signature, split_sig, overwrite)
    if reused is not None:
        say(f"{out} already holds this follow IK; reusing it")
        return reused
    poses, joints = inputs_and_targets(ds, "ik", cfg.pose_source)
    bounds = ds.sequence_bounds()
    prev = previous_rows(bounds)
    tr, va = rows["train"], rows["val"]
    lagged, _ = outer_frame(ds, joints, poses, tr, cfg.seed)   # the follower inverts the outer lag
    frame = replace(lagged, lag=(0.0, 0.0))                      # the network's frame: the commanded αN

    visited: np.ndarray | None = None     # (T, 2N) the follower's own joints before each row (rollouts)

    def draw(r: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """Features and joint changes of rows r from perturbed current joints, half of them (after a
        rollout, where it stayed on the recorded branch) from the joints the follower itself reached."""
        current = joints[prev[r]] + joint_noise(rng, len(r), n)
        if visited is not None:
            own = visited[prev[r]]
            near = _on_branch(own, joints[prev[r]], n) & (rng.random(len(r)) < ONPOLICY_FRACTION)
            current[near] = own[near]
        return follow_features(frame, n, poses[r], poses[prev[r]], current), joints[r] - current

    rng = np.random.default_rng(cfg.seed)
    X, Y = draw(tr, rng)
    x_norm, y_norm = MinMax.fit(X), MinMax.fit(Y)

    def tensors(x: np.ndarray, y: np.ndarray) -> tuple[torch.Tensor, torch.Tensor]:
        return (torch.from_numpy(x_norm.transform(x)[:, None, :].astype(np.float32)),
                torch.from_numpy(y_norm.transform(y).astype(np.float32)))

    Xv, Yv = tensors(*draw(va, np.random.default_rng(cfg.seed + 1)))
    steps = np.linalg.norm(poses[tr, :3] - poses[prev[tr], :3], axis=1)
    moved = steps[steps > 0]
    follow = {"max_step_mm": float(np.quantile(moved, STEP_QUANTILE)) if len(moved) else 1.0,
              "settle_iterations": SETTLE_ITERATIONS, "outer_lag_deg": list(lagged.lag)}
    torch.manual_seed(cfg.seed)
    bundle = ModelBundle.create(cfg.to_dict(), cfg.layout(n), x_norm, y_norm, ds.robot,
                                {"data": {"signature": signature, "split_signature": split_sig,
                                          "samples": len(ds.frame), "source": str(ds.meta.get("path", "")),
                                          "protocol": ds.meta.get("protocol")},
                                 "follow": follow}, frame=frame)
    net = bundle.net
    opt = _optimizer(net, cfg)
    run_epoch = _epoch_gathered if cfg.loop == "epoch" else _epoch
    gen = torch.Generator().manual_seed(cfg.seed)
    history: list[dict[str, float]] = []
    best = (float("inf"), 0, {k: v.clone() for k, v in net.state_dict().items()})
    seconds = 0.0
    bar = (progress_bar(total=cfg.max_epochs, desc=f"train ik {cfg.model}") if progress
           else tqdm(disable=True))
    with bar:
        rollouts = {int(cfg.max_epochs * f) for f in ROLLOUT_AT} - {0}
        for epoch in range(cfg.max_epochs):
            t0 = time.perf_counter()
            if epoch in rollouts:
                net.eval()
                visited = _rollout(bundle, poses, joints, bounds, tr)
            if epoch:
                X, Y = draw(tr, rng)
            for group in opt.param_groups:
                group["lr"] = _learning_rate(cfg, epoch)
            train_loss = run_epoch(net, opt, *tensors(X, Y), cfg.batch_size, gen)
            net.eval()
            with torch.inference_mode():
                val_loss = float(torch.mean(torch.abs(net(Xv) - Yv)))
            seconds += time.perf_counter() - t0
            history.append({"epoch": epoch + 1, "train_loss": train_loss, "val_loss": val_loss,
                            "seconds": seconds})
            if val_loss < best[0] - cfg.min_delta:
                best = (val_loss, epoch + 1, {k: v.detach().clone() for k, v in net.state_dict().items()})
            bar.update(1)
            bar.set_postfix(train=f"{train_loss:.4g}", val=f"{val_loss:.4g}", best=best[1])
            if epoch + 1 - best[1] >= cfg.patience:
                break
    net.load_state_dict(best[2])
    net.eval()

    build = out.with_name(f".{out.name}.build")
    if build.exists():
        shutil.rmtree(build)
    build.mkdir(parents=True)
    bundle.save(build)
    split.save(build / "split.json")
    workspace = Workspace.fit(poses[tr], poses[va], MinMax.fit(poses[tr]), train_joints=joints[tr])
    workspace.save(build)
    metrics = _evaluate(bundle, workspace, ds, rows, poses, joints)
    metrics["training"] = {"epochs": len(history), "best_epoch": best[1], "best_val_loss": best[0],
                           "seconds": seconds, "early_stopped": len(history) < cfg.max_epochs,
                           "threads": cfg.threads, "parameters": sum(p.numel() for p in net.parameters())}
    write_json(build / "metrics.json", metrics)
    _write_history(build / "history.csv", history)
    plot_curves(history, build / "curves.png", f"IK {cfg.model}: training and validation loss")
    write_marker(build, "model")
    write_manifest(build)
    swap_in(build, out, ModelError, "model")
    return TrainResult(out, metrics, history)


def _on_branch(q: np.ndarray, ref: np.ndarray, n: int) -> np.ndarray:
    """(M,) rows whose joints q are within ONPOLICY_DEG / ONPOLICY_MM of ref (the recorded branch:
    the recorded next joints are then the right label; on a mirror solution they are not)."""
    da = np.abs((q[:, :n] - ref[:, :n] + 180.0) % 360.0 - 180.0).max(axis=1)
    return (da < ONPOLICY_DEG) & (np.abs(q[:, n:] - ref[:, n:]).max(axis=1) < ONPOLICY_MM)


def _rollout(bundle: ModelBundle, poses: np.ndarray, joints: np.ndarray, bounds: list[tuple[int, int]],
             train_rows: np.ndarray) -> np.ndarray:
    """(T, 2N) the joints the current network reaches at every row of the training sequences,
    following their recorded targets from their recorded start joints (NaN elsewhere)."""
    follower = Follower(bundle, None)
    follower.lag = (0.0, 0.0)     # recorded joints already carry the recording's outer lag
    used = np.zeros(len(joints), bool)
    used[train_rows] = True
    followed = [(a, b) for a, b in bounds if used[a:b].any()]
    out, _ = follower.run(poses, followed, [joints[a] for a, _ in followed])
    return out


def _evaluate(bundle: ModelBundle, workspace: Workspace, ds: Dataset, rows: dict[str, np.ndarray],
              poses: np.ndarray, joints: np.ndarray) -> dict[str, Any]:
    """Joint errors of following the validation and test sequences from the nearest training joints
    (as Kinematics.predict runs a follow IK)."""
    follower = Follower(bundle, workspace)
    sid = ds.frame["sequence_id"].to_numpy()
    res: dict[str, Any] = {}
    for part in ("val", "test"):
        r = rows[part]
        if len(r):
            pred, _ = follower.run(check_raw(bundle.layout, poses[r]), sequence_bounds(sid[r]))
            res[part] = {"rows": len(r), "joints": metrics_json_joint_errors(pred, joints[r], ds.n_tubes)}
    return res


def _reusable(out: Path, cfg: TrainConfig, signature: str, split_sig: str, overwrite: bool
              ) -> TrainResult | None:
    """The finished model in `out` if it was trained with `cfg` on this data and split; None if there
    is none (or overwrite); ModelError if `out` holds another model."""
    if overwrite or not (out / CONFIG).is_file():
        return None
    saved = read_json(out / CONFIG)
    data = saved.get("data", {})
    diffs = setup_differences(saved["train"], data.get("signature"), data.get("split_signature"), cfg,
                              signature, split_sig, ignore=("threads",))
    if diffs:
        raise ModelError(f"{out} holds a model with a different setup ({'; '.join(diffs)}); pass "
                         f"overwrite (--overwrite) or choose another --out")
    with open(out / "history.csv", newline="") as f:
        history = [{k: float(v) for k, v in row.items()} for row in csv.DictReader(f)]
    return TrainResult(out, read_json(out / "metrics.json"), history)
