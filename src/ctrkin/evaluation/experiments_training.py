"""What the training learned, as the paper shows it: the paper's LSTM-MLP with and without Δα0 along
the rotation sweeps at three overlaps (Fig. 6: low nonlinearity, higher nonlinearity, snapping) and the
training and validation loss of the FK and IK models (Fig. 9)."""

from __future__ import annotations

from typing import Any

import numpy as np

from ctrkin.evaluation.context import Context, valid_rows
from ctrkin.evaluation.experiments_fk import level_label
from ctrkin.evaluation.table import (
    ABLATION_ROW,
    FK_BRANCH_ROW,
    FK_PAPER_ROW,
    IK_FOLLOW_ROW,
    IK_PAPER_ROW,
    Experiment,
    Figure,
    Row,
)
from ctrkin.metrics import position_error
from ctrkin.training.curves import read_history
from ctrkin.viz import experiments as fig

FIG6 = Figure("fig6_delta_overlaps", "Fig. 6: Δα0 at three overlaps",
              "The measured tip (red) and the paper's LSTM-MLP's prediction with Δα0 among its inputs "
              "(blue) and without it (orange) along the full inner rotations 0 → 360 → 0° at the "
              "lowest, a middle and the highest relative translation d of the sweeps (x–y, mm; the "
              "paper's β12 = 15, 35, 55 on the paper robot). Each title gives both models' position "
              "MAE at that level. Without the direction of rotation the model cannot tell the two "
              "branches of the hysteresis loop apart.")
FIG9 = Figure("fig9_training_curves", "Fig. 9: training and validation loss",
              "Normalised MAE loss per epoch (log scale) of the FK models (a) and the IK models (b): "
              "training (solid) and validation (dashed); a dot marks each model's best validation "
              "epoch, the weights it keeps.")
CURVE_ROWS = (FK_PAPER_ROW, FK_BRANCH_ROW, IK_PAPER_ROW, IK_FOLLOW_ROW)


def _three(levels: list[float]) -> list[int]:
    """Indices of the lowest, a middle and the highest level (fewer where there are fewer)."""
    return sorted({0, len(levels) // 2, len(levels) - 1}) if levels else []


def delta_overlaps(ctx: Context, rows_: tuple[Row, ...]) -> dict[str, Any]:
    """Fig. 6: with and without Δα0 along the sweeps at three relative translations."""
    ds = ctx.data.sweeps
    measured = ds.poses()
    rows = np.zeros(len(ds.frame), bool)
    rows[valid_rows(ds)] = True
    level = ds.frame["level"].to_numpy()
    levels = [lv["relative_translation_mm"] for lv in ds.meta.get("levels", [])]
    preds = {r.name: ctx.fk(str(r.folder), ds) for r in rows_}
    out: dict[str, Any] = {}
    panels = []
    for k in _three(levels):
        m = rows & (level == k)
        if not m.any():
            continue
        mae = {name: float(np.mean(position_error(p[m], measured[m]))) for name, p in preds.items()}
        out[f"{levels[k]:g}"] = {f"{name}_position_mae_mm": v for name, v in mae.items()}
        panels.append({"label": level_label(levels[k], ds.robot), "measured": measured[m, :3],
                       "series": {r.label: (preds[r.name][m, :3], mae[r.name]) for r in rows_}})
    fig.delta_overlaps_figure(panels, ctx.figures / f"{FIG6.stem}.png")
    return {"by_level": out}


def training_curves(ctx: Context, rows_: tuple[Row, ...]) -> dict[str, Any]:
    """Fig. 9: each model's loss per epoch, from its folder's history.csv."""
    out: dict[str, Any] = {}
    curves: dict[str, dict[str, list[dict[str, float]]]] = {"fk": {}, "ik": {}}
    for r in rows_:
        model = ctx.models.get(str(r.folder))
        history = read_history(model.path) if model is not None and model.path is not None else []
        if not history:
            continue
        best = min(history, key=lambda h: h["val_loss"])
        out[f"{r.task}_{r.name}"] = {"epochs": len(history), "best_epoch": int(best["epoch"]),
                                     "best_val_loss": best["val_loss"],
                                     "final_train_loss": history[-1]["train_loss"]}
        curves[r.task][r.label] = history
    fig.training_curves_figure(curves, ctx.figures / f"{FIG9.stem}.png")
    return out


STAGE = "training: Δα0 at three overlaps and the loss curves (Fig. 6, 9)"
EXPERIMENTS = (
    Experiment("delta_overlaps", STAGE, delta_overlaps, (FK_PAPER_ROW, ABLATION_ROW), (FIG6,)),
    Experiment("training_curves", STAGE, training_curves, CURVE_ROWS, (FIG9,)),
)
