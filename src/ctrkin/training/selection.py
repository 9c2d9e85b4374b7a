"""Keep an FK's extra inputs only where validation says the data identify them (TrainConfig.select_inputs).

The recommended FK's play lags (ctrkin.models.play_lags) and joint field (ctrkin.models.joint_field)
are a memory of the joint path and a field of the tracker, learned from data. They help where the
recording holds what identifies them: reversals at many places along each joint, a tracker field
over the workspace (the reproduction's protocols; benchmarks/bench_fk_memory.py). A log with one
amplitude of sweep ties each lag to the joint and the direction of motion; the network then fits
whatever the few other rows say and extrapolates it on a new path (the comet-lab OptiTrack logs:
docs/real_robot.md: 5. Train). Nothing in the lags or the field tells which case a log is; validation does.

    requested   the configuration as given (lags and/or field on)
    plain       the same network without lags and field, same seed and split

Both are trained, each into a hidden sibling of `out` (`.NAME.select-requested`, `.NAME.select-plain`:
a killed selection resumes each from its checkpoint); the one with the lower validation position RMSE
(metrics.json val.vs_measured.position_mm_rmse; the requested one on a tie or without validation
rows) gets the metrics entry `input_selection` and is swapped in whole for `out`, the other removed.
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
from ctrkin.models.store import write_json
from ctrkin.training.config import TrainConfig
from ctrkin.util.folders import swap_in, write_manifest

CANDIDATES = ("requested", "plain")
CHECKPOINT = "checkpoint.pt"

TrainOne = Callable[[Dataset, TrainConfig, Path, bool, bool, Callable[[str], None]], Any]


def selects_inputs(cfg: TrainConfig) -> bool:
    """Whether `cfg` asks for a selection that has something to select."""
    return cfg.select_inputs and (cfg.play_lags or cfg.joint_field)


def candidate_configs(cfg: TrainConfig) -> dict[str, TrainConfig]:
    """The two configurations a selection trains (module docstring)."""
    return {"requested": cfg, "plain": replace(cfg, play_lags=False, joint_field=False)}


def candidate_folder(out: Path, name: str) -> Path:
    return out.with_name(f".{out.name}.select-{name}")


def validation_rmse(metrics: dict[str, Any]) -> float | None:
    """The validation rows' position RMSE (mm) of a model's metrics, None without validation rows."""
    value = metrics.get("val", {}).get("vs_measured", {}).get("position_mm_rmse")
    return None if value is None else float(value)


def choose(val_rmse: dict[str, float | None]) -> str:
    """The candidate kept: the lowest validation RMSE; the requested one on a tie or where either
    lacks a figure."""
    req, plain = val_rmse["requested"], val_rmse["plain"]
    return "plain" if req is not None and plain is not None and plain < req else "requested"


def train_selecting(ds: Dataset, cfg: TrainConfig, out: Path, overwrite: bool, progress: bool,
                    say: Callable[[str], None], train_one: TrainOne) -> Any:
    """Train both candidates with `train_one` (the engine's locked training of one folder), keep the
    one validation prefers in `out` (module docstring). Call it holding `out`'s writer lock."""
    if os.path.isdir(out) and os.listdir(out) and not overwrite:
        raise ModelError(f"{out} already holds a model; selecting the FK's inputs writes a new one: "
                         "pass overwrite (--overwrite) or choose another --out")
    results, val = {}, {}
    for name, c in candidate_configs(cfg).items():
        say(f"input selection: training the {name} network "
            f"(play lags {'on' if c.play_lags else 'off'}, joint field {'on' if c.joint_field else 'off'})")
        results[name] = train_one(ds, c, candidate_folder(out, name), overwrite, progress, say)
        val[name] = validation_rmse(results[name].metrics)
    kept = choose(val)
    shown = {k: "–" if v is None else f"{v:.3f} mm" for k, v in val.items()}
    say(f"input selection: validation position RMSE requested {shown['requested']}, plain "
        f"{shown['plain']}: keeping the {kept} network")
    folder = candidate_folder(out, kept)
    metrics = {**results[kept].metrics, "input_selection": {
        "kept": kept, "val_position_rmse_mm": val,
        "candidates": {k: {"play_lags": c.play_lags, "joint_field": c.joint_field}
                       for k, c in candidate_configs(cfg).items()}}}
    write_json(folder / "metrics.json", metrics)
    write_manifest(folder, skip=(CHECKPOINT,))
    swap_in(folder, out, ModelError, "model")
    for name in CANDIDATES:
        if name != kept:
            shutil.rmtree(candidate_folder(out, name), ignore_errors=True)
    return replace(results[kept], out=out, metrics=metrics)
