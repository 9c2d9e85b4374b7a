"""The out-of-distribution score's features and kernels (ctrkin.models.uncertainty; docs/planning.md:
Uncertainty).

A model's scored input is one of three kinds (`INPUTS`):

- "joints" (FK): x (T, 2N) joints (deg, mm);
- "pose" (an IK calibrated before the robot's joints were scored, uncertainty format 1): x (T, 6)
  target poses;
- "pose+joints" (an IK): x (T, 6 + 2N), the target pose and the robot's joints when it was asked
  (what a loop's encoders read, the joints a follow IK steps from).

The features come in blocks, in this order: the pose (6,) as it is; the joints' configuration
(cos, sin of each relative rotation αi − αN, i < N: a common turn of every tube is the same robot
turned; then each βi); the pose's last HISTORY changes; the joints' last HISTORY changes (relative
rotations wrapped, deg; translations, mm). Each kind has the blocks of its input. The k-NN score is
taken over *parts*: contiguous runs of these columns (`part_bounds`), each over its calibration
median; the score is the largest part's, plus the excess beyond the trained range.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numba
import numpy as np

HISTORY = 2           # changes of the input over the last HISTORY steps are features (the "history" blocks)
RANGE_UNIT = 0.01    # a feature 1 % of its training spread beyond its trained range adds 1 to the score
INPUTS = ("joints", "pose", "pose+joints")
SPLITS = ("config-history", "blocks", "fine")
POSE = 6
_MODE = {"joints": 0, "pose": 1, "pose+joints": 2}


def wrap_deg(x: np.ndarray) -> np.ndarray:
    """Angles (deg) wrapped into [−180, 180)."""
    return (np.asarray(x, float) + 180.0) % 360.0 - 180.0


def input_width(inputs: str, n_tubes: int) -> int:
    """Columns of the raw scored input x of this kind (module docstring)."""
    return {"joints": 2 * n_tubes, "pose": POSE, "pose+joints": POSE + 2 * n_tubes}[inputs]


def block_widths(inputs: str, n_tubes: int) -> list[int]:
    """The widths of the feature blocks of this kind, in column order (module docstring)."""
    jc, jd = 3 * n_tubes - 2, 2 * n_tubes - 1
    return {"joints": [jc, HISTORY * jd], "pose": [POSE, HISTORY * POSE],
            "pose+joints": [POSE, jc, HISTORY * POSE, HISTORY * jd]}[inputs]


def part_bounds(inputs: str, n_tubes: int, split: str) -> np.ndarray:
    """(P + 1,) column boundaries of the k-NN parts: "config-history", two parts (every configuration
    block, every history block); "blocks", each block its own part (the same for "joints" and "pose",
    two blocks); "fine", the blocks with the joints' configuration split into its rotations (cos, sin)
    and its translations."""
    w = block_widths(inputs, n_tubes)
    if split == "config-history":
        w = [sum(w[:len(w) // 2]), sum(w[len(w) // 2:])]
    elif split == "fine" and inputs != "pose":
        at = 0 if inputs == "joints" else 1
        w = [*w[:at], 2 * (n_tubes - 1), n_tubes, *w[at + 1:]]
    elif split not in ("blocks", "fine"):
        raise ValueError(f"split must be one of {SPLITS}, got {split!r}")
    return np.cumsum([0, *w]).astype(np.int64)


def _joint_config(n: int, q: np.ndarray) -> np.ndarray:
    rel = np.deg2rad(q[:, :n - 1] - q[:, n - 1:n])
    return np.hstack([np.cos(rel), np.sin(rel), q[:, n:]])


def _joint_changes(n: int, q: np.ndarray) -> np.ndarray:
    rel = q[:, :n - 1] - q[:, n - 1:n]
    return np.hstack([wrap_deg(np.diff(rel, axis=0)), np.diff(q[:, n:], axis=0)])


def _history(length: int, dim: int, bounds: list[tuple[int, int]], per_run: list[np.ndarray]) -> np.ndarray:
    """(T, HISTORY·dim): the last HISTORY changes of each row (zero before its run's start), from each
    run's changes (b − a − 1, dim)."""
    hist = np.zeros((length, HISTORY * dim))
    for (a, b), d in zip(bounds, per_run, strict=True):
        for h in range(HISTORY):
            if b - a > 1 + h:
                hist[a + 1 + h:b, h * dim:(h + 1) * dim] = d[:len(d) - h]
    return hist


def sequence_features(inputs: str, n_tubes: int, x: np.ndarray, bounds: list[tuple[int, int]]) -> np.ndarray:
    """OOD features (T, F) of raw inputs x (T, input_width) split into sequences [a, b): the blocks of
    the module docstring (the changes zero before a sequence's start: a robot at rest before it)."""
    x = np.atleast_2d(np.asarray(x, float))
    n = n_tubes
    blocks_cfg, blocks_hist = [], []
    if inputs in ("pose", "pose+joints"):
        p = x[:, :POSE]
        blocks_cfg.append(p)
        blocks_hist.append(_history(len(x), POSE, bounds, [np.diff(p[a:b], axis=0) for a, b in bounds]))
    if inputs in ("joints", "pose+joints"):
        q = x[:, POSE:] if inputs == "pose+joints" else x
        blocks_cfg.append(_joint_config(n, q))
        changes = [_joint_changes(n, q[a:b]) for a, b in bounds]
        blocks_hist.append(_history(len(x), 2 * n - 1, bounds, changes))
    return np.hstack(blocks_cfg + blocks_hist)


# --- the streaming features (one row: sequence_features' last row, for the stream) ---------------------
@numba.njit(cache=True)
def _pose_block(rows: np.ndarray, count: int, out: np.ndarray, f_cfg: int, f_hist: int) -> None:
    last = rows[count - 1]
    for i in range(POSE):
        out[f_cfg + i] = last[i]
    f = f_hist
    for h in range(HISTORY):
        a, b = count - 2 - h, count - 1 - h          # the change from row a to row b
        for j in range(POSE):
            out[f] = rows[b, j] - rows[a, j] if a >= 0 else 0.0
            f += 1


@numba.njit(cache=True)
def _joint_block(n: int, rows: np.ndarray, count: int, c0: int, out: np.ndarray, f_cfg: int,
                 f_hist: int) -> None:
    """The joints at raw columns c0.. of the last of `count` rows: configuration at f_cfg, their
    changes at f_hist."""
    last = rows[count - 1]
    f = f_cfg
    for i in range(n - 1):
        out[f] = math.cos(math.radians(last[c0 + i] - last[c0 + n - 1]))
        out[f + n - 1] = math.sin(math.radians(last[c0 + i] - last[c0 + n - 1]))
        f += 1
    f += n - 1
    for i in range(n):
        out[f] = last[c0 + n + i]
        f += 1
    f = f_hist
    for h in range(HISTORY):
        a, b = count - 2 - h, count - 1 - h
        for j in range(2 * n - 1):
            v = 0.0
            if a >= 0:
                if j < n - 1:
                    d = (rows[b, c0 + j] - rows[b, c0 + n - 1]) - (rows[a, c0 + j] - rows[a, c0 + n - 1])
                    v = (d + 180.0) % 360.0 - 180.0
                else:
                    v = rows[b, c0 + j + 1] - rows[a, c0 + j + 1]
            out[f] = v
            f += 1


@numba.njit(cache=True)
def _stream_features(mode: int, n: int, rows: np.ndarray, count: int, center: np.ndarray, spread: np.ndarray,
                     out: np.ndarray) -> None:
    """The standardised OOD features of the last of `count` (≤ HISTORY + 1) raw inputs rows (·, W),
    oldest first, into out (F,); mode: 0 joints, 1 pose, 2 pose+joints."""
    jc = 3 * n - 2
    if mode == 0:
        _joint_block(n, rows, count, 0, out, 0, jc)
    elif mode == 1:
        _pose_block(rows, count, out, 0, POSE)
    else:
        _pose_block(rows, count, out, 0, POSE + jc)
        _joint_block(n, rows, count, POSE, out, POSE, POSE + jc + HISTORY * POSE)
    for j in range(out.shape[0]):
        out[j] = (out[j] - center[j]) / spread[j]


# --- the score ------------------------------------------------------------------------------------------
# The k-NN scan is exact and searched: each part's reference rows are kept sorted by their projection on
# the part's first principal axis v (the key; `KnnIndex`), contiguous part by part, and the scan walks
# outward from the query's key, nearest key first. |v·(z − r)| ≤ ‖z − r‖ (‖v‖ = 1), so once the key's
# gap, less δ (a bound on its rounding: 1e-12 × (Σ|z_i| + max_r Σ|r_i|), some 200 times the worst
# error of the two dot products), squared, exceeds the k-th best squared distance (by a relative 1e-12,
# beyond the rounding of a row's sum of squares), every row further along is further than the k-th:
# the scan stops. And a part whose running distance (the mean of its k best so far, which only falls)
# over its calibration median is already no larger than a part before it cannot change the score's
# maximum: its scan stops there too. Each row's distance sums the part's columns in order as brute
# force does, so the k nearest distances, and the score, are brute force's to the bit (tested).
@numba.njit(cache=True)
def _knn_score(z: np.ndarray, ref: np.ndarray, lo: int, hi: int, k: int, best: np.ndarray) -> float:
    """Mean Euclidean distance of z (F,) to its k nearest rows of ref (M, F), over columns lo..hi−1, by
    brute force (the searched scan's reference; calibration); best (k,) scratch."""
    for j in range(k):
        best[j] = np.inf
    for m in range(ref.shape[0]):
        s = 0.0
        lim = best[k - 1]
        for f in range(lo, hi):
            e = z[f] - ref[m, f]
            s += e * e
            if s >= lim:          # already further than the k-th nearest: the rest cannot help
                break
        if s < lim:
            j = k - 1
            while j > 0 and best[j - 1] > s:
                best[j] = best[j - 1]
                j -= 1
            best[j] = s
    tot = 0.0
    for j in range(k):
        tot += math.sqrt(best[j])
    return tot / k


@numba.njit(cache=True)
def _mean_root(best: np.ndarray, k: int) -> float:
    tot = 0.0
    for j in range(k):
        tot += math.sqrt(best[j])
    return tot / k


@numba.njit(cache=True)
def _knn_searched(z: np.ndarray, rows: np.ndarray, keys: np.ndarray, axis: np.ndarray, reach: float, lo: int,
                  hi: int, k: int, best: np.ndarray, tau: float, enough: float) -> float:
    """`_knn_score` of z over columns lo..hi−1 from the part's rows (M·(hi − lo),) flat, sorted by their
    keys (M,) (projections on the unit axis (hi − lo,); reach: the rows' largest Σ|r_i|): module comment
    above. Stops early, with a distance d ≥ the true one and d / tau ≤ enough, once that holds."""
    w = hi - lo
    n = keys.shape[0]
    for j in range(k):
        best[j] = np.inf
    zk = 0.0
    size = 0.0
    for f in range(w):
        zk += axis[f] * z[lo + f]
        size += abs(z[lo + f])
    slack = 1e-12 * (size + reach)
    a, b = 0, n
    while a < b:                              # the first row whose key is not below the query's
        mid = (a + b) // 2
        if keys[mid] < zk:
            a = mid + 1
        else:
            b = mid
    down, up = a - 1, a
    while down >= 0 or up < n:
        gd = zk - keys[down] if down >= 0 else np.inf
        gu = keys[up] - zk if up < n else np.inf
        if gd <= gu:
            g, m = gd, down
            down -= 1
        else:
            g, m = gu, up
            up += 1
        lim = best[k - 1]
        g -= slack
        if g > 0.0 and g * g > lim * (1.0 + 1e-12):      # this row and every one after: further than the k-th
            break
        s = 0.0
        base = m * w
        for f in range(w):
            e = z[lo + f] - rows[base + f]
            s += e * e
            if s >= lim:
                break
        if s < lim:
            j = k - 1
            while j > 0 and best[j - 1] > s:
                best[j] = best[j - 1]
                j -= 1
            best[j] = s
            if best[k - 1] < np.inf and _mean_root(best, k) / tau <= enough:
                break
    return _mean_root(best, k)


@numba.njit(cache=True)
def _score(z: np.ndarray, rows: np.ndarray, keys: np.ndarray, axes: np.ndarray, reach: np.ndarray,
           parts: np.ndarray, k: int, tau: np.ndarray, stats: np.ndarray, best: np.ndarray) -> float:
    """The OOD score of standardised features z (F,): the largest over parts [parts[p], parts[p+1]) of
    the k-NN distance over the part's calibration median tau[p], plus the excess beyond the trained
    range [stats[2], stats[3]] (F,) in units of RANGE_UNIT. rows, keys, axes, reach: a KnnIndex's."""
    worst = 0.0
    n = keys.shape[1]
    for p in range(parts.shape[0] - 1):
        lo, hi = parts[p], parts[p + 1]
        d = _knn_searched(z, rows[n * lo:n * hi], keys[p], axes[lo:hi], reach[p], lo, hi, k, best, tau[p],
                          worst if p > 0 else -1.0)
        worst = max(worst, d / tau[p])
    excess = 0.0
    for f in range(z.shape[0]):
        excess += max(z[f] - stats[3, f], 0.0) + max(stats[2, f] - z[f], 0.0)
    return worst + excess / RANGE_UNIT


@numba.njit(cache=True)
def stream_step(mode: int, n: int, x: np.ndarray, joints: np.ndarray, history: np.ndarray, count: np.ndarray,
                stats: np.ndarray, z: np.ndarray, rows: np.ndarray, keys: np.ndarray, axes: np.ndarray,
                reach: np.ndarray, parts: np.ndarray, k: int, tau: np.ndarray, best: np.ndarray) -> float:
    """One streamed step's OOD score, in one call: x (W,) (mode 2: the pose (6,) and joints (2N,)) pushed
    as the newest of the last HISTORY + 1 raw inputs history (HISTORY + 1, W), count[0] of them held;
    the features into z, then the score. stats (4, F): center, spread, trained lo, hi."""
    c = count[0]
    if c == HISTORY + 1:
        for i in range(HISTORY):
            for j in range(history.shape[1]):
                history[i, j] = history[i + 1, j]
    else:
        c += 1
        count[0] = c
    row = history[c - 1]
    for j in range(x.shape[0]):
        row[j] = x[j]
    if mode == 2:
        for j in range(joints.shape[0]):
            row[POSE + j] = joints[j]
    _stream_features(mode, n, history, c, stats[0], stats[1], z)
    return _score(z, rows, keys, axes, reach, parts, k, tau, stats, best)


@numba.njit(cache=True)
def part_scores(Z: np.ndarray, ref: np.ndarray, lo: int, hi: int, k: int) -> np.ndarray:
    """(T,) k-NN distances of rows Z (T, F) over columns lo..hi−1 (brute force)."""
    out = np.empty(Z.shape[0])
    best = np.empty(k)
    for t in range(Z.shape[0]):
        out[t] = _knn_score(Z[t], ref, lo, hi, k, best)
    return out


@numba.njit(cache=True)
def batch_scores(Z: np.ndarray, rows: np.ndarray, keys: np.ndarray, axes: np.ndarray, reach: np.ndarray,
                 parts: np.ndarray, k: int, tau: np.ndarray, stats: np.ndarray) -> np.ndarray:
    """(T,) OOD scores of standardised rows Z (T, F) (the same kernel as the stream's)."""
    out = np.empty(Z.shape[0])
    best = np.empty(k)
    for t in range(Z.shape[0]):
        out[t] = _score(Z[t], rows, keys, axes, reach, parts, k, tau, stats, best)
    return out


@dataclass(frozen=True, eq=False)
class KnnIndex:
    """The reference rows (M, F) arranged for the searched scan (module comment above): rows (M·F,) part
    after part, each part's block (M, w) contiguous and sorted by its key; keys (P, M) the sorted keys;
    axes (F,) each part's unit principal axis in its columns; reach (P,) each part's largest Σ|r_i|."""

    rows: np.ndarray
    keys: np.ndarray
    axes: np.ndarray
    reach: np.ndarray

    @classmethod
    def of(cls, ref: np.ndarray, parts: np.ndarray) -> KnnIndex:
        ref = np.asarray(ref, np.float64)
        m, width = ref.shape
        flat, axes = np.empty(m * width), np.zeros(width)
        keys, reach = np.empty((len(parts) - 1, m)), np.zeros(len(parts) - 1)
        for p, (lo, hi) in enumerate(itertools.pairwise(parts.tolist())):
            block = ref[:, lo:hi]
            axis = np.zeros(hi - lo)
            axis[0] = 1.0
            if m > 1:
                centred = block - block.mean(axis=0)
                axis = np.linalg.eigh(centred.T @ centred)[1][:, -1]
            axis = axis / np.linalg.norm(axis)
            key = block @ axis
            order = np.argsort(key, kind="stable")
            flat[m * lo:m * hi] = block[order].ravel()
            keys[p], axes[lo:hi] = key[order], axis
            reach[p] = float(np.abs(block).sum(axis=1).max()) if m else 0.0
        return cls(flat, keys, axes, reach)


def mode(inputs: str) -> int:
    """The streaming kernel's code of an input kind."""
    return _MODE[inputs]


def joints_before(joints: np.ndarray, bounds: list[tuple[int, int]],
                  starts: list[np.ndarray | None] | None = None) -> np.ndarray:
    """(T, 2N) the robot's joints when each row's target was asked, from the joints it stood at after
    each row (T, 2N) (a recording's joints, or the answers a loop executed): row t of a sequence
    [a, b) gets row t − 1's, its first row the sequence's start joints (starts[s], else its own)."""
    q = np.asarray(joints, float)
    out = q.copy()
    for s, (a, b) in enumerate(bounds):
        out[a + 1:b] = q[a:b - 1]
        start = None if starts is None else starts[s]
        if start is not None and b > a:
            out[a] = start
    return out
