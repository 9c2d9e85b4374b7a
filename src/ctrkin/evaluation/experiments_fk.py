"""Forward-kinematics experiments: model comparison and Δα0 ablation on held-out sequences (Fig. 5),
rotation sweeps with hysteresis and snaps (Fig. 10a), full turns at full overlap off the training
grid (snap turns), 20 random points (Fig. 10b) and the arbitrary trajectory (Fig. 10c). Each
compares the TCM, the learned models (the paper's LSTM-MLP and the snap-aware model) and the
measurement (and truth); the TCM calibrated on the training rows (μ between the tubes included) is
a row beside them, point-wise (`tcm_calibrated`) and continued along each sequence
(`tcm_calibrated_continued`)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ctrkin.acquisition.trajectories import relative_translation_to_paper_level
from ctrkin.data.dataset import Dataset
from ctrkin.evaluation.context import Context, summary, valid_rows
from ctrkin.evaluation.snapping import (
    azimuth_series,
    glitch_window,
    rotation_direction,
    snap_report,
    snap_steps,
    snap_window,
)
from ctrkin.evaluation.table import (
    ABLATION_ROW,
    BASELINE_ROWS,
    FK_BRANCH_ROW,
    FK_LEARNED,
    FK_PAPER_ROW,
    HEADLINE,
    RECOMMENDED,
    TCM_CALIBRATED_ROWS,
    TCM_COLOUR,
    TCM_CONTINUED_ROW,
    TCM_ROW,
    Experiment,
    Figure,
    Row,
    fk_predictions,
    with_headline,
)
from ctrkin.metrics import position_error, timing_stats
from ctrkin.robots import Robot, paper_robot
from ctrkin.viz import experiments as fig


def turn_curves(rows: Sequence[Row]) -> fig.Curves:
    """The T(L) curves of the turn figures, in drawing order: the measurement, the rows drawn as
    points, the rows drawn as lines with the recommended FK model's last, and the truth (a thin line
    on top: under the predictions it was hidden wherever they are right)."""
    drawn = [r for r in rows if r.curve is not None]
    points = [r for r in drawn if r.curve is not None and r.curve.kind == "points"]
    lines = sorted((r for r in drawn if r not in points), key=lambda r: r is RECOMMENDED["fk"])
    out: fig.Curves = {"measured": fig.MEASURED_CURVE}
    out |= {r.name: (r.label, *r.curve) for r in points if r.curve is not None}
    out |= {r.name: (r.label, *r.curve) for r in lines if r.curve is not None}
    out["truth"] = fig.TRUTH_CURVE
    return out


SNAPPING_ROWS = (FK_PAPER_ROW.name, FK_BRANCH_ROW.name)   # scored at and away from the snaps per level
TURNS = (
    "Solid lines and filled dots: forward (α0 increasing); dashed lines and open dots: backward, so "
    "the gap between a predictor's two curves is its hysteresis. Black crosses: the snaps flagged in "
    "the data. The point-wise TCM has no history, so its forward and "
    "backward points coincide; the continued TCM follows the equilibrium branch and snaps at its "
    "folds. The snap-aware model's gate ablations are scored in the snap-prediction table, not drawn."
)
FIG5A = Figure("fig5a_model_comparison", "Fig. 5a: FK model comparison",
               "Position MAE (mm, lower is better) of every FK model and the point-wise TCM on the "
               "held-out test sequences, per relative translation d of the paper protocol. The paper "
               "plotted normalised training MAE; the table above gives RMSE and MAE over all levels.")
FIG5B = Figure("fig5b_delta_ablation", "Fig. 5b: the directional parameter Δα0",
               "Position MAE (mm) of the paper's LSTM-MLP trained with and without Δα0 among its inputs, "
               "per relative translation d, on the held-out test sequences.")
FIG10A = Figure("fig10a_sweeps", "Fig. 10a: rotation sweeps",
                "T(L), the tip azimuth measured from the outer tube's base rotation (deg), against the "
                "relative rotation α0 = α1 − αN (deg), for full inner rotations 0 → 360 → 0° at each "
                "relative translation d (one panel each, low nonlinearity to snapping; on the paper "
                "robot each title also gives the paper's level β12 = 15..55). " + TURNS)
FIG_SNAP_TURNS = Figure("snap_turns", "Snap turns (beyond the paper)",
                    "As Fig. 10a, for full turns at full overlap at outer angles αN and translations βN that "
                    "the training data never recorded (one panel each). " + TURNS)
FIG10B = Figure("fig10b_random_points", "Fig. 10b: random points",
                "The 20 random targets, numbered in the order visited: measured tip, the snap-aware "
                "LSTM-MLP's and the point-wise TCM's predictions in the x–y and x–z planes (mm), and each "
                "point's position error against the measurement.")
FIG10C = Figure("fig10c_arbitrary", "Fig. 10c: arbitrary path",
                "The paper's simultaneous trajectory: measured tip, snap-aware LSTM-MLP and point-wise "
                "TCM in the x–y and x–z planes (mm), and the distribution of their position errors "
                "against the measurement.")


def level_label(d: float, robot: Robot) -> str:
    """A relative translation level's panel title: d, and on the paper robot the paper's own name of
    the level (β12 = 15..55 for d = 4..20 mm, ctrkin.acquisition.trajectories)."""
    if robot.fingerprint() != paper_robot().fingerprint():
        return f"d = {d:g} mm"
    return f"d = {d:g} mm (paper β12 = {relative_translation_to_paper_level(d):g})"


def fk_comparison(ctx: Context, rows_: tuple[Row, ...]) -> dict[str, Any]:
    """Every FK predictor on the paper dataset's held-out test sequences."""
    ds = ctx.data.paper
    rows = valid_rows(ds, ds.get_split().test)
    measured, truth = ds.poses(), ctx.truth(ds)
    b = ds.sequence_bounds()
    near_snap = snap_window(ds.frame["snap"].to_numpy(), b)
    level = ds.frame["level"].to_numpy() if "level" in ds.frame else np.zeros(len(ds.frame), int)
    levels = [lv["relative_translation_mm"] for lv in ds.meta.get("levels", [])] or [0.0]
    preds, tcm_times = fk_predictions(ctx, rows_, ds, rows, "TCM on test rows")
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
    if tcm_times is not None:
        out[TCM_ROW.name]["timing"] = timing_stats(tcm_times)
    paper, ablation = FK_PAPER_ROW.name, ABLATION_ROW.name
    groups = list(out[paper]["position_mae_by_level_mm"])
    fig.grouped_bars(
        [f"d = {g} mm" for g in groups],
        {r.label: [out[r.name]["position_mae_by_level_mm"].get(g, np.nan) for g in groups]
         for r in rows_ if r.bars},
        "position MAE (mm)",
        ctx.figures / f"{FIG5A.stem}.png",
        "FK models (Fig. 5a): position MAE on the test sequences, by relative translation d",
        colours={TCM_ROW.label: TCM_COLOUR},
    )
    fig.grouped_bars(
        [f"d = {g} mm" for g in groups],
        {
            "with Δα0": [out[paper]["position_mae_by_level_mm"].get(g, np.nan) for g in groups],
            "without Δα0": [out[ablation]["position_mae_by_level_mm"].get(g, np.nan) for g in groups],
        },
        "position MAE (mm)",
        ctx.figures / f"{FIG5B.stem}.png",
        "Δα0 (Fig. 5b): the paper's LSTM-MLP, position MAE on the test sequences",
    )
    with_d, without = out[paper]["position_mae_mm"], out[ablation]["position_mae_mm"]
    out["ablation"] = {
        "position_mae_with_delta_mm": with_d,
        "position_mae_without_delta_mm": without,
        "mae_decrease_pct": 100.0 * (without - with_d) / without if without > 0 else 0.0,
    }
    return with_headline(out, "fk")


def _turn_predictions(ctx: Context, rows: tuple[Row, ...], ds: Dataset) -> dict[str, np.ndarray]:
    """Every predictor of a turn experiment over every row of ds."""
    return fk_predictions(ctx, rows, ds, np.arange(len(ds.frame)), "TCM")[0]


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


def sweeps(ctx: Context, rows_: tuple[Row, ...]) -> dict[str, Any]:
    """Full inner rotations at five relative translations: hysteresis and snaps (Fig. 10a)."""
    ds = ctx.data.sweeps
    rows = valid_rows(ds)
    b = ds.sequence_bounds()
    n = ds.n_tubes
    joints, measured, truth = ds.joints(), ds.poses(), ctx.truth(ds)
    preds = _turn_predictions(ctx, rows_, ds)
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
            for name in SNAPPING_ROWS:
                entry[f"{name}_away_from_snap"] = summary(preds[name], measured, truth, m & ~near)
                entry[f"{name}_at_snap"] = summary(preds[name], measured, truth, m & near)
        by_level[f"{d:g}"] = entry
        sel = lev == k
        panels.append({"label": level_label(d, ds.robot), "alpha0": joints[sel, 0] - joints[sel, n - 1],
                       "snaps": snap[sel], **{key: series[sel] for key, series in az.items()}})
    out["by_level"] = by_level
    if snap.any():
        out["snapping_levels"] = {
            f"{name}_{where}": summary(preds[name], measured, truth,
                                       (in_rows & _snapping_sequences(ds) & ~near)
                                       if where == "away_from_snap" else near)
            for name in SNAPPING_ROWS for where in ("away_from_snap", "at_snap")
        }
    out["snap_prediction"] = _snap_turn_scores(ctx, ds, preds, az)
    fig.sweeps_figure(panels, ctx.figures / f"{FIG10A.stem}.png", turn_curves(rows_))
    return out


def snap_turns(ctx: Context, rows_: tuple[Row, ...]) -> dict[str, Any]:
    """Full turns at full overlap at outer angles and translations the training never recorded."""
    ds = ctx.data.snap_turns
    preds = _turn_predictions(ctx, rows_, ds)
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
    fig.sweeps_figure(panels, ctx.figures / f"{FIG_SNAP_TURNS.stem}.png", turn_curves(rows_))
    return out


def _snapping_sequences(ds: Any) -> np.ndarray:
    """(T,) bool: rows of sequences that contain a snap."""
    sid = ds.frame["sequence_id"].to_numpy()
    snapped = np.unique(sid[ds.frame["snap"].to_numpy()])
    return np.isin(sid, snapped)


def _point_rows(ctx: Context, rows_: tuple[Row, ...], ds: Dataset, rows: np.ndarray, desc: str
                ) -> dict[str, Any]:
    """The predictors at `rows` of ds: summaries (headline included) and predictions."""
    measured, truth = ds.poses(), ctx.truth(ds)
    preds, times = fk_predictions(ctx, rows_, ds, rows, desc)
    out: dict[str, Any] = {k: summary(p, measured[rows], truth[rows]) for k, p in preds.items()}
    if times is not None:
        out[TCM_ROW.name]["timing"] = timing_stats(times)
    out = with_headline(out, "fk")
    out["position_rmse_mm"] = out[HEADLINE]["position_rmse_mm"]
    return {"results": out, "preds": preds}


def random_points(ctx: Context, rows_: tuple[Row, ...]) -> dict[str, Any]:
    """20 random configurations, each reached from the previous one (Fig. 10b): errors at targets."""
    ds = ctx.data.random_points
    is_t = ds.frame["is_target"].to_numpy() if "is_target" in ds.frame else np.ones(len(ds.frame), bool)
    rows = valid_rows(ds, np.nonzero(is_t)[0])
    r = _point_rows(ctx, rows_, ds, rows, "TCM on random points")
    out, preds = r["results"], r["preds"]
    out["n_points"] = len(rows)
    model = RECOMMENDED["fk"]
    fig.points_figure(ds.poses()[rows], preds[model.name], preds[TCM_ROW.name],
                      ctx.figures / f"{FIG10B.stem}.png", model_label=model.label, tcm_label=TCM_ROW.label)
    return out


def arbitrary(ctx: Context, rows_: tuple[Row, ...]) -> dict[str, Any]:
    """The paper's simultaneous path (Fig. 10c): errors along it and their distribution."""
    ds = ctx.data.arbitrary
    rows = valid_rows(ds)
    measured = ds.poses()[rows]
    r = _point_rows(ctx, rows_, ds, rows, "TCM on the arbitrary path")
    out, preds = r["results"], r["preds"]
    for name, p in preds.items():
        e = position_error(p, measured)
        out[name]["position_error_percentiles_mm"] = {f"p{q}": float(np.percentile(e, q))
                                                      for q in (50, 90, 99)}
    model = RECOMMENDED["fk"]
    fig.trajectory_figure(measured, preds[model.name], preds[TCM_ROW.name],
                          ctx.figures / f"{FIG10C.stem}.png", model_label=model.label,
                          tcm_label=TCM_ROW.label)
    return out


TURN_ROWS = (*FK_LEARNED, TCM_ROW, TCM_CONTINUED_ROW, *TCM_CALIBRATED_ROWS)
POINT_ROWS = (*FK_LEARNED, TCM_ROW, *TCM_CALIBRATED_ROWS)
FK_COMPARISON = Experiment("fk", "FK: model comparison on held-out sequences (Fig. 5)", fk_comparison,
                           (*FK_LEARNED, *BASELINE_ROWS, ABLATION_ROW, TCM_ROW, *TCM_CALIBRATED_ROWS),
                           (FIG5A, FIG5B), top_level=True)
SWEEPS = Experiment("sweeps", "FK experiment: sweeps (Fig. 10)", sweeps, TURN_ROWS, (FIG10A,), section="fk")
RANDOM_POINTS = Experiment("random_points", "FK experiment: random_points (Fig. 10)", random_points,
                           POINT_ROWS, (FIG10B,), section="fk")
ARBITRARY = Experiment("arbitrary", "FK experiment: arbitrary (Fig. 10)", arbitrary, POINT_ROWS,
                       (FIG10C,), section="fk")
SNAP_TURNS = Experiment("snap_turns", "FK experiment: snap_turns (Fig. 10)", snap_turns, TURN_ROWS,
                        (FIG_SNAP_TURNS,), section="fk")
EXPERIMENTS = (FK_COMPARISON, SWEEPS, RANDOM_POINTS, ARBITRARY, SNAP_TURNS)
