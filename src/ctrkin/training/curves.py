"""Loss curves like paper Fig. 9: training and validation MAE loss per epoch."""

from __future__ import annotations

import csv
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from ctrkin.util.files import atomic_path


def read_history(folder: str | Path) -> list[dict[str, float]]:
    """A trained model folder's history.csv: one dict per epoch ('epoch', 'train_loss', 'val_loss',
    ...); [] where the folder has none (a model assembled from others, e.g. the refined IK)."""
    path = Path(folder) / "history.csv"
    if not path.is_file():
        return []
    with open(path, newline="") as f:
        return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(f)]


def plot_curves(history: list[dict[str, float]], path: str | Path, title: str) -> None:
    """history: one dict per epoch with 'epoch', 'train_loss', 'val_loss' (normalised MAE)."""
    ep = [h["epoch"] for h in history]
    fig, ax = plt.subplots(figsize=(6, 4), dpi=120)
    ax.plot(ep, [h["train_loss"] for h in history], label="training loss")
    ax.plot(ep, [h["val_loss"] for h in history], label="validation loss")
    best = min(history, key=lambda h: h["val_loss"])
    ax.axvline(best["epoch"], color="grey", lw=0.8, ls="--", label=f"best (epoch {best['epoch']})")
    ax.set_yscale("log")
    ax.set_xlabel("epoch")
    ax.set_ylabel("MAE loss (normalised)")
    ax.set_title(title)
    ax.legend()
    ax.grid(alpha=0.3, which="both")
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png")
    plt.close(fig)
