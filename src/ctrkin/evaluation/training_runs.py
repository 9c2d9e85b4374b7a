"""Every model a reproduction trains: the LSTM-MLP FK and IK models, the baselines and the Δα0
ablation (Fig. 5), and the input-buffer and structure grids (Tables II, III).

All runs use the same by-sequence split of the paper dataset (saved in it), so every model is tested
on the same held-out sequences. Grid and comparison models may see fewer training sequences
(ReproScale.grid_sequences) to keep the quick scale within minutes.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from ctrkin.data.dataset import Dataset
from ctrkin.evaluation.scales import Budget, ReproScale
from ctrkin.inference import Kinematics
from ctrkin.training.config import TrainConfig
from ctrkin.training.loop import train

BASELINES = ("mlp", "lstm", "cnn", "tcn", "resnet")
ABLATION = "lstm_mlp_no_delta"


@dataclass(frozen=True)
class Run:
    """name: folder and results name; role: main | compare | grid."""

    name: str
    role: str
    config: TrainConfig


def plan_runs(scale: ReproScale) -> list[Run]:
    def cfg(budget: Budget, **kw: Any) -> TrainConfig:
        return TrainConfig(
            max_epochs=budget.epochs,
            patience=budget.patience,
            batch_size=budget.batch_size,
            split="dataset",
            **kw,
        )

    runs = [
        Run("fk_lstm_mlp", "main", cfg(scale.main, task="fk")),
        Run("ik_lstm_mlp", "main", cfg(scale.main, task="ik")),
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


def with_fewer_sequences(ds: Dataset, n_sequences: int | None) -> Dataset:
    """The same dataset and split, but only the first n training sequences used for training."""
    split = ds.get_split()
    if n_sequences is None:
        return ds
    sid = ds.frame["sequence_id"].to_numpy()
    train_seqs = np.unique(sid[split.train])[:n_sequences]
    train = split.train[np.isin(sid[split.train], train_seqs)]
    small = replace(split, train=train)
    return Dataset(ds.frame, ds.robot, ds.meta, split=small)


def train_all(ds: Dataset, scale: ReproScale, out: Path, log=print) -> dict[str, Kinematics]:
    """Train (or resume / reuse) every run into out/<name>; returns the loaded models."""
    models: dict[str, Kinematics] = {}
    runs = plan_runs(scale)
    small = with_fewer_sequences(ds, scale.grid_sequences)
    for k, run in enumerate(runs, 1):
        data = ds if run.role == "main" else small
        log(
            f"[{k}/{len(runs)}] train {run.name} ({run.config.task}, {run.config.model}, "
            f"IB {run.config.ib}, up to {run.config.max_epochs} epochs)"
        )
        train(data, run.config, out / run.name, overwrite=False, progress=True, log=None)
        models[run.name] = Kinematics.load(out / run.name)
    return models
