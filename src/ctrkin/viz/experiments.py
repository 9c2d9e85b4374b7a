"""Figures of the reproduction, one function per paper figure. Colours follow the paper: TCM black,
learned model blue, measurement red (truth, which hardware cannot give, grey dashed)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from ctrkin.util.files import atomic_path

TCM, MODEL, MEAS, TRUE = "k", "tab:blue", "tab:red", "0.3"


def _save(fig: plt.Figure, path: str | Path) -> None:
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)


# T(L) curves of sweeps_figure: panel key -> (label, colour, kind, size); kind "points": markers,
# filled forward and open backward; "line": solid forward, dashed backward. The predictors' curves
# come from the report's table (ctrkin.evaluation.table.Row.curve); these two are the data's.
MEASURED_CURVE = ("measured", MEAS, "points", 2.5)
TRUTH_CURVE = ("truth", TRUE, "line", 0.8)
Curves = dict[str, tuple[str, str, str, float]]


def _directions(a0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(T,) bool forward (α0 not decreasing, judged on the step into the row, the first row by the
    step out of it) and (T,) bool breaks: rows that start a new stretch (direction change, or an α0
    jump of more than 10°, e.g. a new sequence) so that lines are not drawn across them."""
    d = np.diff(a0)
    fw = np.r_[d[:1] >= 0, d >= 0] if len(a0) > 1 else np.ones(len(a0), bool)
    brk = np.r_[True, (fw[1:] != fw[:-1]) | (np.abs(d) > 10.0)]
    return fw, brk


def _stretch(y: np.ndarray, keep: np.ndarray, brk: np.ndarray) -> np.ndarray:
    """y with NaN outside `keep` and before each break, so that one plot call draws separate lines."""
    out = np.where(keep, y, np.nan).astype(float)
    starts = np.nonzero(brk)[0]
    return np.insert(out, starts[starts > 0], np.nan)


def _turn_axes(ax: plt.Axes, p: dict, curves: Curves) -> None:
    """One panel of sweeps_figure (see there)."""
    a0 = np.asarray(p["alpha0"], float)
    fw, brk = _directions(a0)
    # shift T(L) by whole turns so that the measurement sits in [−180°, 180°) (unwrapping can
    # leave it a turn away; the curves keep their relative positions)
    ref = np.asarray(p.get("measured", p.get("truth", np.zeros(1))), float)
    shift = 360.0 * np.round(np.nanmedian(ref) / 360.0) if np.isfinite(ref).any() else 0.0
    for key, (_label, colour, kind, size) in curves.items():
        if p.get(key) is None:
            continue
        y = np.asarray(p[key], float) - shift
        if kind == "points":
            ax.plot(a0[fw], y[fw], "o", color=colour, ms=size, mew=0, ls="none")
            ax.plot(a0[~fw], y[~fw], "o", color=colour, ms=size, mfc="none", mew=0.5, ls="none")
        else:
            x = np.insert(a0, np.nonzero(brk)[0][1:], np.nan)
            ax.plot(x, _stretch(y, fw, brk), "-", color=colour, lw=size)
            ax.plot(x, _stretch(y, ~fw, brk), "--", color=colour, lw=size)
    sn = np.asarray(p.get("snaps", np.zeros(len(a0), bool)), bool)
    if sn.any() and p.get("measured") is not None:
        ax.plot(a0[sn], np.asarray(p["measured"], float)[sn] - shift, "x", color="k", ms=8, mew=1.8)
    ax.set_title(p["label"], fontsize=9)
    ax.set_xlabel("α0 = α1 − αN (deg)")
    ax.grid(alpha=0.3)


def _turn_legend(fig: plt.Figure, keys: set[str], curves: Curves) -> None:
    """One legend for all panels: every curve drawn, the two directions, and the snap marker."""
    from matplotlib.lines import Line2D

    handles = []
    for key, (label, colour, kind, _size) in curves.items():
        if key in keys:
            handles.append(Line2D([], [], color=colour, marker="o" if kind == "points" else None,
                                  ls="none" if kind == "points" else "-", ms=5, lw=1.5, label=label))
    handles += [Line2D([], [], color="0.3", ls="-", label="forward (α0 increasing)"),
                Line2D([], [], color="0.3", ls="--", label="backward"),
                Line2D([], [], color="0.3", marker="o", ls="none", mfc="none", label="measured, backward"),
                Line2D([], [], color="k", marker="x", ls="none", ms=8, mew=1.8, label="snap (in the data)")]
    fig.legend(handles=handles, loc="lower center", ncol=min(6, len(handles)), fontsize=7, frameon=False)


def sweeps_figure(panels: Sequence[dict], path: str | Path, curves: Curves) -> None:
    """Fig. 10a: T(L) against α0 for each relative translation (or each turn). panels: dicts with
    `label`, `alpha0` (T,) deg, any of the keys of `curves` as (T,) T(L) in deg, `snaps` (T,) bool;
    curves: key -> (label, colour, kind, size), drawn in this order (the last on top).
    The direction of rotation is read from α0: forward solid / filled, backward dashed / open."""
    n = len(panels)
    cols = min(n, 3)
    rows = -(-n // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(4.6 * cols, 3.6 * rows + 1.0), squeeze=False)
    for ax, p in zip(axes.flat, panels, strict=False):
        _turn_axes(ax, p, curves)
    for ax in list(axes.flat)[n:]:
        ax.set_visible(False)
    for ax in axes[:, 0]:
        ax.set_ylabel("T(L) (deg)")
    _turn_legend(fig, {k for p in panels for k in curves if p.get(k) is not None}, curves)
    fig.tight_layout(rect=(0, 0.1 if rows == 1 else 0.06, 1, 1))
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)


def points_figure(measured: np.ndarray, model: np.ndarray, tcm: np.ndarray, path: str | Path,
                  title: str = "Random points", model_label: str = "model", tcm_label: str = "TCM") -> None:
    """Fig. 10b: target points (x–y and x–z views, numbered) and per-point position errors."""
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.8))
    for ax, (i, j, lab) in zip(axes[:2], [(0, 1, "x–y"), (0, 2, "x–z")], strict=True):
        ax.plot(tcm[:, i], tcm[:, j], "s", color=TCM, mfc="none", label=tcm_label)
        ax.plot(measured[:, i], measured[:, j], "o", color=MEAS, label="measured")
        ax.plot(model[:, i], model[:, j], "+", color=MODEL, ms=9, label=model_label)
        for num, p in enumerate(measured, start=1):
            ax.annotate(str(num), (p[i], p[j]), fontsize=6, xytext=(2, 2), textcoords="offset points")
        ax.set_xlabel("xyz"[i] + " (mm)")
        ax.set_ylabel("xyz"[j] + " (mm)")
        ax.set_title(f"{title}: {lab}", fontsize=9)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7)
    k = np.arange(1, len(measured) + 1)
    axes[2].bar(k - 0.2, np.linalg.norm(tcm[:, :3] - measured[:, :3], axis=1), 0.4, color=TCM,
                label=tcm_label)
    axes[2].bar(k + 0.2, np.linalg.norm(model[:, :3] - measured[:, :3], axis=1), 0.4, color=MODEL,
                label=model_label)
    axes[2].set_xlabel("point")
    axes[2].set_ylabel("position error (mm)")
    axes[2].legend(fontsize=7)
    axes[2].grid(alpha=0.3, axis="y")
    _save(fig, path)


def trajectory_figure(measured: np.ndarray, model: np.ndarray, tcm: np.ndarray, path: str | Path,
                      model_label: str = "model", tcm_label: str = "TCM") -> None:
    """Fig. 10c: the arbitrary path (x–y and x–z) and the distribution of position errors."""
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.8))
    for ax, (i, j) in zip(axes[:2], [(0, 1), (0, 2)], strict=True):
        ax.plot(tcm[:, i], tcm[:, j], "-", color=TCM, lw=1, label=tcm_label)
        ax.plot(measured[:, i], measured[:, j], "-", color=MEAS, lw=2, label="measured")
        ax.plot(model[:, i], model[:, j], "-", color=MODEL, lw=1, label=model_label)
        ax.set_xlabel("xyz"[i] + " (mm)")
        ax.set_ylabel("xyz"[j] + " (mm)")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7)
    e_tcm = np.linalg.norm(tcm[:, :3] - measured[:, :3], axis=1)
    e_mod = np.linalg.norm(model[:, :3] - measured[:, :3], axis=1)
    top = float(np.nanmax(np.r_[e_tcm, e_mod, 1.0]))
    bins = np.linspace(0, top, 40)
    axes[2].hist(e_tcm, bins, color=TCM, alpha=0.5, density=True, label=tcm_label)
    axes[2].hist(e_mod, bins, color=MODEL, alpha=0.6, density=True, label=model_label)
    axes[2].set_xlabel("position error (mm)")
    axes[2].set_ylabel("density")
    axes[2].legend(fontsize=7)
    _save(fig, path)


def ik_points_figure(joints_true: np.ndarray, joints_pred: np.ndarray, targets: np.ndarray,
                     reached_fk: np.ndarray, reached_robot: np.ndarray, path: str | Path) -> None:
    """Fig. 11: (a) predicted vs true joints per point, (b) targets vs the tips reached."""
    n = joints_true.shape[1] // 2
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.8))
    k = np.arange(1, len(targets) + 1)
    for i in range(n):
        axes[0].plot(k, joints_true[:, i], "o", mfc="none", color=f"C{i}", label=f"α{i + 1} true")
        axes[0].plot(k, joints_pred[:, i], "x", color=f"C{i}", label=f"α{i + 1} IK")
        axes[1].plot(k, joints_true[:, n + i], "o", mfc="none", color=f"C{i}", label=f"β{i + 1} true")
        axes[1].plot(k, joints_pred[:, n + i], "x", color=f"C{i}", label=f"β{i + 1} IK")
    axes[0].set_ylabel("α (deg)")
    axes[1].set_ylabel("β (mm)")
    for ax in axes[:2]:
        ax.set_xlabel("point")
        ax.legend(fontsize=6, ncol=2)
        ax.grid(alpha=0.3)
    axes[2].plot(targets[:, 0], targets[:, 1], "o", color=MEAS, mfc="none", ms=8, label="target")
    axes[2].plot(reached_fk[:, 0], reached_fk[:, 1], "+", color=MODEL, ms=9, label="IK → FK model")
    axes[2].plot(reached_robot[:, 0], reached_robot[:, 1], "x", color="tab:green", label="IK → robot")
    axes[2].set_xlabel("x (mm)")
    axes[2].set_ylabel("y (mm)")
    axes[2].legend(fontsize=7)
    axes[2].grid(alpha=0.3)
    _save(fig, path)


def ik_path_figure(targets: np.ndarray, reached_fk: np.ndarray, reached_robot: np.ndarray,
                   joints_pred: np.ndarray, path: str | Path, title: str) -> None:
    """Fig. 12: a task-space path, the tips reached through the FK model and the robot, and the
    predicted joints along it."""
    n = joints_pred.shape[1] // 2
    fig = plt.figure(figsize=(12, 3.8))
    ax3 = fig.add_subplot(1, 3, 1, projection="3d")
    ax3.plot(*targets[:, :3].T, "o-", color=MEAS, label="target")
    ax3.plot(*reached_fk[:, :3].T, "+-", color=MODEL, label="IK → FK model")
    ax3.plot(*reached_robot[:, :3].T, "x--", color="tab:green", label="IK → robot")
    ax3.set_xlabel("x (mm)", fontsize=8)
    ax3.set_ylabel("y (mm)", fontsize=8)
    ax3.set_zlabel("z (mm)", fontsize=8)
    ax3.set_title(title, fontsize=9)
    ax3.legend(fontsize=6)
    k = np.arange(1, len(targets) + 1)
    ax = fig.add_subplot(1, 3, 2)
    for i in range(n):
        ax.plot(k, joints_pred[:, i], "o-", label=f"α{i + 1}")
    ax.set_ylabel("α (deg)")
    ax.set_xlabel("point")
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    ax = fig.add_subplot(1, 3, 3)
    for i in range(n):
        ax.plot(k, joints_pred[:, n + i], "o-", label=f"β{i + 1}")
    ax.set_ylabel("β (mm)")
    ax.set_xlabel("point")
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    _save(fig, path)


def delta_overlaps_figure(panels: Sequence[dict], path: str | Path) -> None:
    """Fig. 6: per panel (a relative translation) the measured tip and each model's prediction in the
    x–y plane. panels: dicts with `label`, `measured` (T, 3) mm and `series`: label -> (prediction
    (T, 3) mm, position MAE mm); the first series in the model colour, the others after it."""
    fig, axes = plt.subplots(1, max(len(panels), 1), figsize=(4.4 * max(len(panels), 1), 4.2),
                             squeeze=False)
    for ax, p in zip(axes[0], panels, strict=False):
        ax.plot(p["measured"][:, 0], p["measured"][:, 1], "o", color=MEAS, ms=2.5, label="measured")
        maes = []
        for k, (label, (pred, mae)) in enumerate(p["series"].items()):
            colour = MODEL if k == 0 else f"C{k}"
            ax.plot(pred[:, 0], pred[:, 1], "-", color=colour, lw=1.0, label=label)
            maes.append(f"{mae:.2f}")
        ax.set_title(f"{p['label']}\nMAE {' / '.join(maes)} mm", fontsize=9)
        ax.set_xlabel("x (mm)")
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(alpha=0.3)
    axes[0, 0].set_ylabel("y (mm)")
    if panels:
        axes[0, 0].legend(fontsize=7)
    _save(fig, path)


def training_curves_figure(curves: dict[str, dict[str, list[dict[str, float]]]], path: str | Path) -> None:
    """Fig. 9: training (solid) and validation (dashed) loss per epoch of each model, one panel per
    task. curves: task ("fk", "ik") -> model label -> history (dicts with 'epoch', 'train_loss',
    'val_loss'); the best validation epoch is marked."""
    fig, axes = plt.subplots(1, len(curves), figsize=(5.2 * len(curves), 3.8), squeeze=False)
    for ax, (task, models), tag in zip(axes[0], curves.items(), "abcdefgh", strict=False):
        for k, (label, history) in enumerate(models.items()):
            ep = [h["epoch"] for h in history]
            ax.plot(ep, [h["train_loss"] for h in history], "-", color=f"C{k}", label=f"{label}: training")
            ax.plot(ep, [h["val_loss"] for h in history], "--", color=f"C{k}", label=f"{label}: validation")
            best = min(history, key=lambda h: h["val_loss"])
            ax.plot(best["epoch"], best["val_loss"], "o", color=f"C{k}", ms=5)
        ax.set_yscale("log")
        ax.set_xlabel("epoch")
        ax.set_title(f"({tag}) {task.upper()}", fontsize=10)
        ax.grid(alpha=0.3, which="both")
        if models:
            ax.legend(fontsize=7)
    axes[0, 0].set_ylabel("MAE loss (normalised)")
    _save(fig, path)


def grouped_bars(groups: Sequence[str], series: dict[str, Sequence[float]], ylabel: str,
                 path: str | Path, title: str, colours: dict[str, str] | None = None) -> None:
    """Fig. 5: one bar per series in each group (e.g. models × relative translation levels); series:
    legend label -> values per group; colours: label -> colour where not the cycle's (the TCM's)."""
    fig, ax = plt.subplots(figsize=(min(11, max(6, 0.3 * len(groups) * max(1, len(series)))), 3.8))
    w = 0.8 / max(1, len(series))
    x = np.arange(len(groups))
    for k, (name, vals) in enumerate(series.items()):
        ax.bar(x + (k - (len(series) - 1) / 2) * w, vals, w, label=name,
               color=(colours or {}).get(name, f"C{k}"))
    ax.set_xticks(x, groups)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    ax.legend(fontsize=7, ncol=min(4, len(series)))
    ax.grid(alpha=0.3, axis="y")
    _save(fig, path)


def grid_figure(rows: Sequence[str], cols: Sequence[str], values: np.ndarray, path: str | Path,
                title: str, fmt: str = "{:.3f}", units: Sequence[str] | None = None) -> None:
    """Tables II/III as heat maps (Fig. 7, 8): values (len(rows), len(cols)); units (len(rows),):
    the unit of each row (default: one unit). Rows of one unit share one colour scale and colour
    bar, so that mm and deg never share a scale; darker is larger (worse, for errors)."""
    values = np.asarray(values, float)
    units = list(units) if units is not None else [""] * len(rows)
    groups = list(dict.fromkeys(units))
    idx = [[i for i, u in enumerate(units) if u == g] for g in groups]
    fig, axes = plt.subplots(len(groups), 1, squeeze=False,
                             figsize=(1.3 * len(cols) + 3.2, 0.55 * len(rows) + 1.0 * len(groups) + 0.6),
                             gridspec_kw={"height_ratios": [len(i) for i in idx]})
    for ax, unit, sel in zip(axes[:, 0], groups, idx, strict=True):
        v = values[sel]
        finite = v[np.isfinite(v)]
        lo, hi = (float(finite.min()), float(finite.max())) if finite.size else (0.0, 1.0)
        im = ax.imshow(v, cmap="viridis_r", aspect="auto", vmin=lo, vmax=hi if hi > lo else lo + 1e-9)
        ax.set_xticks(range(len(cols)), cols)
        ax.set_yticks(range(len(sel)), [rows[i] for i in sel])
        for i in range(len(sel)):
            for j in range(len(cols)):
                if np.isfinite(v[i, j]):
                    dark = (v[i, j] - lo) / (hi - lo) > 0.5 if hi > lo else False
                    ax.text(j, i, fmt.format(v[i, j]), ha="center", va="center", fontsize=8,
                            color="w" if dark else "k")
        fig.colorbar(im, ax=ax, label=unit)
    axes[0, 0].set_title(title, fontsize=10)
    _save(fig, path)
