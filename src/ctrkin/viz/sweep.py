"""Plot T(L) against the relative rotation α0 for rotation sweeps (paper Fig. 2b)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from ctrkin.util.files import atomic_path


def plot_sweeps(curves: list[dict], path: str | Path, title: str = "Rotation sweeps") -> None:
    """curves: dicts with `label`, `alpha0` (T,) deg, `azimuth` (T,) deg, `snaps` (T,) bool and
    `forward` (T,) bool (rotation direction), optionally `folds_frictionless` (T,) bool: where the
    same robot without friction snaps. Snaps are marked with a cross, frictionless folds with a
    circle on the curve."""
    fig, ax = plt.subplots(figsize=(8, 5.5))
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for k, c in enumerate(curves):
        col = colors[k % len(colors)]
        fw = np.asarray(c["forward"], bool)
        a0 = np.asarray(c["alpha0"], float)
        az = np.asarray(c["azimuth"], float)
        ax.plot(a0[fw], az[fw], "-", color=col, lw=1.4, label=f"{c['label']} (forward)")
        ax.plot(a0[~fw], az[~fw], "--", color=col, lw=1.2, label=f"{c['label']} (backward)")
        sn = np.asarray(c["snaps"], bool)
        if sn.any():
            ax.plot(a0[sn], az[sn], "x", color="k", ms=9, mew=2)
        ref = np.asarray(c.get("folds_frictionless", np.zeros_like(sn)), bool)
        if ref.any():
            ax.plot(a0[ref], az[ref], "o", mfc="none", mec="k", ms=9, mew=1.5)
    ax.plot([], [], "x", color="k", ms=9, mew=2, label="snap (fold)")
    if any(np.asarray(c.get("folds_frictionless", []), bool).any() for c in curves):
        ax.plot([], [], "o", mfc="none", mec="k", ms=9, mew=1.5, label="frictionless fold")
    ax.set_xlabel("relative rotation α0 = α1 − αN (deg)")
    ax.set_ylabel("T(L): tip azimuth from outer tube base (deg)")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=120, format="png")
    plt.close(fig)
