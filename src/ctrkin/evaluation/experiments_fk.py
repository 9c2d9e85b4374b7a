"""Forward-kinematics experiments: model comparison and Δα0 ablation on held-out sequences (Fig. 5),
rotation sweeps with hysteresis and snaps (Fig. 10a), full turns at full overlap off the training
grid (snap turns), 20 random points (Fig. 10b) and the arbitrary trajectory (Fig. 10c). Each
compares the TCM, the learned models (the paper's LSTM-MLP and the snap-aware model) and the
measurement (and truth); the TCM calibrated on the training rows (μ between the tubes included) is
a row beside them, point-wise (`tcm_calibrated`) and continued along each sequence
(`tcm_calibrated_continued`)."""

from __future__ import annotations

from typing import Any

import numpy as np

from ctrkin.data.dataset import Dataset
from ctrkin.evaluation.context import (
    FK_ROWS,
    HEADLINE,
    RECOMMENDED,
    Context,
    summary,
    valid_rows,
    with_headline,
)
from ctrkin.evaluation.snapping import (
    azimuth_series,
    glitch_window,
    rotation_direction,
    snap_report,
    snap_steps,
    snap_window,
)
from ctrkin.evaluation.training_runs import ABLATION, BASELINES
from ctrkin.metrics import position_error, timing_stats
from ctrkin.viz import experiments as fig

PAPER_ROW = "lstm_mlp_paper"


def fk_comparison(ctx: Context) -> dict[str, Any]:
    """Every FK predictor on the paper dataset's held-out test sequences."""
    ds = ctx.data.paper
    rows = valid_rows(ds, ds.get_split().test)
    measured, truth = ds.poses(), ctx.truth(ds)
    b = ds.sequence_bounds()
    near_snap = snap_window(ds.frame["snap"].to_numpy(), b)
    level = ds.frame["level"].to_numpy() if "level" in ds.frame else np.zeros(len(ds.frame), int)
    levels = [lv["relative_translation_mm"] for lv in ds.meta.get("levels", [])] or [0.0]
    preds = {name: p[rows] for name, p in ctx.fk_rows(ds).items()}
    preds |= {m: ctx.fk(f"fk_{m}", ds)[rows] for m in (*BASELINES, ABLATION)}
    tcm_pred, tcm_times = ctx.tcm_rows(ds, rows, "TCM on test rows")
    preds["tcm"] = tcm_pred
    preds |= ctx.calibrated_rows(ds, rows)
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
    groups = list(out[PAPER_ROW]["position_mae_by_level_mm"])
    fig.grouped_bars(
        [f"d = {g} mm" for g in groups],
        {
            m: [out[m]["position_mae_by_level_mm"].get(g, np.nan) for g in groups]
            for m in (*FK_ROWS, *BASELINES, "tcm")
        },
        "position MAE (mm)",
        ctx.figures / "fig5a_model_comparison.png",
        "FK models (Fig. 5a): position MAE on the test sequences, by relative translation d",
    )
    fig.grouped_bars(
        [f"d = {g} mm" for g in groups],
        {
            "with Δα0": [out[PAPER_ROW]["position_mae_by_level_mm"].get(g, np.nan) for g in groups],
            "without Δα0": [out[ABLATION]["position_mae_by_level_mm"].get(g, np.nan) for g in groups],
        },
        "position MAE (mm)",
        ctx.figures / "fig5b_delta_ablation.png",
        "Δα0 (Fig. 5b): the paper's LSTM-MLP, position MAE on the test sequences",
    )
    with_d, without = out[PAPER_ROW]["position_mae_mm"], out[ABLATION]["position_mae_mm"]
    out["ablation"] = {
        "position_mae_with_delta_mm": with_d,
        "position_mae_without_delta_mm": without,
        "mae_decrease_pct": 100.0 * (without - with_d) / without if without > 0 else 0.0,
    }
    return with_headline(out, "fk")


def _turn_predictions(ctx: Context, ds: Dataset) -> dict[str, np.ndarray]:
    """Every predictor of a turn experiment: learned rows, point-wise and continued TCM."""
    preds = dict(ctx.fk_rows(ds))
    preds["tcm"], _ = ctx.tcm_rows(ds, np.arange(len(ds.frame)), "TCM")
    preds["tcm_continued"] = ctx.tcm_continued(ds)
    preds |= ctx.calibrated_rows(ds, np.arange(len(ds.frame)))
    return preds


def _turn_azimuths(ctx: Context, ds: Dataset, preds: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """T(L) (deg) of every predictor, the measurement and the truth over ds, unwrapped per sequence."""
    series = {**preds, "measured": ds.poses(), "truth": ctx.truth(ds)}
    b, joints = ds.sequence_bounds(), ds.joints()
    return {k: azimuth_series(p, joints, ds.n_tubes, b) for k, p in series.items()}


def _snap_turn_scores(ctx: Context, ds: Dataset, preds: dict[str, np.ndarray],
                      az: dict[str, np.ndarray]) -> dict[str, Any]:
    """Per predictor: snap events vs truth (headline) and vs measured, per direction; position
    error vs truth on the two steps at each true snap and away from them. az: _turn_azimuths."""
    b = ds.sequence_bounds()
    truth = ctx.truth(ds)
    rows = np.zeros(len(ds.frame), bool)
    rows[valid_rows(ds)] = True
    direction = rotation_direction(ds.joints(), ds.n_tubes, b)
    true_snap = np.zeros(len(ds.frame), bool)
    true_snap[snap_steps(az["truth"], b)] = True
    near = snap_window(true_snap, b)
    keep = ~glitch_window(ds.frame["outlier"].to_numpy(), b)
    out: dict[str, Any] = {}
    for name, p in preds.items():
        e = position_error(p, truth)
        out[name] = {
            **snap_report(az[name], az["truth"], b, direction, keep),
            "vs_measured": snap_report(az[name], az["measured"], b, direction, keep),
            "position_at_snap_true_mm": float(np.mean(e[rows & near])) if (rows & near).any() else None,
            "position_away_from_snap_true_mm": float(np.mean(e[rows & ~near])),
        }
    return out


def sweeps(ctx: Context) -> dict[str, Any]:
    """Full inner rotations at five relative translations: hysteresis and snaps (Fig. 10a)."""
    ds = ctx.data.sweeps
    rows = valid_rows(ds)
    b = ds.sequence_bounds()
    n = ds.n_tubes
    joints, measured, truth = ds.joints(), ds.poses(), ctx.truth(ds)
    preds = _turn_predictions(ctx, ds)
    az = _turn_azimuths(ctx, ds, preds)
    snap = ds.frame["snap"].to_numpy()
    near = snap_window(snap, b)
    levels = [lv["relative_translation_mm"] for lv in ds.meta.get("levels", [])]
    out: dict[str, Any] = {k: summary(p[rows], measured[rows], truth[rows]) for k, p in preds.items()}
    out = with_headline(out, "fk")
    out["position_rmse_mm"] = out[HEADLINE]["position_rmse_mm"]
    by_level, panels = {}, []
    lev = ds.frame["level"].to_numpy()
    in_rows = np.isin(np.arange(len(ds.frame)), rows)
    for k, d in enumerate(levels):
        m = in_rows & (lev == k)
        entry: dict[str, Any] = {name: summary(p, measured, truth, m) for name, p in preds.items()}
        entry["snap_samples"] = int(snap[lev == k].sum())
        if (snap & (lev == k)).any():
            for name in FK_ROWS:
                entry[f"{name}_away_from_snap"] = summary(preds[name], measured, truth, m & ~near)
                entry[f"{name}_at_snap"] = summary(preds[name], measured, truth, m & near)
        by_level[f"{d:g}"] = entry
        sel = lev == k
        panels.append({"label": f"d = {d:g} mm", "alpha0": joints[sel, 0] - joints[sel, n - 1],
                       "snaps": snap[sel], **{key: series[sel] for key, series in az.items()}})
    out["by_level"] = by_level
    if snap.any():
        out["snapping_levels"] = {
            f"{name}_{where}": summary(preds[name], measured, truth,
                                       (in_rows & _snapping_sequences(ds) & ~near)
                                       if where == "away_from_snap" else near)
            for name in FK_ROWS for where in ("away_from_snap", "at_snap")
        }
    out["snap_prediction"] = _snap_turn_scores(ctx, ds, preds, az)
    fig.sweeps_figure(panels, ctx.figures / "fig10a_sweeps.png")
    return out


def snap_turns(ctx: Context) -> dict[str, Any]:
    """Full turns at full overlap at outer angles and translations the training never recorded."""
    ds = ctx.data.snap_turns
    preds = _turn_predictions(ctx, ds)
    b = ds.sequence_bounds()
    n = ds.n_tubes
    joints, truth, measured = ds.joints(), ctx.truth(ds), ds.poses()
    rows = valid_rows(ds)
    out: dict[str, Any] = {k: summary(p[rows], measured[rows], truth[rows]) for k, p in preds.items()}
    out = with_headline(out, "fk")
    az = _turn_azimuths(ctx, ds, preds)
    out["snap_prediction"] = _snap_turn_scores(ctx, ds, preds, az)
    out["outer_angles_deg"] = ds.meta.get("protocol_params", {}).get("outer_angles_deg")
    panels = []
    for a, c in b:
        panels.append({"label": f"αN = {joints[a, n - 1]:.0f}°, βN = {joints[a, 2 * n - 1]:.2f} mm",
                       "alpha0": joints[a:c, 0] - joints[a:c, n - 1],
                       "snaps": ds.frame["snap"].to_numpy()[a:c],
                       **{key: series[a:c] for key, series in az.items()}})
    fig.sweeps_figure(panels, ctx.figures / "snap_turns.png")
    return out


def _snapping_sequences(ds: Any) -> np.ndarray:
    """(T,) bool: rows of sequences that contain a snap."""
    sid = ds.frame["sequence_id"].to_numpy()
    snapped = np.unique(sid[ds.frame["snap"].to_numpy()])
    return np.isin(sid, snapped)


def _point_rows(ctx: Context, ds: Dataset, rows: np.ndarray, desc: str) -> dict[str, Any]:
    """Learned rows and the TCM at `rows` of ds: summaries (headline included) and predictions."""
    measured, truth = ds.poses(), ctx.truth(ds)
    preds = {name: p[rows] for name, p in ctx.fk_rows(ds).items()}
    tcm, times = ctx.tcm_rows(ds, rows, desc)
    preds["tcm"] = tcm
    preds |= ctx.calibrated_rows(ds, rows)
    out: dict[str, Any] = {k: summary(p, measured[rows], truth[rows]) for k, p in preds.items()}
    out["tcm"]["timing"] = timing_stats(times)
    out = with_headline(out, "fk")
    out["position_rmse_mm"] = out[HEADLINE]["position_rmse_mm"]
    return {"results": out, "preds": preds}


def random_points(ctx: Context) -> dict[str, Any]:
    """20 random configurations, each reached from the previous one (Fig. 10b): errors at targets."""
    ds = ctx.data.random_points
    is_t = ds.frame["is_target"].to_numpy() if "is_target" in ds.frame else np.ones(len(ds.frame), bool)
    rows = valid_rows(ds, np.nonzero(is_t)[0])
    r = _point_rows(ctx, ds, rows, "TCM on random points")
    out, preds = r["results"], r["preds"]
    out["n_points"] = len(rows)
    fig.points_figure(ds.poses()[rows], preds[RECOMMENDED["fk"]], preds["tcm"],
                      ctx.figures / "fig10b_random_points.png", model_label=fig.LABELS[RECOMMENDED["fk"]])
    return out


def arbitrary(ctx: Context) -> dict[str, Any]:
    """The paper's simultaneous path (Fig. 10c): errors along it and their distribution."""
    ds = ctx.data.arbitrary
    rows = valid_rows(ds)
    measured = ds.poses()[rows]
    r = _point_rows(ctx, ds, rows, "TCM on the arbitrary path")
    out, preds = r["results"], r["preds"]
    for name, p in preds.items():
        e = position_error(p, measured)
        out[name]["position_error_percentiles_mm"] = {f"p{q}": float(np.percentile(e, q))
                                                      for q in (50, 90, 99)}
    fig.trajectory_figure(measured, preds[RECOMMENDED["fk"]], preds["tcm"],
                          ctx.figures / "fig10c_arbitrary.png", model_label=fig.LABELS[RECOMMENDED["fk"]])
    return out
