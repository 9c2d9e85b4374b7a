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


SPLIT_KINDS = ("sequence", "random")


@dataclass(frozen=True, eq=False)
class Split:
    """Row indices (into the dataset frame) of each part, (n_part,) int64 sorted; kind: "sequence"
    or "random"; n_rows: the number of rows of the frame it was made for (None: not recorded);
    test_chosen: the test sequences were named by the user (`ctrkin dataset split --test`)."""

    train: np.ndarray
    val: np.ndarray
    test: np.ndarray
    kind: str
    seed: int
    fractions: tuple[float, float, float]
    n_rows: int | None = None
    test_chosen: bool = False

    def __post_init__(self) -> None:
        if self.kind not in SPLIT_KINDS:
            raise DatasetError(f"split kind must be one of {SPLIT_KINDS}, got {self.kind!r}")
        for name in SPLIT_NAMES:
            object.__setattr__(self, name, np.asarray(getattr(self, name), dtype=np.int64))

    def sizes(self) -> dict[str, int]:
        return {k: len(self.part(k)) for k in SPLIT_NAMES}

    def part(self, name: str) -> np.ndarray:
        if name not in SPLIT_NAMES:
            raise DatasetError(f"split part must be one of {SPLIT_NAMES}, got {name!r}")
        return getattr(self, name)

    def to_dict(self) -> dict[str, object]:
        return {"kind": self.kind, "seed": self.seed, "fractions": list(self.fractions),
                "n_rows": self.n_rows, **({"test_chosen": True} if self.test_chosen else {}),
                **{k: self.part(k).tolist() for k in SPLIT_NAMES}}

    @classmethod
    def from_dict(cls, d: dict) -> Split:
        try:
            tr, va, te = (np.asarray(d[k], dtype=np.int64) for k in SPLIT_NAMES)
            f = tuple(float(v) for v in d["fractions"])
            n_rows = d.get("n_rows")
            return cls(tr, va, te, kind=str(d["kind"]), seed=int(d["seed"]),
                       fractions=(f[0], f[1], f[2]), n_rows=None if n_rows is None else int(n_rows),
                       test_chosen=bool(d.get("test_chosen", False)))
        except KeyError as e:
            raise DatasetError(f"malformed split: missing key {e}") from None
        except (TypeError, ValueError, IndexError) as e:
            raise DatasetError(f"malformed split: {e}") from None

    def save(self, path: str | Path) -> None:
        atomic_write_text(path, json.dumps(self.to_dict()))

    @classmethod
    def load(cls, path: str | Path) -> Split:
        try:
            return cls.from_dict(json.loads(Path(path).read_text()))
        except (OSError, json.JSONDecodeError) as e:
            raise DatasetError(f"cannot read split file {path}: {e}") from None


def _check_fractions(fractions: tuple[float, ...]) -> tuple[float, float, float]:
    if len(fractions) != 3 or any(f < 0 for f in fractions) or abs(sum(fractions) - 1) > 1e-9:
        raise DatasetError(f"split fractions must be three non-negative numbers summing to 1, "
                           f"got {fractions}")
    return float(fractions[0]), float(fractions[1]), float(fractions[2])


def part_sizes(n_rows: int, fractions: tuple[float, float, float]) -> tuple[int, int, int]:
    """Sizes summing exactly to n_rows, each within one of fraction·n_rows (largest remainder)."""
    exact = np.asarray(fractions, dtype=float) * n_rows
    sizes = np.floor(exact).astype(int)
    for k in np.argsort(-(exact - sizes), kind="stable")[: n_rows - int(sizes.sum())]:
        sizes[k] += 1
    return int(sizes[0]), int(sizes[1]), int(sizes[2])


def split_by_sequence(sequence_id: np.ndarray, fractions: tuple[float, float, float] = (0.7, 0.15, 0.15),
                      seed: int = 0) -> Split:
    """Assign whole sequences to train/val/test, aiming at the sample fractions given.

    sequence_id: (T,) per-row sequence ids. Sequences are shuffled (seeded) and filled greedily;
    with at least three sequences each part gets one.
    """
    fractions = _check_fractions(fractions)
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
    return Split(tr, va, te, kind="sequence", seed=seed, fractions=fractions, n_rows=len(sid))


def random_split(n_rows: int, fractions: tuple[float, float, float] = (0.7, 0.15, 0.15),
                 seed: int = 0) -> Split:
    """The paper's split: rows shuffled individually (neighbouring samples leak across parts)."""
    fractions = _check_fractions(fractions)
    perm = np.random.default_rng(seed).permutation(n_rows)
    n_train, n_val, _ = part_sizes(n_rows, fractions)
    a, b = n_train, n_train + n_val
    return Split(np.sort(perm[:a]), np.sort(perm[a:b]), np.sort(perm[b:]), kind="random",
                 seed=seed, fractions=fractions, n_rows=n_rows)


FAR_FROM_RATIO = 0.10   # a part this far (absolute fraction of the samples) from its request is reported


def split_with_test(sequence_id: np.ndarray, labels: list[str], test: list[str],
                    fractions: tuple[float, float, float] = (0.7, 0.15, 0.15), seed: int = 0) -> Split:
    """Test part = the sequences named in `test` (labels, e.g. imported file stems, or indices); the
    other sequences go to train and validation in the ratio fractions[0] : fractions[1]."""
    fractions = _check_fractions(fractions)
    sid = np.asarray(sequence_id)
    uniq = np.unique(sid)
    chosen = []
    for t in test:
        if t in labels:
            chosen.append(labels.index(t))
        elif t.lstrip("-").isdigit() and int(t) in uniq:
            chosen.append(int(t))
        else:
            raise DatasetError(f"--test {t!r}: no such sequence; names {labels or '(none)'}, indices "
                               f"{uniq.tolist()}")
    test_rows = np.isin(sid, chosen)
    rest = [k for k in uniq if k not in chosen]
    if len(rest) < 2:
        raise DatasetError(f"--test leaves {len(rest)} sequence(s) for train and validation; need 2")
    tv = fractions[0] + fractions[1]
    inner = split_by_sequence(sid[~test_rows], (fractions[0] / tv, fractions[1] / tv, 0.0), seed=seed)
    idx = np.nonzero(~test_rows)[0]
    train, val = idx[inner.train], np.sort(np.r_[idx[inner.val], idx[inner.test]])
    if len(val) == 0 and fractions[1] > 0:
        # few sequences: validation gets the one whose size is closest to its target
        ids, counts = np.unique(sid[train], return_counts=True)
        pick = ids[int(np.argmin(np.abs(counts - fractions[1] / tv * len(train))))]
        val, train = train[sid[train] == pick], train[sid[train] != pick]
    return Split(np.sort(train), val, np.nonzero(test_rows)[0], kind="sequence", seed=seed,
                 fractions=fractions, n_rows=len(sid), test_chosen=True)


def split_with_test_val_rows(sequence_id: np.ndarray, labels: list[str], test: list[str],
                             val_fraction: float = 0.15, seed: int = 0) -> Split:
    """Test part = the sequences named in `test`; validation = `val_fraction` of the other sequences'
    rows, drawn at random (seeded); training = the rest. With few, unequal sequences a whole
    validation sequence would be unlike the test one and stop training early; these rows only choose
    the epoch (they are neighbours of training rows, so their error is not a held-out figure). The
    split of benchmarks/bench_realdata.py."""
    if not 0 < val_fraction < 1:
        raise DatasetError(f"the validation fraction must be in (0, 1), got {val_fraction}")
    by_seq = split_with_test(sequence_id, labels, test, (1 - val_fraction, val_fraction, 0.0), seed)
    rest = np.sort(np.r_[by_seq.train, by_seq.val])
    perm = np.random.default_rng(seed).permutation(rest)
    n_val = round(val_fraction * len(rest))
    return Split(np.sort(perm[n_val:]), np.sort(perm[:n_val]), by_seq.test, kind="random", seed=seed,
                 fractions=(1 - val_fraction, val_fraction, 0.0), n_rows=len(sequence_id),
                 test_chosen=True)


def joint_coverage(joints_train: np.ndarray, joints_other: np.ndarray, names: list[str],
                   tol: float = 1e-6) -> list[str]:
    """Messages for the joints that another part (held out, validation) moves but the training rows
    never moved: a model (learned or calibrated) knows nothing of their effect there.
    joints_*: (T, 2N) deg, mm."""
    out: list[str] = []
    if len(joints_train) == 0 or len(joints_other) == 0:
        return out
    for k, name in enumerate(names):
        t, o = joints_train[:, k], joints_other[:, k]
        if np.ptp(t) <= tol and np.abs(o - t[0]).max() > tol:
            unit = "deg" if name.startswith("alpha") else "mm"
            out.append(f"{name} never moved in training (always {t[0]:.4g} {unit}) but the held-out rows "
                       f"take it over [{o.min():.4g}, {o.max():.4g}] {unit}: its effect is unknown to the "
                       "model there")
    return out


def split_warnings(split: Split, fractions: tuple[float, float, float]) -> list[str]:
    """Messages for parts more than FAR_FROM_RATIO away from the requested fractions (the advice to
    name the test sequences only where they were not)."""
    sizes = split.sizes()
    total = max(sum(sizes.values()), 1)
    advice = ("the test part is the sequences given with --test" if split.test_chosen
              else "choose the test sequences with --test")
    out = []
    for name, want in zip(("train", "val", "test"), fractions, strict=True):
        got = sizes[name] / total
        if abs(got - want) > FAR_FROM_RATIO:
            out.append(f"{name} has {sizes[name]} samples ({got:.0%}) where {want:.0%} was asked: whole "
                       f"sequences cannot match the ratio; {advice}, or record more, shorter sequences")
    return out
