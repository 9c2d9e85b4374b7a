"""Train/validation/test splits, saved with the dataset.

By sequence (default): whole sequences go to one split, so no sample leaks into another split through
the input buffer. Random (the paper's 70:15:15): samples are shuffled individually, for comparison.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ctrkin.errors import DatasetError
from ctrkin.util.files import atomic_write_text

SPLIT_NAMES = ("train", "val", "test")


@dataclass(frozen=True, eq=False)
class Split:
    """Row indices (into the dataset frame) of each part; kind: "sequence" or "random"."""

    train: np.ndarray
    val: np.ndarray
    test: np.ndarray
    kind: str
    seed: int
    fractions: tuple[float, float, float]

    def part(self, name: str) -> np.ndarray:
        if name not in SPLIT_NAMES:
            raise DatasetError(f"split part must be one of {SPLIT_NAMES}, got {name!r}")
        return getattr(self, name)

    def to_dict(self) -> dict[str, object]:
        return {"kind": self.kind, "seed": self.seed, "fractions": list(self.fractions),
                **{k: self.part(k).tolist() for k in SPLIT_NAMES}}

    @classmethod
    def from_dict(cls, d: dict) -> Split:
        try:
            tr, va, te = (np.asarray(d[k], dtype=np.int64) for k in SPLIT_NAMES)
            f = tuple(float(v) for v in d["fractions"])
            return cls(tr, va, te, kind=str(d["kind"]), seed=int(d["seed"]),
                       fractions=(f[0], f[1], f[2]))
        except (KeyError, TypeError, ValueError) as e:
            raise DatasetError(f"malformed split: {e}") from None

    def save(self, path: str | Path) -> None:
        atomic_write_text(path, json.dumps(self.to_dict()))

    @classmethod
    def load(cls, path: str | Path) -> Split:
        try:
            return cls.from_dict(json.loads(Path(path).read_text()))
        except (OSError, json.JSONDecodeError) as e:
            raise DatasetError(f"cannot read split file {path}: {e}") from None


def _check_fractions(fractions: tuple[float, float, float]) -> None:
    if len(fractions) != 3 or any(f < 0 for f in fractions) or abs(sum(fractions) - 1) > 1e-9:
        raise DatasetError(f"split fractions must be three non-negative numbers summing to 1, "
                           f"got {fractions}")


def split_by_sequence(sequence_id: np.ndarray, fractions: tuple[float, float, float] = (0.7, 0.15, 0.15),
                      seed: int = 0) -> Split:
    """Assign whole sequences to train/val/test, aiming at the sample fractions given.

    sequence_id: (T,) per-row sequence ids. Sequences are shuffled (seeded) and filled greedily;
    with at least three sequences each part gets one.
    """
    _check_fractions(fractions)
    sid = np.asarray(sequence_id)
    uniq, counts = np.unique(sid, return_counts=True)
    order = np.random.default_rng(seed).permutation(len(uniq))
    total = counts.sum()
    targets = np.array(fractions) * total
    assign = np.zeros(len(uniq), dtype=int)
    filled = np.zeros(3)
    for rank, k in enumerate(order):
        if len(uniq) >= 3 and rank < 3 and fractions[2 - rank] > 0:
            part = 2 - rank  # seed test and val with one sequence each first
        else:
            part = int(np.argmax(targets - filled))
        assign[k] = part
        filled[part] += counts[k]
    tr, va, te = (np.nonzero(np.isin(sid, uniq[assign == p]))[0] for p in range(3))
    return Split(tr, va, te, kind="sequence", seed=seed, fractions=fractions)


def random_split(n_rows: int, fractions: tuple[float, float, float] = (0.7, 0.15, 0.15),
                 seed: int = 0) -> Split:
    """The paper's split: rows shuffled individually (neighbouring samples leak across parts)."""
    _check_fractions(fractions)
    perm = np.random.default_rng(seed).permutation(n_rows)
    a = round(fractions[0] * n_rows)
    b = a + round(fractions[1] * n_rows)
    return Split(np.sort(perm[:a]), np.sort(perm[a:b]), np.sort(perm[b:]), kind="random",
                 seed=seed, fractions=fractions)
