"""The planned tip path in 3-D, coloured by its stability margin, with the naive plan's snaps (and,
beside it, the learned snap model's margin per step)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from ctrkin.util.files import atomic_path


def plot_plan(tips: np.ndarray, margin: np.ndarray, targets: np.ndarray, reached: np.ndarray,
              path: str | Path, naive_tips: np.ndarray | None = None,
              naive_snaps: np.ndarray | None = None, title: str = "Snap-safe plan",
              learned_margin: np.ndarray | None = None) -> None:
    """tips (T, 3) mm and margin (T,) of the plan's steps; targets (K, 3) mm, reached (K,) bool;
    naive_tips (S, 3) and naive_snaps (S,) bool: the naive plan's executed tips and where it
    snapped (a cross at the tip after each snap); learned_margin (T,) deg: the learned snap model's
    margin per step, drawn beside the mechanics' against the step. Written atomically as PNG."""
    fig = plt.figure(figsize=(7.5, 6.5) if learned_margin is None else (13.0, 6.5))
    ax = fig.add_subplot(1, 1 if learned_margin is None else 2, 1, projection="3d")
    if naive_tips is not None and len(naive_tips):
        ax.plot(*naive_tips.T, "-", color="0.6", lw=1.0, label="naive IK, executed")
        sn = np.asarray(naive_snaps, bool)
        if sn.any():
            ax.scatter(*naive_tips[sn].T, marker="x", s=80, color="red", linewidths=2,
                       label=f"naive IK's snaps ({int(sn.sum())})")
    ax.plot(*tips.T, "-", color="0.2", lw=0.6)
    sc = ax.scatter(*tips.T, c=np.clip(margin, 0.0, 1.0), cmap="viridis", vmin=0.0, vmax=1.0, s=12,
                    label="plan (margin)")
    ok = np.asarray(reached, bool)
    ax.scatter(*targets[ok].T, marker="o", s=60, facecolors="none", edgecolors="k", label="target reached")
    if (~ok).any():
        ax.scatter(*targets[~ok].T, marker="s", s=60, facecolors="none", edgecolors="red",
                   label="target not reached on the branch")
    fig.colorbar(sc, ax=ax, shrink=0.6, label="stability margin (1 aligned, 0 fold)")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_zlabel("z (mm)")
    ax.set_title(title)
    ax.legend(fontsize=7, loc="upper left")
    if learned_margin is not None:
        ax2 = fig.add_subplot(1, 2, 2)
        steps = np.arange(len(margin))
        ax2.plot(steps, learned_margin, "-", color="tab:orange", label="learned: inner rotation left (deg)")
        ax2.set_xlabel("step")
        ax2.set_ylabel("learned margin (deg of inner rotation before its predicted snap)")
        ax3 = ax2.twinx()
        ax3.plot(steps, margin, "-", color="tab:blue", label="mechanics: stability margin")
        ax3.set_ylabel("mechanics margin (1 aligned, 0 fold)")
        ax3.set_ylim(0.0, 1.05)
        ax2.set_ylim(0.0, max(1.0, float(np.nanmax(learned_margin))) * 1.05)
        ax2.legend(handles=ax2.get_lines() + ax3.get_lines(), fontsize=7, loc="lower left")
        ax2.set_title("margins along the plan")
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
