"""The figures of `ctrkin evaluate` (real.py): every figure titled with the predictor and its mean
errors per part, points coloured by sequence (file), held-out rows marked, each measured tip joined
to its prediction.

    tips.png               measured (o) and predicted (x) tips, x-y and x-z, a grey line per pair
    error_vs_joints.png    tip error against each joint that moves (a joint that never moves has
                           no panel)
    error_by_sequence.png  mean tip error per sequence, coloured by the part it belongs to, with the
                           mean of each part as a line: the figures a reader compares
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ctrkin.data.dataset import Dataset

HELD_OUT_MARK = {"marker": "o", "facecolors": "none", "linewidths": 1.2}
MAX_LEGEND = 12


def _summary(res: dict[str, Any]) -> str:
    """'training 0.41 mm, held out (test) 0.52 mm' (mean tip distance per part)."""
    return ", ".join(f"{p} {s['position_mean_mm']:.2f} mm" for p, s in res["per_part"].items()) or \
        f"all {res['overall']['position_mean_mm']:.2f} mm"


def plots(ds: Dataset, pred: np.ndarray, pos_e: np.ndarray, held: np.ndarray, labels: list[str], name: str,
          res: dict[str, Any], out: Path) -> list[str]:
    """Write the three figures into `out`; returns their file names. held: (T,) bool, the rows of a
    held-out part; labels: the name of each sequence id (ctrkin.evaluation.real.sequence_names)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    meas = ds.poses()
    sid = ds.frame["sequence_id"].to_numpy()
    ids = np.unique(sid)
    colours = plt.get_cmap("tab10" if len(ids) <= 10 else "tab20")(np.arange(len(ids)) % 20)
    title = f"{name}: {_summary(res)}"

    fig, axes = plt.subplots(1, 2, figsize=(11, 5))
    for ax, (a, b) in zip(axes, ((0, 1), (0, 2)), strict=True):
        pairs = np.stack([meas[:, [a, b]], pred[:, [a, b]]], axis=1)       # (T, 2, 2)
        ax.add_collection(matplotlib.collections.LineCollection(list(pairs), colors="0.75", linewidths=0.6))
        for k, (seq, c) in enumerate(zip(ids, colours, strict=True)):
            rows = sid == seq
            lab = labels[k] if k < MAX_LEGEND else None
            ax.scatter(meas[rows & ~held, a], meas[rows & ~held, b], s=10, color=c, label=lab)
            ax.scatter(meas[rows & held, a], meas[rows & held, b], s=22, edgecolors=c, **HELD_OUT_MARK)
            ax.scatter(pred[rows, a], pred[rows, b], s=12, marker="x", color=c, alpha=0.8)
        ax.set_xlabel("xyz"[a] + " (mm)")
        ax.set_ylabel("xyz"[b] + " (mm)")
        ax.set_aspect("equal", "datalim")
    axes[0].legend(fontsize=7, title="sequence (o measured, x predicted; ring: held out)",
                   title_fontsize=7)
    fig.suptitle(f"{title}\npredicted vs measured tips, each pair joined", fontsize=10)
    fig.tight_layout()
    fig.savefig(out / "tips.png", dpi=110)
    plt.close(fig)

    names = ds.robot.joint_names()
    joints = ds.joints()
    moving = [j for j in range(len(names)) if np.ptp(joints[:, j]) > 1e-9]
    fig, axes = plt.subplots(1, max(len(moving), 1), figsize=(3.2 * max(len(moving), 1), 3.4), sharey=True,
                             squeeze=False)
    for ax, j in zip(axes[0], moving, strict=False):
        for seq, c in zip(ids, colours, strict=True):
            rows = sid == seq
            ax.scatter(joints[rows & ~held, j], pos_e[rows & ~held], s=6, color=c)
            ax.scatter(joints[rows & held, j], pos_e[rows & held], s=14, edgecolors=c, **HELD_OUT_MARK)
        ax.set_xlabel(names[j] + (" (deg)" if names[j].startswith("alpha") else " (mm)"))
    axes[0][0].set_ylabel("tip error (mm)")
    still = [n for j, n in enumerate(names) if j not in moving]
    fig.suptitle(title + (f"\n(not moving, no panel: {', '.join(still)})" if still else ""), fontsize=9)
    fig.tight_layout()
    fig.savefig(out / "error_vs_joints.png", dpi=110)
    plt.close(fig)

    per = res["per_sequence"]
    part_names = list(res["per_part"]) or ["all"]
    part_colour = {p: plt.get_cmap("Set2")(k) for k, p in enumerate(part_names)}
    fig, ax = plt.subplots(figsize=(max(5.0, 0.6 * len(per) + 2), 4))
    x = np.arange(len(per))
    for k, s in enumerate(per.values()):
        p = s["parts"][0] if len(s["parts"]) == 1 else (s["parts"] and "mixed") or "all"
        ax.bar(k, s["position_mean_mm"], color=part_colour.get(p, "0.6"), label=p)
        ax.text(k, s["position_mean_mm"], f"{s['position_mean_mm']:.2f}", ha="center", va="bottom",
                fontsize=7)
    for p, s in res["per_part"].items():
        ax.axhline(s["position_mean_mm"], color=part_colour[p], ls="--", lw=1)
    handles, labs = ax.get_legend_handles_labels()
    unique = dict(zip(labs, handles, strict=True))
    ax.legend(unique.values(), unique.keys(), fontsize=7, title="part (dashed: its mean)", title_fontsize=7)
    ax.set_xticks(x, list(per), rotation=30, ha="right", fontsize=7)
    ax.set_ylabel("mean tip error (mm)")
    ax.set_title(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(out / "error_by_sequence.png", dpi=110)
    plt.close(fig)
    return ["tips.png", "error_vs_joints.png", "error_by_sequence.png"]
