"""The generic training engine of paper IV.A: Adam, mini-batches, early stopping on the validation
loss; seeded, checkpointed (after an epoch, at most every CHECKPOINT_EVERY_S seconds, and at the end:
a small set's epochs take milliseconds) and resumable. What a model learns from and its loss
come from its family's recipe (ctrkin.models.recipe), found by the registry
(ctrkin.families.registry); everything else is here, the same for every family.

    from ctrkin.data import Dataset
    from ctrkin.training import TrainConfig, train
    result = train(Dataset.load("data/quick"), TrainConfig(task="fk"), "models/fk")
"""

from __future__ import annotations

import copy
import csv
import io
import math
import pickle
import shutil
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import torch
from tqdm.auto import tqdm

from ctrkin.data.dataset import Dataset
from ctrkin.data.splits import split_warnings
from ctrkin.errors import ModelError
from ctrkin.families.registry import build_net, recipe
from ctrkin.models.recipe import Recipe, TrainingData
from ctrkin.models.store import CHECKPOINT, CONFIG, ModelBundle, read_json, write_json
from ctrkin.models.window_lstm import use_window_lstm
from ctrkin.training.config import TrainConfig
from ctrkin.training.curves import plot_curves, read_history
from ctrkin.training.data import data_signature, split_rows, split_signature
from ctrkin.training.device import resolve_device
from ctrkin.training.fit import diagnose
from ctrkin.training.selection import CANDIDATES, candidate_configs, selects, train_selecting
from ctrkin.util.files import atomic_path, atomic_write_text
from ctrkin.util.folders import folder_lock, swap_in, write_manifest
from ctrkin.util.ownership import check_replaceable, write_marker
from ctrkin.util.progress import progress_bar

CHECKPOINT_EVERY_S = 5.0     # at most one checkpoint per this many seconds of training, and the last
SMOOTH_RTOL = 1e-3


@dataclass
class TrainResult:
    out: Path
    metrics: dict[str, Any]
    history: list[dict[str, float]]


Loss = Callable[[torch.nn.Module, torch.Tensor, torch.Tensor, torch.Tensor, torch.Generator], torch.Tensor]


def _epoch(net: torch.nn.Module, opt: torch.optim.Optimizer, X: torch.Tensor, Y: torch.Tensor,
           batch: int, gen: torch.Generator, loss_fn: Loss) -> float:
    """One epoch of the loop up to issue 11 (TrainConfig.loop = "batch"): a gather per batch.
    loss_fn(net, x, y, idx, gen): the recipe's loss of a batch (idx: its rows of X, Y)."""
    net.train()
    perm = torch.randperm(len(X), generator=gen)
    total, count = 0.0, 0
    on_device = perm.to(X.device)
    for a in range(0, len(perm), batch):
        idx = perm[a:a + batch]
        loss = loss_fn(net, X[on_device[a:a + batch]], Y[on_device[a:a + batch]], idx, gen)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        total += loss.item() * len(idx)
        count += len(idx)
    return total / max(count, 1)


def _epoch_gathered(net: torch.nn.Module, opt: torch.optim.Optimizer, X: torch.Tensor, Y: torch.Tensor,
                    batch: int, gen: torch.Generator, loss_fn: Loss) -> float:
    """One epoch with the training tensors shuffled by one gather (TrainConfig.loop = "epoch"):
    batches are contiguous views, the loss is summed without a per-batch sync. The same permutation
    and batches as `_epoch`, so both loops see the same data order for a seed."""
    net.train()
    perm = torch.randperm(len(X), generator=gen)
    on_device = perm.to(X.device)
    Xp, Yp = X[on_device], Y[on_device]
    total = torch.zeros((), dtype=torch.float64, device=X.device)
    for a in range(0, len(perm), batch):
        x, y = Xp[a:a + batch], Yp[a:a + batch]
        loss = loss_fn(net, x, y, perm[a:a + batch], gen)
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


def _learning_rate(cfg: TrainConfig, epoch: int, max_epochs: int) -> float:
    """The learning rate of epoch `epoch` (0-based) of `max_epochs` (the run's resolved budget):
    constant (paper) or cosine from lr to lr/50."""
    if cfg.lr_schedule == "constant":
        return cfg.lr
    low = cfg.lr / 50.0
    return low + (cfg.lr - low) * 0.5 * (1.0 + math.cos(math.pi * min(epoch / max_epochs, 1.0)))


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
    larger max_epochs continues a finished run); a different one is refused unless `overwrite`. A
    recipe without checkpoints (Recipe.checkpoints) starts over, or reuses a finished folder of the
    same setup. The folder is built aside (`.NAME.build`, which also keeps the checkpoints of an
    unfinished run) and swapped in whole at the end, under a lock: a kill leaves the previous model
    or the new one, never a mix, and a second training into the same `out` is refused while one runs.
    An FK with cfg.select_by_validation also trains the paper's LSTM-MLP and keeps the one validation
    prefers (ctrkin.training.selection).
    """
    out = Path(out)
    say = log or (lambda _m: None)
    with folder_lock(out, ModelError, "train"):        # also cleans what killed runs left
        check_replaceable(out, "model", ModelError)     # only a model folder is ever replaced
        if selects(cfg):                                # two trainings, the one validation prefers kept
            reused = _reused_selection(ds, cfg, out, overwrite)
            if reused is not None:
                say(f"{out} already holds this selection ({reused.metrics['model_selection']['kept']} "
                    "model kept); reusing it")
                return reused
            return train_selecting(ds, cfg, out, overwrite, progress, say, _train_locked)
        return _train_locked(ds, cfg, out, overwrite, progress, say)


def _train_locked(ds: Dataset, cfg: TrainConfig, out: Path, overwrite: bool, progress: bool,
                  say: Callable[[str], None]) -> TrainResult:
    device, note = resolve_device(cfg.device)
    if note:
        say(note)
    torch.set_num_threads(cfg.threads)
    split, rows = split_rows(ds, cfg)
    train_rows = len(rows["train"])
    cfg = replace(cfg, max_epochs=cfg.epoch_budget(train_rows))   # the budget of this set (config.json)
    rec = recipe(cfg)
    if split.kind == "sequence":
        for w in split_warnings(split, split.fractions):
            say(f"warning: {w}")
    signature, split_sig = data_signature(ds), split_signature(rows)
    if not rec.checkpoints:
        reused = _reusable(out, cfg, signature, split_sig, overwrite)
        if reused is not None:
            say(f"{out} already holds this model; reusing it")
            return reused
    prepared = rec.prepare(TrainingData(ds, cfg, split, rows))
    torch.manual_seed(cfg.seed)
    bundle = ModelBundle.create(cfg.to_dict(), prepared.layout, prepared.x_norm, prepared.y_norm, ds.robot,
                                {"data": {"signature": signature, "split_signature": split_sig,
                                          "samples": len(ds.frame), "source": str(ds.meta.get("path", "")),
                                          "protocol": ds.meta.get("protocol")}, **prepared.extra},
                                frame=prepared.frame, build=build_net)
    rec.attach(bundle.net)              # e.g. a field layer learned beside the network
    run = _Run(bundle, cfg, rec, out, signature, split_sig, train_rows, device)
    run.start(overwrite, say)
    run.epochs(progress)
    return run.finish(split, say)


class _Run:
    """One training run's state: the network, Adam, the batch-order generator, the early-stopping
    counters and history (`state`), the best weights, and the build folder with its checkpoint.
    cfg.max_epochs is resolved (TrainConfig.epoch_budget); the patience counts at least
    cfg.patience_steps optimiser steps (TrainConfig.patience_epochs).

    On a device other than the CPU (ctrkin.training.device) Adam steps a copy of the network there
    (`net`), whose weights are copied back into the bundle's CPU network (`cpu_net`) after every
    epoch: the recipe (its rollouts, validation, metrics) and the saved folder see the CPU network,
    and the batch order, augmentation draws and checkpoints are those of a CPU run. On the CPU both
    are the one network."""

    def __init__(self, bundle: ModelBundle, cfg: TrainConfig, rec: Recipe, out: Path, signature: str,
                 split_sig: str, train_rows: int, device: torch.device | None = None) -> None:
        assert cfg.max_epochs is not None
        self.bundle, self.cfg, self.recipe, self.out = bundle, cfg, rec, out
        self.max_epochs, self.train_rows = cfg.max_epochs, train_rows
        self.patience = cfg.patience_epochs(train_rows)
        self.signature, self.split_sig = signature, split_sig
        self.device = device or torch.device("cpu")
        self.cpu_net = bundle.net
        self.net = (copy.deepcopy(self.cpu_net).to(self.device) if _needs_copy(self.device)
                    else self.cpu_net)
        self.opt = _optimizer(self.net, cfg)
        self.gen = torch.Generator().manual_seed(cfg.seed)
        self.state: dict[str, Any] = {"epoch": 0, "best_val": float("inf"), "best_epoch": 0, "since_best": 0,
                                      "history": [], "seconds": 0.0, "done": False}
        self.best_weights = {k: v.clone() for k, v in self.net.state_dict().items()}
        self.build = out.with_name(f".{out.name}.build")
        self.ckpt = self.build / CHECKPOINT
        self.previous: list[Path] = []

    def start(self, overwrite: bool, say: Callable[[str], None]) -> None:
        """Resume from a checkpoint of the same setup in the build folder or `out` (refuse another
        setup unless `overwrite`), and make the build folder."""
        cfg, build = self.cfg, self.build
        if build.exists() and (overwrite or not self.recipe.checkpoints):
            shutil.rmtree(build)
        if self.recipe.checkpoints:
            self.previous = [p / CHECKPOINT for p in (build, self.out) if (p / CHECKPOINT).is_file()]
        if self.previous and not overwrite:
            saved = _load_checkpoint(self.previous[0])
            diffs = setup_differences(saved["config"], saved["data_signature"], saved.get("split_signature"),
                                      cfg, self.signature, self.split_sig)
            if diffs:
                raise ModelError(f"{self.out} holds a training run with a different setup "
                                 f"({'; '.join(diffs)}); pass overwrite (--overwrite) or choose another "
                                 "--out")
            self.cpu_net.load_state_dict(saved["net"])
            if self.net is not self.cpu_net:
                self.net.load_state_dict(saved["net"])
            self.opt.load_state_dict(saved["opt"])
            self.gen.set_state(saved["gen"])
            self.best_weights = saved["best"]
            self.state = state = saved["state"]
            if (state["done"] and self.max_epochs > state["epoch"] and state["since_best"] < self.patience
                    and not _out_of_time(state, cfg)):
                state["done"] = False
            say(f"resuming {self.out} after epoch {state['epoch']}")
        if build.exists() and not (build / CHECKPOINT).is_file():
            shutil.rmtree(build)             # a build killed before its first checkpoint: nothing to keep
        build.mkdir(parents=True, exist_ok=True)

    def epochs(self, progress: bool) -> None:
        """Train until early stopping, max_epochs or max_seconds; a checkpoint after an epoch at most
        every CHECKPOINT_EVERY_S seconds, and after the last."""
        cfg, state, net, rec = self.cfg, self.state, self.net, self.recipe
        saved_at = time.perf_counter()
        run_epoch = _epoch_gathered if cfg.loop == "epoch" else _epoch
        bar = (progress_bar(total=self.max_epochs, desc=f"train {cfg.task} {cfg.model}",
                            initial=state["epoch"]) if progress else tqdm(disable=True))
        use_window_lstm(net, cfg.loop == "epoch" and cfg.fused_lstm)    # for the epochs only: not in export
        try:
            while not state["done"] and state["epoch"] < self.max_epochs:
                t0, cpu0 = time.perf_counter(), time.process_time()
                for group in self.opt.param_groups:
                    group["lr"] = _learning_rate(cfg, state["epoch"], self.max_epochs)
                X, Y = self._on_device(rec.epoch_tensors(state["epoch"], self.bundle))
                train_loss = run_epoch(net, self.opt, X, Y, cfg.batch_size, self.gen, rec.loss)
                self._sync()
                val_loss = rec.val_loss(self.cpu_net)
                state["seconds"] += time.perf_counter() - t0
                # CPU time of all the process's threads: per-core throughput, less exposed to other jobs
                state["cpu_seconds"] = state.get("cpu_seconds", 0.0) + time.process_time() - cpu0
                state["epoch"] += 1
                state["history"].append({"epoch": state["epoch"], "train_loss": train_loss,
                                         "val_loss": val_loss, "seconds": state["seconds"]})
                if _early_stopping(state, val_loss, cfg):
                    self.best_weights = {k: v.detach().clone() for k, v in self.cpu_net.state_dict().items()}
                if (state["since_best"] >= self.patience or state["epoch"] >= self.max_epochs
                        or _out_of_time(state, cfg)):
                    state["done"] = True
                due = time.perf_counter() - saved_at >= CHECKPOINT_EVERY_S
                if rec.checkpoints and (state["done"] or due):
                    self._checkpoint()
                    saved_at = time.perf_counter()
                bar.update(1)
                bar.set_postfix(train=f"{train_loss:.4g}", val=f"{val_loss:.4g}", best=state["best_epoch"])
        finally:
            bar.close()
            use_window_lstm(net, False)

    def _on_device(self, tensors: tuple[torch.Tensor, torch.Tensor]) -> tuple[torch.Tensor, torch.Tensor]:
        """An epoch's (X, Y) on the training device (copied once while the recipe returns the same
        tensors)."""
        if self.net is self.cpu_net:
            return tensors
        key = tuple(id(t) for t in tensors)
        if getattr(self, "_moved_key", None) != key:
            self._moved_key = key
            self._moved = (tensors[0].to(self.device), tensors[1].to(self.device))
        return self._moved

    def _sync(self) -> None:
        """The trained weights into the CPU network (nothing to do when training on it)."""
        if self.net is not self.cpu_net:
            with torch.no_grad():
                for dst, src in zip(self.cpu_net.state_dict().values(), self.net.state_dict().values(),
                                    strict=True):
                    dst.copy_(src)

    def _checkpoint(self) -> None:
        with atomic_path(self.ckpt) as tmp:
            torch.save({"config": self.cfg.to_dict(), "data_signature": self.signature,
                        "split_signature": self.split_sig, "net": self.cpu_net.state_dict(),
                        "opt": self.opt.state_dict(), "gen": self.gen.get_state(), "best": self.best_weights,
                        "state": self.state}, tmp)

    def finish(self, split: Any, say: Callable[[str], None]) -> TrainResult:
        """The best epoch's weights, the model folder (the recipe's metrics and files, history, curves,
        manifest) swapped in for `out`."""
        cfg, state, net, build = self.cfg, self.state, self.net, self.build
        if not state["history"]:
            raise ModelError(f"no epoch was trained (max_epochs = {cfg.max_epochs})")
        if self.recipe.checkpoints and not self.ckpt.is_file():   # resumed a finished run without training
            shutil.copy2(self.previous[0], self.ckpt)
        net = self.cpu_net
        net.load_state_dict(self.best_weights)
        net.eval()
        self.recipe.detach(net)         # the best epoch's extras stay with the recipe, not in the weights
        self.bundle.save(build)
        split.save(build / "split.json")
        metrics = self.recipe.finish(self.bundle, build, say)
        steps = cfg.steps_per_epoch(self.train_rows)
        stopped_by = ("patience" if state["since_best"] >= self.patience else
                      "max_epochs" if state["epoch"] >= self.max_epochs else "max_seconds")
        fit = diagnose(state["history"], state["best_epoch"], self.patience, stopped_by,
                       *self._fit_losses(metrics))
        for w in fit["warnings"]:
            say(f"warning: {w}")
        metrics["training"] = {"epochs": state["epoch"], "best_epoch": state["best_epoch"],
                               "best_val_loss": state["best_val"], "seconds": state["seconds"],
                               "early_stopped": stopped_by == "patience", "stopped_by": stopped_by,
                               "max_epochs": self.max_epochs, "patience_epochs": self.patience,
                               "steps_per_epoch": steps, "steps": steps * state["epoch"], "fit": fit,
                               "samples_per_s": self.train_rows * state["epoch"]
                               / max(state["seconds"], 1e-9),
                               "cpu_seconds": state.get("cpu_seconds", 0.0),
                               "samples_per_cpu_s": self.train_rows * state["epoch"]
                               / max(state.get("cpu_seconds", 0.0), 1e-9),
                               "threads": cfg.threads, "parameters": sum(p.numel() for p in net.parameters())}
        write_json(build / "metrics.json", metrics)
        _write_history(build / "history.csv", state["history"])
        plot_curves(state["history"], build / "curves.png",
                    f"{cfg.task.upper()} {cfg.model} (IB = {cfg.ib}): training and validation loss")
        write_marker(build, "model")
        write_manifest(build, skip=(CHECKPOINT,))
        swap_in(build, self.out, ModelError, "model")
        return TrainResult(self.out, metrics, state["history"])

    def _fit_losses(self, metrics: dict[str, Any]) -> tuple[float, float]:
        """(training, validation) loss of the kept weights: the recipe's own evaluation of its
        training and validation rows where it reports both, else the history's best epoch (whose
        training loss is the epoch's running mean)."""
        tr, va = metrics.get("train", {}), metrics.get("val", {})
        if "loss" in tr and "loss" in va:
            return float(tr["loss"]), float(va["loss"])
        best = self.state["history"][max(self.state["best_epoch"], 1) - 1]
        return float(best["train_loss"]), float(best["val_loss"])


def _reusable(out: Path, cfg: TrainConfig, signature: str, split_sig: str, overwrite: bool
              ) -> TrainResult | None:
    """For a recipe without checkpoints: the finished model in `out` if it was trained with `cfg` on
    this data and split; None if there is none (or overwrite); ModelError if `out` holds another
    model."""
    if overwrite or not (out / CONFIG).is_file():
        return None
    saved = read_json(out / CONFIG)
    data = saved.get("data", {})
    diffs = setup_differences(saved["train"], data.get("signature"), data.get("split_signature"), cfg,
                              signature, split_sig, ignore=("threads", "device"))
    if diffs:
        raise ModelError(f"{out} holds a model with a different setup ({'; '.join(diffs)}); pass "
                         f"overwrite (--overwrite) or choose another --out")
    return TrainResult(out, read_json(out / "metrics.json"), read_history(out))


def _reused_selection(ds: Dataset, cfg: TrainConfig, out: Path, overwrite: bool) -> TrainResult | None:
    """The finished selection of `cfg` in `out` (ctrkin.training.selection) if it was made on this
    data and split; None if there is none (or overwrite); ModelError if `out` holds another setup."""
    if overwrite or not (out / "metrics.json").is_file():
        return None
    kept = read_json(out / "metrics.json").get("model_selection", {}).get("kept")
    if kept not in CANDIDATES:
        return None                     # not a selection: train_selecting refuses to replace it
    chosen = candidate_configs(cfg)[kept]
    _, rows = split_rows(ds, chosen)
    chosen = replace(chosen, max_epochs=chosen.epoch_budget(len(rows["train"])))
    return _reusable(out, chosen, data_signature(ds), split_signature(rows), overwrite=False)


def _needs_copy(device: torch.device) -> bool:
    """Whether the network trains as a copy on `device` (any device but the CPU; _Run)."""
    return device.type != "cpu"


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


def _write_history(path: Path, history: list[dict[str, float]]) -> None:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(history[0]))
    w.writeheader()
    w.writerows(history)
    atomic_write_text(path, buf.getvalue())
