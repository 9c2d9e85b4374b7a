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

import math

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
@numba.njit(cache=True)
def _knn_score(z: np.ndarray, ref: np.ndarray, lo: int, hi: int, k: int, best: np.ndarray) -> float:
    """Mean Euclidean distance of z (F,) to its k nearest rows of ref (M, F), over columns lo..hi−1;
    best (k,) scratch."""
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
def _score(z: np.ndarray, ref: np.ndarray, parts: np.ndarray, k: int, tau: np.ndarray, lo: np.ndarray,
           hi: np.ndarray, best: np.ndarray) -> float:
    """The OOD score of standardised features z (F,): the largest over parts [parts[p], parts[p+1]) of
    the k-NN distance over the part's calibration median tau[p], plus the excess beyond the trained
    range [lo, hi] (F,) in units of RANGE_UNIT."""
    worst = 0.0
    for p in range(parts.shape[0] - 1):
        worst = max(worst, _knn_score(z, ref, parts[p], parts[p + 1], k, best) / tau[p])
    excess = 0.0
    for f in range(z.shape[0]):
        excess += max(z[f] - hi[f], 0.0) + max(lo[f] - z[f], 0.0)
    return worst + excess / RANGE_UNIT


@numba.njit(cache=True)
def stream_score(mode: int, n: int, rows: np.ndarray, count: int, center: np.ndarray, spread: np.ndarray,
                 z: np.ndarray, ref: np.ndarray, parts: np.ndarray, k: int, tau: np.ndarray, lo: np.ndarray,
                 hi: np.ndarray, best: np.ndarray) -> float:
    """One streamed step's OOD score (one call: the features into z, then the score)."""
    _stream_features(mode, n, rows, count, center, spread, z)
    return _score(z, ref, parts, k, tau, lo, hi, best)


@numba.njit(cache=True)
def part_scores(Z: np.ndarray, ref: np.ndarray, lo: int, hi: int, k: int) -> np.ndarray:
    """(T,) k-NN distances of rows Z (T, F) over columns lo..hi−1."""
    out = np.empty(Z.shape[0])
    best = np.empty(k)
    for t in range(Z.shape[0]):
        out[t] = _knn_score(Z[t], ref, lo, hi, k, best)
    return out


@numba.njit(cache=True)
def batch_scores(Z: np.ndarray, ref: np.ndarray, parts: np.ndarray, k: int, tau: np.ndarray, lo: np.ndarray,
                 hi: np.ndarray) -> np.ndarray:
    """(T,) OOD scores of standardised rows Z (T, F) (the same kernel as the stream's)."""
    out = np.empty(Z.shape[0])
    best = np.empty(k)
    for t in range(Z.shape[0]):
        out[t] = _score(Z[t], ref, parts, k, tau, lo, hi, best)
    return out


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
