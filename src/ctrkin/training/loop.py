"""The training loop of paper IV.A: Adam, MAE loss, mini-batches, early stopping on validation loss;
seeded, checkpointed after every epoch and resumable.

    from ctrkin.data import Dataset
    from ctrkin.training import TrainConfig, train
    result = train(Dataset.load("data/quick"), TrainConfig(task="fk"), "models/fk")
"""

from __future__ import annotations

import csv
import io
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from tqdm.auto import tqdm

from ctrkin.data.dataset import Dataset
from ctrkin.errors import ModelError
from ctrkin.inference.workspace import Workspace
from ctrkin.models.features import postprocess
from ctrkin.models.store import ModelBundle, write_json
from ctrkin.training.config import TrainConfig
from ctrkin.training.curves import plot_curves
from ctrkin.training.data import Prepared, data_signature, prepare
from ctrkin.training.metrics import joint_errors, pose_errors
from ctrkin.util.files import atomic_path, atomic_write_text
from ctrkin.util.progress import progress_bar
from ctrkin.virtual.truth import tracker_truth

CHECKPOINT = "checkpoint.pt"


@dataclass
class TrainResult:
    out: Path
    metrics: dict[str, Any]
    history: list[dict[str, float]]


def predict_normalised(net: torch.nn.Module, X: np.ndarray, rows: np.ndarray, batch: int = 8192
                       ) -> np.ndarray:
    """Network outputs (len(rows), O) for the windows X[rows] (normalised space)."""
    outs = []
    net.eval()
    with torch.inference_mode():
        for a in range(0, len(rows), batch):
            outs.append(net(torch.from_numpy(X[rows[a:a + batch]])).numpy())
    return np.concatenate(outs) if outs else np.zeros((0, net.n_outputs), np.float32)  # type: ignore


def _epoch(net: torch.nn.Module, opt: torch.optim.Optimizer, X: torch.Tensor, Y: torch.Tensor,
           batch: int, gen: torch.Generator) -> float:
    net.train()
    perm = torch.randperm(len(X), generator=gen)
    total, count = 0.0, 0
    for a in range(0, len(perm), batch):
        idx = perm[a:a + batch]
        loss = torch.nn.functional.l1_loss(net(X[idx]), Y[idx])     # MAE loss (paper IV.A)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        total += loss.item() * len(idx)
        count += len(idx)
    return total / max(count, 1)


def _val_loss(net: torch.nn.Module, prep: Prepared, part: str) -> float:
    rows = prep.rows[part]
    pred = predict_normalised(net, prep.X, rows)
    return float(np.mean(np.abs(pred - prep.Y[rows])))


def train(ds: Dataset, cfg: TrainConfig, out: str | Path, overwrite: bool = False, progress: bool = True,
          log: Any = None) -> TrainResult:
    """Train `cfg` on `ds`, writing the model folder `out` (ctrkin.models.store).

    If `out` holds a checkpoint of the same configuration and data, training resumes from it (a larger
    max_epochs continues a finished run); a different one is refused unless `overwrite`.
    """
    say = log or (lambda _m: None)
    out = Path(out)
    torch.set_num_threads(cfg.threads)
    prep = prepare(ds, cfg)
    signature = data_signature(ds)
    torch.manual_seed(cfg.seed)
    bundle = ModelBundle.create(cfg.to_dict(), prep.layout, prep.x_norm, prep.y_norm, ds.robot,
                                {"data": {"signature": signature, "samples": len(ds.frame),
                                          "source": str(ds.meta.get("path", "")),
                                          "protocol": ds.meta.get("protocol")}})
    net = bundle.net
    opt = torch.optim.Adam(net.parameters(), lr=cfg.lr)
    gen = torch.Generator().manual_seed(cfg.seed)
    state: dict[str, Any] = {"epoch": 0, "best_val": float("inf"), "best_epoch": 0, "since_best": 0,
                             "history": [], "seconds": 0.0, "done": False}
    best_weights = {k: v.clone() for k, v in net.state_dict().items()}
    ckpt = out / CHECKPOINT
    if ckpt.is_file() and not overwrite:
        saved = torch.load(ckpt, map_location="cpu", weights_only=True)
        old = TrainConfig.from_dict(saved["config"])
        diffs = old.differences(cfg)
        if saved["data_signature"] != signature:
            diffs.append("the dataset differs")
        if diffs:
            raise ModelError(f"{out} holds a training run with a different setup ({'; '.join(diffs)}); "
                             f"pass overwrite (--overwrite) or choose another --out")
        net.load_state_dict(saved["net"])
        opt.load_state_dict(saved["opt"])
        gen.set_state(saved["gen"])
        best_weights = saved["best"]
        state = saved["state"]
        if state["done"] and cfg.max_epochs > state["epoch"] and state["since_best"] < cfg.patience:
            state["done"] = False
        say(f"resuming {out} after epoch {state['epoch']}")
    Xt, Yt = torch.from_numpy(prep.X[prep.rows["train"]]), torch.from_numpy(prep.Y[prep.rows["train"]])

    bar = (progress_bar(total=cfg.max_epochs, desc=f"train {cfg.task} {cfg.model}", initial=state["epoch"])
           if progress else tqdm(disable=True))
    try:
        while not state["done"] and state["epoch"] < cfg.max_epochs:
            t0 = time.perf_counter()
            train_loss = _epoch(net, opt, Xt, Yt, cfg.batch_size, gen)
            val_loss = _val_loss(net, prep, "val")
            state["seconds"] += time.perf_counter() - t0
            state["epoch"] += 1
            state["history"].append({"epoch": state["epoch"], "train_loss": train_loss, "val_loss": val_loss,
                                     "seconds": state["seconds"]})
            if val_loss < state["best_val"] - cfg.min_delta:
                state.update(best_val=val_loss, best_epoch=state["epoch"], since_best=0)
                best_weights = {k: v.detach().clone() for k, v in net.state_dict().items()}
            else:
                state["since_best"] += 1
            if state["since_best"] >= cfg.patience or state["epoch"] >= cfg.max_epochs:
                state["done"] = True
            out.mkdir(parents=True, exist_ok=True)
            with atomic_path(ckpt) as tmp:
                torch.save({"config": cfg.to_dict(), "data_signature": signature, "net": net.state_dict(),
                            "opt": opt.state_dict(), "gen": gen.get_state(), "best": best_weights,
                            "state": state}, tmp)
            bar.update(1)
            bar.set_postfix(train=f"{train_loss:.4g}", val=f"{val_loss:.4g}", best=state["best_epoch"])
    finally:
        bar.close()
    if not state["history"]:
        raise ModelError(f"no epoch was trained (max_epochs = {cfg.max_epochs})")

    net.load_state_dict(best_weights)
    net.eval()
    bundle.save(out)
    prep.split.save(out / "split.json")
    metrics = evaluate(bundle, ds, prep)
    metrics["training"] = {"epochs": state["epoch"], "best_epoch": state["best_epoch"],
                           "best_val_loss": state["best_val"], "seconds": state["seconds"],
                           "early_stopped": state["since_best"] >= cfg.patience,
                           "threads": cfg.threads, "parameters": sum(p.numel() for p in net.parameters())}
    if cfg.task == "ik":
        pose_cols = slice(0, 6)
        norm = type(prep.x_norm)(prep.x_norm.lo[pose_cols], prep.x_norm.span[pose_cols])
        Workspace.fit(prep.raw_in[prep.rows["train"]], prep.raw_in[prep.rows["val"]], norm).save(out)
    write_json(out / "metrics.json", metrics)
    _write_history(out / "history.csv", state["history"])
    plot_curves(state["history"], out / "curves.png",
                f"{cfg.task.upper()} {cfg.model} (IB = {cfg.ib}): training and validation loss")
    return TrainResult(out, metrics, state["history"])


def evaluate(bundle: ModelBundle, ds: Dataset, prep: Prepared) -> dict[str, Any]:
    """Loss (normalised MAE) and physical errors on the validation and test rows."""
    res: dict[str, Any] = {}
    n = ds.n_tubes
    truth = tracker_truth(ds) if prep.layout.task == "fk" and prep_pose_source(bundle) == "measured" else None
    for part in ("val", "test"):
        rows = prep.rows[part]
        if len(rows) == 0:
            continue
        yn = predict_normalised(bundle.net, prep.X, rows)
        m: dict[str, Any] = {"loss": float(np.mean(np.abs(yn - prep.Y[rows]))), "rows": len(rows)}
        pred = postprocess(prep.layout, prep.y_norm.inverse(yn))
        if prep.layout.task == "fk":
            m["vs_measured"] = pose_errors(pred, ds.poses()[rows])
            if truth is not None:  # the truth as the tracker sees it: the model's frame and sensor point
                m["vs_true"] = pose_errors(pred, truth[rows])
            elif ds.has_truth:
                m["vs_true"] = pose_errors(pred, ds.poses(true=True)[rows])
        else:
            m["joints"] = joint_errors(pred, ds.joints()[rows], n)
        res[part] = m
    return res


def prep_pose_source(bundle: ModelBundle) -> str:
    """Which pose columns the model learned from ("measured" or "true")."""
    return str(bundle.config.get("pose_source", "measured"))


def _write_history(path: Path, history: list[dict[str, float]]) -> None:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(history[0]))
    w.writeheader()
    w.writerows(history)
    atomic_write_text(path, buf.getvalue())
