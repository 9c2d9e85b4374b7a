"""Every model a reproduction trains: the paper's LSTM-MLP FK and IK models, the snap-aware FK
model (lstm_mlp_branch), the baselines and the Δα0 ablation (Fig. 5), and the input-buffer and
structure grids (Tables II, III). The refined IK (the IK model refined on the snap-aware FK,
ctrkin.families.refined.refine) is assembled from two trained folders, not trained.

All runs use the same by-sequence split of the paper dataset (saved in it), so every model is tested
on the same held-out sequences. The recommended models (TRAINED_WITH_EXCITATION: the snap-aware FK
and the follow IK) also train on the excitation protocol's runs (ctrkin.acquisition.excitation),
added to their training rows only (ctrkin.evaluation.datasets.with_training_runs, the folder
`training_dir`); the paper's own models, baselines and grids train on the paper protocol alone, as
the paper ran them. Grid and comparison models may see fewer training sequences
(ReproScale.grid_sequences) to keep the quick scale within minutes.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from ctrkin.data.dataset import Dataset
from ctrkin.errors import CtrkinError
from ctrkin.evaluation.executors import run_jobs
from ctrkin.evaluation.scales import Budget, ReproScale
from ctrkin.evaluation.table import (
    ABLATION,
    BASELINES,
    FK_BRANCH,
    FK_PAPER,
    IK_FOLLOW,
    IK_PAPER,
    IK_REFINED,
    RECOMMENDED,
)
from ctrkin.families.refined.folder import assemble_refined
from ctrkin.inference import Kinematics
from ctrkin.training.config import (
    FK_FOLD_SCALE,
    FK_JOINT_FIELD,
    FK_PLAY_LAGS,
    IK_CATCH_UP,
    IK_OUTER_ANGLE,
    TrainConfig,
)
from ctrkin.training.device import resolve_device
from ctrkin.training.engine import train
from ctrkin.util.progress import progress_bar

# the recommended FK and IK (table.RECOMMENDED) train on the paper protocol + the excitation runs
TRAINED_WITH_EXCITATION = tuple(str(row.folder) for row in RECOMMENDED.values())


@dataclass(frozen=True)
class Run:
    """name: folder and results name; role: main | compare | grid."""

    name: str
    role: str
    config: TrainConfig


def plan_runs(scale: ReproScale) -> list[Run]:
    def cfg(budget: Budget, **kw: Any) -> TrainConfig:
        kw = {"ib": budget.ib, **kw}          # the grids' own IB wins
        return TrainConfig(
            max_epochs=budget.epochs,
            patience=budget.patience,
            batch_size=budget.batch_size,
            lr=budget.lr,
            lr_schedule=budget.lr_schedule,
            val_smoothing=budget.val_smoothing,
            fused_adam=budget.fused_adam,
            fused_lstm=budget.fused_adam,     # a budget that keeps its old weights keeps nn.LSTM too
            split="dataset",
            **kw,
        )

    runs = [
        Run(FK_PAPER, "main", cfg(scale.main, task="fk")),
        Run(IK_PAPER, "main", cfg(scale.main, task="ik")),
        Run(FK_BRANCH, "main", cfg(scale.branch, task="fk", model="lstm_mlp_branch", play_lags=FK_PLAY_LAGS,
                                   joint_field=FK_JOINT_FIELD, fold_scale=FK_FOLD_SCALE)),
        Run(IK_FOLLOW, "main", cfg(scale.follow, task="ik", model="follow_mlp", outer_angle=IK_OUTER_ANGLE,
                                   catch_up=IK_CATCH_UP)),
    ]
    runs += [Run(f"fk_{m}", "compare", cfg(scale.compare, task="fk", model=m)) for m in BASELINES]
    runs += [Run(f"fk_{ABLATION}", "compare", cfg(scale.compare, task="fk", model=ABLATION))]
    for task in ("fk", "ik"):
        runs += [
            Run(f"grid_{task}_ib{ib}", "grid", cfg(scale.grid, task=task, ib=ib)) for ib in scale.ib_grid
        ]
    runs += [
        Run(f"grid_fk_ib{ib}_{s}", "grid", cfg(scale.grid, task="fk", ib=ib, options={"structure": s}))
        for ib in scale.structure_ibs
        for s in scale.structure_grid
    ]
    return runs


def with_fewer_sequences(ds: Dataset, n_sequences: int | None, seed: int = 0) -> Dataset:
    """The same dataset and split, but only n training sequences (a seeded draw, so every level of
    the protocol is represented) used for training."""
    split = ds.get_split()
    if n_sequences is None:
        return ds
    sid = ds.frame["sequence_id"].to_numpy()
    seqs = np.unique(sid[split.train])
    keep = np.random.default_rng(seed).choice(seqs, size=min(n_sequences, len(seqs)), replace=False)
    small = replace(split, train=split.train[np.isin(sid[split.train], keep)])
    return Dataset(ds.frame, ds.robot, ds.meta, split=small)


def _train_run(dataset_dir: str, n_sequences: int | None, cfg: dict[str, Any], out: str) -> str:
    """One run in a worker process (loads the dataset itself: workers are spawned, not forked,
    because a forked torch/OpenMP runtime can hang)."""
    ds = Dataset.load(dataset_dir)
    data = with_fewer_sequences(ds, n_sequences)
    train(data, TrainConfig.from_dict(cfg), out, overwrite=False, progress=False, log=None)
    return out


def training_jobs(runs: list[Run], dataset_dir: Path, scale: ReproScale, out: Path, device: str,
                  training_dir: Path | None = None) -> list[tuple[str, int | None, dict[str, Any], str]]:
    """The arguments of `_train_run` for each of `runs`, in their order: (dataset folder, training
    sequences or None, the configuration dict with one torch thread on `device` (a torch device
    type), model folder out/<name>). train_all's jobs; benchmarks/bench_train_stage.py times the same."""
    jobs = []
    for run in runs:
        cfg = {**replace(run.config, threads=1).to_dict(), "device": device}
        n_seq = None if run.role == "main" else scale.grid_sequences
        with_extra = training_dir is not None and run.name in TRAINED_WITH_EXCITATION
        data_dir = training_dir if with_extra else dataset_dir
        jobs.append((str(data_dir), n_seq, cfg, str(out / run.name)))
    return jobs


def train_all(
    dataset_dir: Path, scale: ReproScale, out: Path, workers: int = 2, log: Callable[[str], None] = print,
    executor: str = "local", device: str = "auto", training_dir: Path | None = None,
) -> dict[str, Kinematics]:
    """Train (or resume / reuse) every run into out/<name>, `workers` runs at a time with one torch
    thread each (two single-threaded runs use two cores better than one run with two threads);
    returns the loaded models. dataset_dir: the saved paper dataset with its split; executor:
    "local" (spawned processes) or "ray" (Ray tasks of one CPU each, ctrkin.evaluation.executors;
    the same results for the same seeds); device: auto | cpu | cuda (ctrkin.training.device), resolved
    here once, so that auto says once where the runs train (the Ray executor's tasks train on the
    CPU: they reserve no GPU); training_dir: the saved paper dataset with the excitation runs among its
    training rows, which the TRAINED_WITH_EXCITATION runs train on (None: dataset_dir)."""
    if executor == "ray" and device != "cpu":        # Ray hides the GPUs from tasks that reserve none
        if device == "cuda":
            raise CtrkinError("--device cuda with --executor ray: the Ray tasks reserve CPUs only; pass "
                              "--device cpu, or use the local executor to train on a GPU")
        log("--device auto with --executor ray: the Ray tasks reserve CPUs only, training on the CPU")
        device = "cpu"
    torch_device, note = resolve_device(device)
    if note:
        log(note)
    runs = plan_runs(scale)
    jobs = training_jobs(runs, dataset_dir, scale, out, torch_device.type, training_dir)
    with progress_bar(total=len(runs), desc="train models", unit="model") as bar:
        for k in run_jobs(_train_run, jobs, executor=executor, workers=workers, threads=1):
            bar.update(1)
            log(f"trained {runs[k].name}")
    models = {run.name: Kinematics.load(out / run.name) for run in runs}
    assemble_refined(out / IK_PAPER, out / FK_BRANCH, out / IK_REFINED)
    models[IK_REFINED] = Kinematics.load(out / IK_REFINED)
    return models
