"""The training loop of paper IV.A: Adam, MAE loss, mini-batches, early stopping on validation loss;
seeded, checkpointed after every epoch and resumable.

    from ctrkin.data import Dataset
    from ctrkin.training import TrainConfig, train
    result = train(Dataset.load("data/quick"), TrainConfig(task="fk"), "models/fk")
"""

from __future__ import annotations

import csv
import hashlib
import io
import math
import pickle
import shutil
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from tqdm.auto import tqdm

from ctrkin.data.dataset import Dataset
from ctrkin.data.schema import sequence_bounds
from ctrkin.data.splits import split_warnings
from ctrkin.data.tracker_view import recorded_tracker_view
from ctrkin.errors import ModelError
from ctrkin.metrics import metrics_json_joint_errors, metrics_json_pose_errors
from ctrkin.models.branch import UNKNOWN_STATE, BranchNet
from ctrkin.models.features import delta_columns, postprocess
from ctrkin.models.fold_gate import FoldGate, build_fold_gate, recorded_motion
from ctrkin.models.registry import get_entry
from ctrkin.models.store import ModelBundle, write_json
from ctrkin.models.workspace import Workspace
from ctrkin.training.config import TrainConfig
from ctrkin.training.curves import plot_curves
from ctrkin.training.data import Prepared, data_signature, prepare
from ctrkin.util.files import atomic_path, atomic_write_text
from ctrkin.util.folders import folder_lock, swap_in, write_manifest
from ctrkin.util.ownership import check_replaceable, write_marker
from ctrkin.util.progress import progress_bar

CHECKPOINT = "checkpoint.pt"
SMOOTH_RTOL = 1e-3


@dataclass
class TrainResult:
    out: Path
    metrics: dict[str, Any]
    history: list[dict[str, float]]


def predict_normalised(net: torch.nn.Module, X: np.ndarray, rows: np.ndarray, batch: int = 8192,
                       bounds: list[tuple[int, int]] | None = None) -> np.ndarray:
    """Network outputs (len(rows), O) for the windows X[rows] (normalised space). A BranchNet carries
    its state through the whole sequences that hold `rows` (bounds: the dataset's sequences)."""
    if isinstance(net, BranchNet):
        return _branch_predict(net, X, rows, bounds or [(0, len(X))])
    outs = []
    net.eval()
    with torch.inference_mode():
        for a in range(0, len(rows), batch):
            outs.append(net(torch.from_numpy(X[rows[a:a + batch]])).numpy())
    return np.concatenate(outs) if outs else np.zeros((0, net.n_outputs), np.float32)  # type: ignore


def _branch_predict(net: BranchNet, X: np.ndarray, rows: np.ndarray, bounds: list[tuple[int, int]]
                    ) -> np.ndarray:
    """Decode the whole sequences that contain `rows` (the state needs their history), return rows."""
    starts = np.array([a for a, _ in bounds])
    seqs = np.unique(np.searchsorted(starts, rows, side="right") - 1)
    idx = np.concatenate([np.arange(*bounds[k]) for k in seqs]) if len(seqs) else np.zeros(0, np.int64)
    local, pos = [], 0
    for k in seqs:
        a, b = bounds[k]
        local.append((pos, pos + b - a))
        pos += b - a
    net.eval()
    with torch.inference_mode():
        h = torch.cat([net.trunk(torch.from_numpy(X[idx[a:a + 8192]])) for a in range(0, len(idx), 8192)]) \
            if len(idx) else torch.zeros((0, net.trunk_width))
        y, _ = net.decode(h, local)
    where = np.full(len(X), -1, dtype=np.int64)
    where[idx] = np.arange(len(idx))
    return y[where[rows]]


@dataclass(eq=False)
class _BranchBatch:
    """Branch labels of the training rows (teacher forcing) and the augmentation of the gate input."""

    state: torch.Tensor          # (M,) labels
    state_prev: torch.Tensor     # (M,) previous labels, 0.5 at sequence starts
    forced: torch.Tensor         # (M,) label independent of history
    gate_rows: torch.Tensor      # (M,) per-row weight of the gate loss
    unknown_prob: float
    weight: float

    def loss(self, net: BranchNet, x: torch.Tensor, y: torch.Tensor, idx: torch.Tensor,
             gen: torch.Generator) -> torch.Tensor:
        s, prev, forced = self.state[idx], self.state_prev[idx].clone(), self.forced[idx]
        u = torch.rand((len(idx), 2), generator=gen)
        flip = forced & (u[:, 0] < 0.5) & (prev != UNKNOWN_STATE)     # a wrong state must recover
        prev = torch.where(flip, 1.0 - prev, prev)
        prev = torch.where(u[:, 1] < self.unknown_prob, torch.full_like(prev, UNKNOWN_STATE), prev)
        h = net.trunk(x)
        pose_loss = torch.nn.functional.l1_loss(net.head_out(h, s), y)          # MAE (paper IV.A)
        gate_loss = torch.nn.functional.binary_cross_entropy_with_logits(
            net.gate_logit(h, prev), s, weight=self.gate_rows[idx])
        return pose_loss + self.weight * gate_loss


def _near_switch(state: np.ndarray, bounds: list[tuple[int, int]], width: int = 5, boost: float = 10.0
                 ) -> np.ndarray:
    """(T,) float32 gate-loss weights: `boost` within `width` rows of a change of branch (where the
    switching point is learned; a few rows per sequence), 1 elsewhere."""
    w = np.ones(len(state), dtype=np.float32)
    for a, b in bounds:
        for t in np.nonzero(np.diff(state[a:b]))[0] + a + 1:
            w[max(a, t - width):min(b, t + width + 1)] = boost
    return w


def _epoch(net: torch.nn.Module, opt: torch.optim.Optimizer, X: torch.Tensor, Y: torch.Tensor,
           batch: int, gen: torch.Generator, branch: _BranchBatch | None = None) -> float:
    """One epoch of the loop up to issue 11 (TrainConfig.loop = "batch"): a gather per batch."""
    net.train()
    perm = torch.randperm(len(X), generator=gen)
    total, count = 0.0, 0
    for a in range(0, len(perm), batch):
        idx = perm[a:a + batch]
        if branch is not None:
            assert isinstance(net, BranchNet)
            loss = branch.loss(net, X[idx], Y[idx], idx, gen)
        else:
            loss = torch.nn.functional.l1_loss(net(X[idx]), Y[idx])     # MAE loss (paper IV.A)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        total += loss.item() * len(idx)
        count += len(idx)
    return total / max(count, 1)


def _epoch_gathered(net: torch.nn.Module, opt: torch.optim.Optimizer, X: torch.Tensor, Y: torch.Tensor,
                    batch: int, gen: torch.Generator, branch: _BranchBatch | None = None) -> float:
    """One epoch with the training tensors shuffled by one gather (TrainConfig.loop = "epoch"):
    batches are contiguous views, the loss is summed without a per-batch sync. The same permutation
    and batches as `_epoch`, so both loops see the same data order for a seed."""
    net.train()
    perm = torch.randperm(len(X), generator=gen)
    Xp, Yp = X[perm], Y[perm]
    total = torch.zeros((), dtype=torch.float64)
    for a in range(0, len(perm), batch):
        x, y = Xp[a:a + batch], Yp[a:a + batch]
        if branch is not None:
            assert isinstance(net, BranchNet)
            loss = branch.loss(net, x, y, perm[a:a + batch], gen)
        else:
            loss = torch.nn.functional.l1_loss(net(x), y)               # MAE loss (paper IV.A)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        total += loss.detach() * len(x)
    return float(total) / max(len(perm), 1)


def _optimizer(net: torch.nn.Module, cfg: TrainConfig) -> torch.optim.Optimizer:
    """Adam (paper IV.A): the fused CPU kernel (one call for all parameters, ~15-30 % of a small
    batch's step saved; rounding differs) unless cfg.fused_adam is off or the loop is "batch"."""
    if cfg.loop == "epoch" and cfg.fused_adam:
        return torch.optim.Adam(net.parameters(), lr=cfg.lr, fused=True)
    return torch.optim.Adam(net.parameters(), lr=cfg.lr)


def _early_stopping(state: dict[str, Any], val_loss: float, cfg: TrainConfig) -> bool:
    """Update the early-stopping counters of `state` with this epoch's val loss; True if it is the
    best epoch so far (its weights are kept). With val_smoothing > 0 the patience counts epochs
    without an improvement of the smoothed val loss (a noisy val loss at a large learning rate
    would otherwise stop a run that is still improving); it must fall by SMOOTH_RTOL of itself to
    count, since an average converging onto a plateau falls forever by ever smaller steps."""
    best = val_loss < state["best_val"] - cfg.min_delta
    if best:
        state.update(best_val=val_loss, best_epoch=state["epoch"])
    a = cfg.val_smoothing
    if a == 0:
        state["since_best"] = 0 if best else state["since_best"] + 1
        return best
    prev = state.get("smooth_val")
    smooth = val_loss if prev is None else a * prev + (1.0 - a) * val_loss
    state["smooth_val"] = smooth
    best_smooth = state.get("best_smooth")
    if best_smooth is None or smooth < best_smooth - max(cfg.min_delta, SMOOTH_RTOL * best_smooth):
        state.update(best_smooth=smooth, since_best=0)
    else:
        state["since_best"] += 1
    return best


def _val_loss(net: torch.nn.Module, prep: Prepared, part: str) -> float:
    rows = prep.rows[part]
    pred = predict_normalised(net, prep.X, rows, bounds=prep.bounds)
    return float(np.mean(np.abs(pred - prep.Y[rows])))


def _learning_rate(cfg: TrainConfig, epoch: int) -> float:
    """The learning rate of epoch `epoch` (0-based): constant (paper) or cosine from lr to lr/50."""
    if cfg.lr_schedule == "constant":
        return cfg.lr
    low = cfg.lr / 50.0
    return low + (cfg.lr - low) * 0.5 * (1.0 + math.cos(math.pi * min(epoch / cfg.max_epochs, 1.0)))


def split_signature(rows: dict[str, np.ndarray]) -> str:
    """A short hash of the train/val/test rows: resuming on another split would leak the epochs
    trained on the old training rows into the new test rows."""
    h = hashlib.sha256()
    for name in ("train", "val", "test"):
        h.update(name.encode())
        h.update(np.ascontiguousarray(rows[name], dtype=np.int64).tobytes())
    return h.hexdigest()[:16]


def setup_differences(saved_config: dict[str, Any], saved_data: str | None, saved_split: str | None,
                      cfg: TrainConfig, signature: str, split_sig: str,
                      ignore: tuple[str, ...] | None = None) -> list[str]:
    """What differs between a saved run (its config dict, data and split signatures) and `cfg` on
    this data and split (data_signature, split_signature); empty if it may be resumed or reused.
    ignore: config keys that may differ (None: those a resume may change, TrainConfig.differences)."""
    old = TrainConfig.from_dict(saved_config)
    diffs = old.differences(cfg) if ignore is None else old.differences(cfg, ignore)
    if saved_data != signature:
        diffs.append("the dataset differs")
    if saved_split != split_sig:
        diffs.append("the train/val/test split differs")
    return diffs


def train(ds: Dataset, cfg: TrainConfig, out: str | Path, overwrite: bool = False, progress: bool = True,
          log: Any = None) -> TrainResult:
    """Train `cfg` on `ds`, writing the model folder `out` (ctrkin.models.store).

    If `out` holds a checkpoint of the same configuration, data and split, training resumes from it (a
    larger max_epochs continues a finished run); a different one is refused unless `overwrite`.
    The folder is built aside (`.NAME.build`, which also keeps the checkpoints of an unfinished run)
    and swapped in whole at the end, under a lock: a kill leaves the previous model or the new one,
    never a mix, and a second training into the same `out` is refused while one runs.
    """
    out = Path(out)
    with folder_lock(out, ModelError, "train"):        # also cleans what killed runs left
        check_replaceable(out, "model", ModelError)     # only a model folder is ever replaced
        if cfg.follow:                       # its own loop: features depend on perturbed joints
            from ctrkin.training.follow import train_follow
            return train_follow(ds, cfg, out, overwrite, progress, log)
        return _train_locked(ds, cfg, out, overwrite, progress, log)


def _train_locked(ds: Dataset, cfg: TrainConfig, out: Path, overwrite: bool, progress: bool,
                  log: Any) -> TrainResult:
    say = log or (lambda _m: None)
    torch.set_num_threads(cfg.threads)
    stateful = get_entry(cfg.model).stateful
    prep = prepare(ds, cfg, branches=stateful)
    if prep.split.kind == "sequence":
        for w in split_warnings(prep.split, prep.split.fractions):
            say(f"warning: {w}")
    signature = data_signature(ds)
    split_sig = split_signature(prep.rows)
    torch.manual_seed(cfg.seed)
    bundle = ModelBundle.create(cfg.to_dict(), prep.layout, prep.x_norm, prep.y_norm, ds.robot,
                                {"data": {"signature": signature, "split_signature": split_sig,
                                          "samples": len(ds.frame),
                                          "source": str(ds.meta.get("path", "")),
                                          "protocol": ds.meta.get("protocol")}}, frame=prep.frame)
    net = bundle.net
    opt = _optimizer(net, cfg)
    gen = torch.Generator().manual_seed(cfg.seed)
    state: dict[str, Any] = {"epoch": 0, "best_val": float("inf"), "best_epoch": 0, "since_best": 0,
                             "history": [], "seconds": 0.0, "done": False}
    best_weights = {k: v.clone() for k, v in net.state_dict().items()}
    build = out.with_name(f".{out.name}.build")
    if overwrite and build.exists():
        shutil.rmtree(build)
    previous = [p / CHECKPOINT for p in (build, out) if (p / CHECKPOINT).is_file()]
    if previous and not overwrite:
        saved = _load_checkpoint(previous[0])
        diffs = setup_differences(saved["config"], saved["data_signature"], saved.get("split_signature"),
                                  cfg, signature, split_sig)
        if diffs:
            raise ModelError(f"{out} holds a training run with a different setup ({'; '.join(diffs)}); "
                             f"pass overwrite (--overwrite) or choose another --out")
        net.load_state_dict(saved["net"])
        opt.load_state_dict(saved["opt"])
        gen.set_state(saved["gen"])
        best_weights = saved["best"]
        state = saved["state"]
        if (state["done"] and cfg.max_epochs > state["epoch"] and state["since_best"] < cfg.patience
                and not _out_of_time(state, cfg)):
            state["done"] = False
        say(f"resuming {out} after epoch {state['epoch']}")
    if build.exists() and not (build / CHECKPOINT).is_file():
        shutil.rmtree(build)             # a build killed before its first checkpoint: nothing to keep
    build.mkdir(parents=True, exist_ok=True)
    ckpt = build / CHECKPOINT
    train_rows = prep.rows["train"]
    Xt, Yt = torch.from_numpy(prep.X[train_rows]), torch.from_numpy(prep.Y[train_rows])
    branch = None
    if stateful:
        assert prep.state is not None and prep.state_prev is not None and prep.forced is not None
        branch = _BranchBatch(torch.from_numpy(prep.state[train_rows].astype(np.float32)),
                              torch.from_numpy(prep.state_prev[train_rows]),
                              torch.from_numpy(prep.forced[train_rows]),
                              torch.from_numpy(_near_switch(prep.state, prep.bounds)[train_rows]),
                              cfg.unknown_prob, cfg.gate_weight)

    run_epoch = _epoch_gathered if cfg.loop == "epoch" else _epoch
    bar = (progress_bar(total=cfg.max_epochs, desc=f"train {cfg.task} {cfg.model}", initial=state["epoch"])
           if progress else tqdm(disable=True))
    try:
        while not state["done"] and state["epoch"] < cfg.max_epochs:
            t0 = time.perf_counter()
            for group in opt.param_groups:
                group["lr"] = _learning_rate(cfg, state["epoch"])
            train_loss = run_epoch(net, opt, Xt, Yt, cfg.batch_size, gen, branch)
            val_loss = _val_loss(net, prep, "val")
            state["seconds"] += time.perf_counter() - t0
            state["epoch"] += 1
            state["history"].append({"epoch": state["epoch"], "train_loss": train_loss, "val_loss": val_loss,
                                     "seconds": state["seconds"]})
            if _early_stopping(state, val_loss, cfg):
                best_weights = {k: v.detach().clone() for k, v in net.state_dict().items()}
            if (state["since_best"] >= cfg.patience or state["epoch"] >= cfg.max_epochs
                    or _out_of_time(state, cfg)):
                state["done"] = True
            with atomic_path(ckpt) as tmp:
                torch.save({"config": cfg.to_dict(), "data_signature": signature,
                            "split_signature": split_sig, "net": net.state_dict(),
                            "opt": opt.state_dict(), "gen": gen.get_state(), "best": best_weights,
                            "state": state}, tmp)
            bar.update(1)
            bar.set_postfix(train=f"{train_loss:.4g}", val=f"{val_loss:.4g}", best=state["best_epoch"])
    finally:
        bar.close()
    if not state["history"]:
        raise ModelError(f"no epoch was trained (max_epochs = {cfg.max_epochs})")
    if not ckpt.is_file():                 # resumed a finished run without training: keep its checkpoint
        shutil.copy2(previous[0], ckpt)

    net.load_state_dict(best_weights)
    net.eval()
    bundle.save(build)
    prep.split.save(build / "split.json")
    if stateful:
        say("tabulating the nominal robot's folds for the fold gate")
        fold_gate(ds, prep.rows["train"]).save(build)
    metrics = evaluate(bundle, ds, prep)
    metrics["training"] = {"epochs": state["epoch"], "best_epoch": state["best_epoch"],
                           "best_val_loss": state["best_val"], "seconds": state["seconds"],
                           "early_stopped": state["since_best"] >= cfg.patience,
                           "samples_per_s": len(train_rows) * state["epoch"] / max(state["seconds"], 1e-9),
                           "threads": cfg.threads, "parameters": sum(p.numel() for p in net.parameters())}
    if cfg.task == "ik":
        pose_norm = prep.x_norm.subset(slice(0, 6))
        Workspace.fit(prep.raw_in[prep.rows["train"]], prep.raw_in[prep.rows["val"]], pose_norm,
                      train_joints=prep.target[prep.rows["train"]]).save(build)
    write_json(build / "metrics.json", metrics)
    _write_history(build / "history.csv", state["history"])
    plot_curves(state["history"], build / "curves.png",
                f"{cfg.task.upper()} {cfg.model} (IB = {cfg.ib}): training and validation loss")
    write_marker(build, "model")
    write_manifest(build, skip=(CHECKPOINT,))
    swap_in(build, out, ModelError, "model")
    return TrainResult(out, metrics, state["history"])


def _out_of_time(state: dict[str, Any], cfg: TrainConfig) -> bool:
    return cfg.max_seconds is not None and state["seconds"] >= cfg.max_seconds


def _load_checkpoint(path: Path) -> dict[str, Any]:
    try:
        saved = torch.load(path, map_location="cpu", weights_only=True)
    except (RuntimeError, OSError, EOFError, pickle.UnpicklingError) as e:
        raise ModelError(f"{path} cannot be read ({e}); pass overwrite (--overwrite) to start over") from None
    if not isinstance(saved, dict) or not {"config", "data_signature", "net", "state"} <= set(saved):
        raise ModelError(f"{path} is not a ctrkin checkpoint; pass overwrite (--overwrite) to start over")
    return saved


def evaluate(bundle: ModelBundle, ds: Dataset, prep: Prepared) -> dict[str, Any]:
    """Loss (normalised MAE) and physical errors on the validation and test rows, with the inputs
    the trained model gets in use: step-change features clipped to their training range, as
    `Kinematics.predict` clips them. Without it, a held-out file with larger steps than training's
    (random configurations against sweeps) was reported on extrapolated inputs, and `ctrkin
    evaluate` gave another figure for the same rows."""
    res: dict[str, Any] = {}
    n = ds.n_tubes
    measured_fk = prep.layout.task == "fk" and prep_pose_source(bundle) == "measured"
    truth = recorded_tracker_view(ds) if measured_fk else None
    X = prep.X
    dcols = delta_columns(prep.layout)
    if len(dcols):                  # normalised on the training rows: their range is [0, 1]
        X = X.copy()
        X[..., dcols] = np.clip(X[..., dcols], 0.0, 1.0)
    for part in ("val", "test"):
        rows = prep.rows[part]
        if len(rows) == 0:
            continue
        yn = predict_normalised(bundle.net, X, rows, bounds=prep.bounds)
        m: dict[str, Any] = {"loss": float(np.mean(np.abs(yn - prep.Y[rows]))), "rows": len(rows)}
        pred = prep.to_world(postprocess(prep.layout, prep.y_norm.inverse(yn)), rows)
        if prep.layout.task == "fk":
            m["vs_measured"] = metrics_json_pose_errors(pred, ds.poses()[rows],
                                                        ds.meta.get("orientation") != "absent")
            if truth is not None:  # the truth as the tracker sees it: the model's frame and sensor point
                m["vs_true"] = metrics_json_pose_errors(pred, truth[rows])
            elif ds.has_truth:
                m["vs_true"] = metrics_json_pose_errors(pred, ds.poses(true=True)[rows])
        else:
            m["joints"] = metrics_json_joint_errors(pred, ds.joints()[rows], n)
        res[part] = m
    return res


def fold_gate(ds: Dataset, rows: np.ndarray) -> FoldGate:
    """The fold gate of a snap-aware model (ctrkin.models.fold_gate): folds of the dataset's nominal
    robot over the translations of `rows` (the training rows, sorted), fitted to their snaps; the
    outer tube's last rotation is followed over the whole dataset (runs cross the split)."""
    f = ds.frame
    q = ds.joints()
    motion, _ = recorded_motion(f, q, ds.sequence_bounds(), ds.n_tubes)
    bounds = sequence_bounds(f["sequence_id"].to_numpy()[rows])
    return build_fold_gate(ds.robot, q[rows], f["snap"].to_numpy()[rows], bounds, motion[rows])


def prep_pose_source(bundle: ModelBundle) -> str:
    """Which pose columns the model learned from ("measured" or "true")."""
    return bundle.config.pose_source


def _write_history(path: Path, history: list[dict[str, float]]) -> None:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(history[0]))
    w.writeheader()
    w.writerows(history)
    atomic_write_text(path, buf.getvalue())
