"""Keep an FK's assumptions only where validation says the data carry them (TrainConfig.select_by_validation).

The recommended FK assumes more than the paper's network: two branches and a fold gate (a robot that
snaps where its folds say), the outer tube's frame, the play lags of the joint path
(ctrkin.models.play_lags) and a field of the tracker (ctrkin.models.joint_field). Each is learned
from data and helps where the recording holds what identifies it: snaps, reversals at many places
along each joint, a tracker field over the workspace (the reproduction's protocols;
benchmarks/bench_fk_memory.py). A log of one amplitude of sweep without snaps holds none of it: the
lags are then tied to the joint and the direction of motion, the network fits whatever the few other
rows say and extrapolates it on a new path (the comet-lab OptiTrack logs: docs/real_robot.md: 5.
Train). Nothing in the model tells which case a log is; validation does.

    requested   the configuration as given
    paper       the paper's LSTM-MLP (sin/cos angles, tracker frame, no lags, no field, no prior) with
                the requested budget, seed and split

Both are trained, each into a hidden sibling of `out` (`.NAME.select-requested`, `.NAME.select-paper`:
a killed selection resumes each from its checkpoint); the one with the lower validation position RMSE
(metrics.json val.vs_measured.position_mm_rmse; the requested one on a tie or without validation
rows) gets the metrics entry `model_selection` and is swapped in whole for `out`, the other removed.
The same command again reuses a finished selection of the same setup (the engine's
`_reused_selection`); a folder holding another model is replaced only with overwrite.
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

from ctrkin.data.dataset import Dataset
from ctrkin.errors import ModelError
from ctrkin.models.store import CHECKPOINT, write_json
from ctrkin.training.config import TrainConfig
from ctrkin.util.folders import swap_in, write_manifest

CANDIDATES = ("requested", "paper")

TrainOne = Callable[[Dataset, TrainConfig, Path, bool, bool, Callable[[str], None]], Any]


def paper_baseline(cfg: TrainConfig) -> TrainConfig:
    """The paper's LSTM-MLP FK with `cfg`'s budget, seed, split and data settings (and its
    select_by_validation, which has nothing to select for the paper's network: `selects`)."""
    return replace(cfg, model="lstm_mlp", options={}, angle_encoding="sincos", target_frame="tracker",
                   output_activation="relu", play_lags=False, joint_field=False, tcm_prior=False,
                   equivariant=False, fold_scale=False)


def selects(cfg: TrainConfig) -> bool:
    """Whether `cfg` asks for a selection that has something to select."""
    return cfg.select_by_validation and cfg.task == "fk" and paper_baseline(cfg).to_dict() != cfg.to_dict()


def candidate_configs(cfg: TrainConfig) -> dict[str, TrainConfig]:
    """The two configurations a selection trains (module docstring)."""
    return {"requested": cfg, "paper": paper_baseline(cfg)}


def candidate_folder(out: Path, name: str) -> Path:
    return out.with_name(f".{out.name}.select-{name}")


def validation_rmse(metrics: dict[str, Any]) -> float | None:
    """The validation rows' position RMSE (mm) of a model's metrics, None without validation rows."""
    value = metrics.get("val", {}).get("vs_measured", {}).get("position_mm_rmse")
    return None if value is None else float(value)


def choose(val_rmse: dict[str, float | None]) -> str:
    """The candidate kept: the lowest validation RMSE; the requested one on a tie or where either
    lacks a figure."""
    req, paper = val_rmse["requested"], val_rmse["paper"]
    return "paper" if req is not None and paper is not None and paper < req else "requested"


def train_selecting(ds: Dataset, cfg: TrainConfig, out: Path, overwrite: bool, progress: bool,
                    say: Callable[[str], None], train_one: TrainOne) -> Any:
    """Train both candidates with `train_one` (the engine's locked training of one folder), keep the
    one validation prefers in `out` (module docstring). Call it holding `out`'s writer lock."""
    if os.path.isdir(out) and os.listdir(out) and not overwrite:
        raise ModelError(f"{out} already holds a model; a selection by validation writes a new one: "
                         "pass overwrite (--overwrite) or choose another --out")
    configs = candidate_configs(cfg)
    results, val = {}, {}
    for name, c in configs.items():
        say(f"selection by validation: training the {name} model ({c.model})")
        results[name] = train_one(ds, c, candidate_folder(out, name), overwrite, progress, say)
        val[name] = validation_rmse(results[name].metrics)
    kept = choose(val)
    shown = {k: "–" if v is None else f"{v:.3f} mm" for k, v in val.items()}
    say(f"selection by validation: position RMSE on the validation rows {shown['requested']} "
        f"({cfg.model}) against {shown['paper']} (the paper's lstm_mlp): keeping the {kept} model")
    folder = candidate_folder(out, kept)
    metrics = {**results[kept].metrics, "model_selection": {
        "kept": kept, "val_position_rmse_mm": val,
        "candidates": {k: {"model": c.model, "play_lags": c.play_lags, "joint_field": c.joint_field}
                       for k, c in configs.items()}}}
    write_json(folder / "metrics.json", metrics)
    write_manifest(folder, skip=(CHECKPOINT,))
    swap_in(folder, out, ModelError, "model")
    for name in CANDIDATES:
        if name != kept:
            shutil.rmtree(candidate_folder(out, name), ignore_errors=True)
    return replace(results[kept], out=out, metrics=metrics)
