"""Forward-kinematics experiments: model comparison and Δα0 ablation on held-out sequences (Fig. 5),
rotation sweeps with hysteresis and snaps (Fig. 10a), 20 random points (Fig. 10b) and the arbitrary
trajectory (Fig. 10c). Each compares the TCM, the learned models and the measurement (and truth)."""

from __future__ import annotations

from typing import Any

import numpy as np

from ctrkin.evaluation.context import Context, summary, valid_rows
from ctrkin.evaluation.metrics import azimuth_series, snap_score, snap_window, timing_stats
from ctrkin.evaluation.training_runs import ABLATION, BASELINES
from ctrkin.pose import position_error
from ctrkin.viz import experiments as fig

FK_MODELS = ("lstm_mlp", *BASELINES, ABLATION)


def fk_comparison(ctx: Context) -> dict[str, Any]:
    """Every FK predictor on the paper dataset's held-out test sequences."""
    ds = ctx.data.paper
    rows = valid_rows(ds, ds.get_split().test)
    measured, truth = ds.poses(), ctx.truth(ds)
    b = ds.sequence_bounds()
    near_snap = snap_window(ds.frame["snap"].to_numpy(), b)
    level = ds.frame["level"].to_numpy() if "level" in ds.frame else np.zeros(len(ds.frame), int)
    levels = [lv["relative_translation_mm"] for lv in ds.meta.get("levels", [])] or [0.0]
    preds = {m: ctx.fk(f"fk_{m}", ds)[rows] for m in FK_MODELS}
    tcm_pred, tcm_times = ctx.tcm_rows(ds, rows, "TCM on test rows")
    preds["tcm"] = tcm_pred
    out: dict[str, Any] = {}
    for name, pred in preds.items():
        r = summary(pred, measured[rows], truth[rows])
        snap_rows = near_snap[rows]
        r["at_snap"] = summary(pred, measured[rows], truth[rows], snap_rows) if snap_rows.any() else None
        r["away_from_snap"] = summary(pred, measured[rows], truth[rows], ~snap_rows)
        err = position_error(pred, measured[rows])
        r["position_mae_by_level_mm"] = {
            f"{levels[k]:g}": float(np.mean(err[level[rows] == k]))
            for k in range(len(levels))
            if (level[rows] == k).any()
        }
        out[name] = r
    out["tcm"]["timing"] = timing_stats(tcm_times)
    groups = list(out["lstm_mlp"]["position_mae_by_level_mm"])
    fig.grouped_bars(
        [f"d = {g} mm" for g in groups],
        {
            m: [out[m]["position_mae_by_level_mm"].get(g, np.nan) for g in groups]
            for m in ("lstm_mlp", *BASELINES, "tcm")
        },
        "position MAE on test sequences (mm)",
        ctx.figures / "fig5a_model_comparison.png",
        "Model comparison (Fig. 5a) by relative translation",
    )
    fig.grouped_bars(
        [f"d = {g} mm" for g in groups],
        {
            "with Δα0": [out["lstm_mlp"]["position_mae_by_level_mm"].get(g, np.nan) for g in groups],
            "without Δα0": [out[ABLATION]["position_mae_by_level_mm"].get(g, np.nan) for g in groups],
        },
        "position MAE on test sequences (mm)",
        ctx.figures / "fig5b_delta_ablation.png",
        "Directional parameter Δα0 (Fig. 5b)",
    )
    with_d, without = out["lstm_mlp"]["position_mae_mm"], out[ABLATION]["position_mae_mm"]
    out["ablation"] = {
        "position_mae_with_delta_mm": with_d,
        "position_mae_without_delta_mm": without,
        "mae_decrease_pct": 100.0 * (without - with_d) / without if without > 0 else 0.0,
    }
    return out


def sweeps(ctx: Context) -> dict[str, Any]:
    """Full inner rotations at five relative translations: hysteresis and snaps (Fig. 10a)."""
    ds = ctx.data.sweeps
    rows = valid_rows(ds)
    b = ds.sequence_bounds()
    n = ds.n_tubes
    joints, measured, truth = ds.joints(), ds.poses(), ctx.truth(ds)
    model = ctx.fk("fk_lstm_mlp", ds)
    tcm, tcm_times = ctx.tcm_rows(ds, np.arange(len(ds.frame)), "TCM on sweeps")
    az = {
        k: azimuth_series(p, joints, n, b)
        for k, p in (("measured", measured), ("truth", truth), ("model", model), ("tcm", tcm))
    }
    snap = ds.frame["snap"].to_numpy()
    near = snap_window(snap, b)
    levels = [lv["relative_translation_mm"] for lv in ds.meta.get("levels", [])]
    out: dict[str, Any] = {
        "lstm_mlp": summary(model[rows], measured[rows], truth[rows]),
        "tcm": summary(tcm[rows], measured[rows], truth[rows]),
    }
    out["position_rmse_mm"] = out["lstm_mlp"]["position_rmse_mm"]
    by_level, panels = {}, []
    lev = ds.frame["level"].to_numpy()
    for k, d in enumerate(levels):
        m = np.isin(np.arange(len(ds.frame)), rows) & (lev == k)
        entry = {
            "lstm_mlp": summary(model, measured, truth, m),
            "tcm": summary(tcm, measured, truth, m),
            "snap_samples": int(snap[lev == k].sum()),
        }
        if (snap & (lev == k)).any():
            entry["lstm_mlp_away_from_snap"] = summary(model, measured, truth, m & ~near)
            entry["lstm_mlp_at_snap"] = summary(model, measured, truth, m & near)
        by_level[f"{d:g}"] = entry
        sel = lev == k
        panels.append(
            {
                "label": f"d = {d:g} mm",
                "alpha0": joints[sel, 0] - joints[sel, n - 1],
                "measured": az["measured"][sel],
                "model": az["model"][sel],
                "tcm": az["tcm"][sel],
                "truth": az["truth"][sel],
                "snaps": snap[sel],
            }
        )
    out["by_level"] = by_level
    if snap.any():
        out["snapping_levels"] = {
            "lstm_mlp_away_from_snap": summary(
                model,
                measured,
                truth,
                np.isin(np.arange(len(ds.frame)), rows) & _snapping_sequences(ds) & ~near,
            ),
            "lstm_mlp_at_snap": summary(model, measured, truth, near),
        }
    out["snap_prediction"] = {
        "lstm_mlp_vs_measured": snap_score(az["model"], az["measured"], b).to_dict(),
        "lstm_mlp_vs_truth": snap_score(az["model"], az["truth"], b).to_dict(),
        "tcm_vs_measured": snap_score(az["tcm"], az["measured"], b).to_dict(),
    }
    out["tcm"]["timing"] = timing_stats(tcm_times)
    fig.sweeps_figure(panels, ctx.figures / "fig10a_sweeps.png")
    return out


def _snapping_sequences(ds: Any) -> np.ndarray:
    """(T,) bool: rows of sequences that contain a snap."""
    sid = ds.frame["sequence_id"].to_numpy()
    snapped = np.unique(sid[ds.frame["snap"].to_numpy()])
    return np.isin(sid, snapped)


def random_points(ctx: Context) -> dict[str, Any]:
    """20 random configurations, each reached from the previous one (Fig. 10b): errors at targets."""
    ds = ctx.data.random_points
    is_t = ds.frame["is_target"].to_numpy() if "is_target" in ds.frame else np.ones(len(ds.frame), bool)
    rows = valid_rows(ds, np.nonzero(is_t)[0])
    measured, truth = ds.poses(), ctx.truth(ds)
    model = ctx.fk("fk_lstm_mlp", ds)[rows]
    tcm, times = ctx.tcm_rows(ds, rows, "TCM on random points")
    out: dict[str, Any] = {
        "lstm_mlp": summary(model, measured[rows], truth[rows]),
        "tcm": summary(tcm, measured[rows], truth[rows]),
        "n_points": len(rows),
    }
    out["tcm"]["timing"] = timing_stats(times)
    out["position_rmse_mm"] = out["lstm_mlp"]["position_rmse_mm"]
    fig.points_figure(measured[rows], model, tcm, ctx.figures / "fig10b_random_points.png")
    return out


def arbitrary(ctx: Context) -> dict[str, Any]:
    """The paper's simultaneous path (Fig. 10c): errors along it and their distribution."""
    ds = ctx.data.arbitrary
    rows = valid_rows(ds)
    measured, truth = ds.poses(), ctx.truth(ds)
    model = ctx.fk("fk_lstm_mlp", ds)[rows]
    tcm, times = ctx.tcm_rows(ds, rows, "TCM on the arbitrary path")
    out = {
        "lstm_mlp": summary(model, measured[rows], truth[rows]),
        "tcm": summary(tcm, measured[rows], truth[rows]),
    }
    out["tcm"]["timing"] = timing_stats(times)
    out["position_rmse_mm"] = out["lstm_mlp"]["position_rmse_mm"]
    for name, p in (("lstm_mlp", model), ("tcm", tcm)):
        e = position_error(p, measured[rows])
        out[name]["position_error_percentiles_mm"] = {
            f"p{q}": float(np.percentile(e, q)) for q in (50, 90, 99)
        }
    fig.trajectory_figure(measured[rows], model, tcm, ctx.figures / "fig10c_arbitrary.png")
    return out
