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

TCM, MODEL, MEAS, TRUE = "k", "tab:blue", "tab:red", "0.55"


def _save(fig: plt.Figure, path: str | Path) -> None:
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)


# T(L) curves of sweeps_figure: panel key -> (label, colour, line style, marker size)
TURN_CURVES = {
    "tcm": ("TCM (point-wise)", TCM, ".", 1.5),
    "tcm_continued": ("TCM (continued)", "tab:green", "-", 0.8),
    "measured": ("measured", MEAS, ".", 2.5),
    "lstm_mlp_paper": ("LSTM-MLP (paper)", "tab:orange", ".", 1.5),
    "lstm_mlp_branch": ("snap-aware LSTM-MLP", MODEL, "-", 1.0),
    "lstm_mlp_branch_tcm_gate": ("snap-aware, TCM-gated", "tab:purple", "-", 0.8),
    "lstm_mlp_branch_learned_gate": ("snap-aware, learned gate", "tab:pink", "-", 0.8),
    "truth": ("truth", TRUE, "--", 0.8),
}


def sweeps_figure(panels: Sequence[dict], path: str | Path) -> None:
    """Fig. 10a: T(L) against α0 for each relative translation (or each turn). panels: dicts with
    `label`, `alpha0` (T,), any of the TURN_CURVES keys as (T,) T(L) in deg, `snaps` (T,) bool."""
    n = len(panels)
    fig, axes = plt.subplots(1, n, figsize=(3.3 * n, 3.6), sharey=False, squeeze=False)
    for ax, p in zip(axes[0], panels, strict=True):
        a0 = np.asarray(p["alpha0"])
        for key, (label, colour, style, size) in TURN_CURVES.items():
            if p.get(key) is None:
                continue
            if style == ".":
                ax.plot(a0, p[key], ".", color=colour, ms=size, label=label)
            else:
                ax.plot(a0, p[key], style, color=colour, lw=size, label=label)
        sn = np.asarray(p.get("snaps", np.zeros(len(a0), bool)), bool)
        if sn.any() and p.get("measured") is not None:
            ax.plot(a0[sn], np.asarray(p["measured"])[sn], "x", color="k", ms=7, label="snap")
        ax.set_title(p["label"], fontsize=9)
        ax.set_xlabel("α0 (deg)")
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel("T(L) (deg)")
    axes[0][0].legend(fontsize=6, markerscale=3)
    _save(fig, path)


def points_figure(measured: np.ndarray, model: np.ndarray, tcm: np.ndarray, path: str | Path,
                  title: str = "Random points") -> None:
    """Fig. 10b: target points (x–y and x–z views, numbered) and per-point position errors."""
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.8))
    for ax, (i, j, lab) in zip(axes[:2], [(0, 1, "x–y"), (0, 2, "x–z")], strict=True):
        ax.plot(tcm[:, i], tcm[:, j], "s", color=TCM, mfc="none", label="TCM")
        ax.plot(measured[:, i], measured[:, j], "o", color=MEAS, label="measured")
        ax.plot(model[:, i], model[:, j], "+", color=MODEL, ms=9, label="LSTM-MLP")
        for num, p in enumerate(measured, start=1):
            ax.annotate(str(num), (p[i], p[j]), fontsize=6, xytext=(2, 2), textcoords="offset points")
        ax.set_xlabel("xyz"[i] + " (mm)")
        ax.set_ylabel("xyz"[j] + " (mm)")
        ax.set_title(f"{title}: {lab}", fontsize=9)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7)
    k = np.arange(1, len(measured) + 1)
    axes[2].bar(k - 0.2, np.linalg.norm(tcm[:, :3] - measured[:, :3], axis=1), 0.4, color=TCM, label="TCM")
    axes[2].bar(k + 0.2, np.linalg.norm(model[:, :3] - measured[:, :3], axis=1), 0.4, color=MODEL,
                label="LSTM-MLP")
    axes[2].set_xlabel("point")
    axes[2].set_ylabel("position error (mm)")
    axes[2].legend(fontsize=7)
    axes[2].grid(alpha=0.3, axis="y")
    _save(fig, path)


def trajectory_figure(measured: np.ndarray, model: np.ndarray, tcm: np.ndarray, path: str | Path) -> None:
    """Fig. 10c: the arbitrary path (x–y and x–z) and the distribution of position errors."""
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.8))
    for ax, (i, j) in zip(axes[:2], [(0, 1), (0, 2)], strict=True):
        ax.plot(tcm[:, i], tcm[:, j], "-", color=TCM, lw=1, label="TCM")
        ax.plot(measured[:, i], measured[:, j], "-", color=MEAS, lw=2, label="measured")
        ax.plot(model[:, i], model[:, j], "-", color=MODEL, lw=1, label="LSTM-MLP")
        ax.set_xlabel("xyz"[i] + " (mm)")
        ax.set_ylabel("xyz"[j] + " (mm)")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7)
    e_tcm = np.linalg.norm(tcm[:, :3] - measured[:, :3], axis=1)
    e_mod = np.linalg.norm(model[:, :3] - measured[:, :3], axis=1)
    top = float(np.nanmax(np.r_[e_tcm, e_mod, 1.0]))
    bins = np.linspace(0, top, 40)
    axes[2].hist(e_tcm, bins, color=TCM, alpha=0.5, density=True, label="TCM")
    axes[2].hist(e_mod, bins, color=MODEL, alpha=0.6, density=True, label="LSTM-MLP")
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


def grouped_bars(groups: Sequence[str], series: dict[str, Sequence[float]], ylabel: str,
                 path: str | Path, title: str) -> None:
    """Fig. 5: one bar per series in each group (e.g. models × relative translation levels)."""
    fig, ax = plt.subplots(figsize=(max(6, 1.1 * len(groups) * max(1, len(series)) / 2), 3.8))
    w = 0.8 / max(1, len(series))
    x = np.arange(len(groups))
    for k, (name, vals) in enumerate(series.items()):
        ax.bar(x + (k - (len(series) - 1) / 2) * w, vals, w, label=name)
    ax.set_xticks(x, groups)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    ax.legend(fontsize=7, ncol=min(4, len(series)))
    ax.grid(alpha=0.3, axis="y")
    _save(fig, path)


def grid_figure(rows: Sequence[str], cols: Sequence[str], values: np.ndarray, path: str | Path,
                title: str, fmt: str = "{:.3f}") -> None:
    """Tables II/III as a heat map (Fig. 7, 8): values (len(rows), len(cols))."""
    fig, ax = plt.subplots(figsize=(1.2 * len(cols) + 2, 0.6 * len(rows) + 1.5))
    im = ax.imshow(values, cmap="viridis_r", aspect="auto")
    ax.set_xticks(range(len(cols)), cols)
    ax.set_yticks(range(len(rows)), rows)
    for i in range(len(rows)):
        for j in range(len(cols)):
            if np.isfinite(values[i, j]):
                ax.text(j, i, fmt.format(values[i, j]), ha="center", va="center", fontsize=8, color="w")
    fig.colorbar(im, ax=ax)
    ax.set_title(title, fontsize=10)
    _save(fig, path)
