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
taken over *parts*: spans of contiguous columns (`part_spans`; spans may overlap, a column may count
in two parts), each over its calibration median; the score is the largest part's, plus the excess
beyond the trained range.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from ctrkin.metrics import wrap_deg

HISTORY = 2           # changes of the input over the last HISTORY steps are features (the "history" blocks)
RANGE_UNIT = 0.01    # a feature 1 % of its training spread beyond its trained range adds 1 to the score
INPUTS = ("joints", "pose", "pose+joints")
SPLITS = ("config-history", "blocks", "fine", "blocks+translations")
DEFAULT_SPLIT = "blocks+translations"   # chosen on validation walks (docs/planning.md: Uncertainty)
POSE = 6
_MODE = {"joints": 0, "pose": 1, "pose+joints": 2}


def input_width(inputs: str, n_tubes: int) -> int:
    """Columns of the raw scored input x of this kind (module docstring)."""
    return {"joints": 2 * n_tubes, "pose": POSE, "pose+joints": POSE + 2 * n_tubes}[inputs]


def block_widths(inputs: str, n_tubes: int) -> list[int]:
    """The widths of the feature blocks of this kind, in column order (module docstring)."""
    jc, jd = 3 * n_tubes - 2, 2 * n_tubes - 1
    return {"joints": [jc, HISTORY * jd], "pose": [POSE, HISTORY * POSE],
            "pose+joints": [POSE, jc, HISTORY * POSE, HISTORY * jd]}[inputs]


def spans_of(bounds: np.ndarray) -> np.ndarray:
    """(P, 2) the column spans [lo, hi) between boundaries (P + 1,) (parts that tile the columns)."""
    b = np.asarray(bounds, np.int64)
    return np.ascontiguousarray(np.stack([b[:-1], b[1:]], axis=1))


def part_spans(inputs: str, n_tubes: int, split: str) -> np.ndarray:
    """(P, 2) column spans [lo, hi) of the k-NN parts: "config-history", two parts (every configuration
    block, every history block); "blocks", each block its own part (the same for "joints" and "pose",
    two blocks); "fine", the blocks with the joints' configuration split into its rotations (cos, sin)
    and its translations; "blocks+translations", the blocks and, beside them, the joints'
    translations alone (their columns count in the joints' configuration part and in a part of their
    own: a joint combination never recorded is out of distribution in the translations only, where
    the rotations' neighbour distances would swamp it; the blocks keep the rotations and translations
    together, which "fine" loses). "pose" has no joints: its "fine" and "blocks+translations" are its
    blocks."""
    w = block_widths(inputs, n_tubes)
    extra = None
    if split == "config-history":
        w = [sum(w[:len(w) // 2]), sum(w[len(w) // 2:])]
    elif split == "fine" and inputs != "pose":
        at = 0 if inputs == "joints" else 1
        w = [*w[:at], 2 * (n_tubes - 1), n_tubes, *w[at + 1:]]
    elif split == "blocks+translations" and inputs != "pose":
        first = (0 if inputs == "joints" else POSE) + 2 * (n_tubes - 1)    # after the cos and sin columns
        extra = [first, first + n_tubes]
    elif split not in SPLITS:
        raise ValueError(f"split must be one of {SPLITS}, got {split!r}")
    spans = spans_of(np.cumsum([0, *w]))
    if extra is not None:                    # after the joints' configuration block, before the histories
        at = 1 if inputs == "joints" else 2
        spans = np.ascontiguousarray(np.insert(spans, at, extra, axis=0))
    return spans.astype(np.int64)


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
    the module docstring (the changes zero before a sequence's start: a robot at rest before it). The
    training and calibration rows' (center, spread, reference, tau); scores take each row's features
    from the stream's kernel (`sequence_scores`), equal to these to rounding."""
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
# The k-NN scan is exact and searched: each part's reference rows are kept in a k-d tree (`KnnIndex`:
# median splits on the widest column down to leaves of at most LEAF rows, each node's rows contiguous,
# its bounding box stored), visited nearest box first, and a box is skipped once the squared distance
# from the query to it reaches the k-th best squared distance so far. That bound is exact in floating
# point: for a row r in the box, |fl(z_f − r_f)| ≥ |fl(z_f − box_f)| column by column (rounding is
# monotone), so the row's sum of squares, taken in the same column order, is at least the box's. And a
# part whose running distance (the mean of its k best so far, which only falls) over its calibration
# median is already no larger than a part before it cannot change the score's maximum: its search
# stops there. Each row's distance sums the part's columns in order as brute force does, so the k
# nearest distances, and the score, are brute force's to the bit (tested).
LEAF = 16
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
def _box_bound(z: np.ndarray, box: np.ndarray, lo: int, w: int) -> float:
    """Squared distance from z's columns lo.. (w of them) to the box (2, ≥ w): the module comment's bound."""
    s = 0.0
    for f in range(w):
        v = z[lo + f]
        g = 0.0
        if v < box[0, f]:
            g = box[0, f] - v
        elif v > box[1, f]:
            g = v - box[1, f]
        s += g * g
    return s


@numba.njit(cache=True)
def _knn_searched(z: np.ndarray, rows: np.ndarray, tree: np.ndarray, boxes: np.ndarray, lo: int, hi: int,
                  k: int, best: np.ndarray, stack: np.ndarray, bounds: np.ndarray, tau: float,
                  enough: float) -> float:
    """`_knn_score` of z over columns lo..hi−1 from the part's rows (M·(hi − lo),) flat in tree order,
    tree (4, nodes) first row, end, left and right child (−1: a leaf), boxes (nodes, 2, ≥ w); stack,
    bounds scratch (≥ tree depth + 1,). Stops early, with a distance d ≥ the true one and
    d / tau ≤ enough, once that holds (module comment above)."""
    w = hi - lo
    for j in range(k):
        best[j] = np.inf
    stack[0] = 0
    bounds[0] = _box_bound(z, boxes[0], lo, w)
    top = 1
    while top > 0:
        top -= 1
        node = stack[top]
        if bounds[top] >= best[k - 1]:
            continue
        left = tree[2, node]
        if left < 0:
            for m in range(tree[0, node], tree[1, node]):
                lim = best[k - 1]
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
                        return _mean_root(best, k)
        else:
            right = tree[3, node]
            bl = _box_bound(z, boxes[left], lo, w)
            br = _box_bound(z, boxes[right], lo, w)
            if bl <= br:                     # the nearer child on top: visited first
                stack[top], bounds[top], stack[top + 1], bounds[top + 1] = right, br, left, bl
            else:
                stack[top], bounds[top], stack[top + 1], bounds[top + 1] = left, bl, right, br
            top += 2
    return _mean_root(best, k)


@numba.njit(cache=True)
def _score(z: np.ndarray, rows: np.ndarray, tree: np.ndarray, boxes: np.ndarray, parts: np.ndarray, k: int,
           tau: np.ndarray, stats: np.ndarray, best: np.ndarray, stack: np.ndarray,
           bounds: np.ndarray) -> float:
    """The OOD score of standardised features z (F,): the largest over parts, the spans
    [parts[p, 0], parts[p, 1]) (P, 2), of the k-NN distance over the part's calibration median tau[p],
    plus the excess beyond the trained range [stats[2], stats[3]] (F,) in units of RANGE_UNIT. rows,
    tree, boxes: a KnnIndex's (the parts' blocks one after another)."""
    worst = 0.0
    m = tree[1, 0]                           # the root's end: the reference rows
    at = 0
    for p in range(parts.shape[0]):
        lo, hi = parts[p, 0], parts[p, 1]
        size = m * (hi - lo)
        d = _knn_searched(z, rows[at:at + size], tree, boxes[p], lo, hi, k, best, stack, bounds, tau[p],
                          worst if p > 0 else -1.0)
        at += size
        worst = max(worst, d / tau[p])
    excess = 0.0
    for f in range(z.shape[0]):
        excess += max(z[f] - stats[3, f], 0.0) + max(stats[2, f] - z[f], 0.0)
    return worst + excess / RANGE_UNIT


@numba.njit(cache=True)
def stream_step(mode: int, n: int, x: np.ndarray, joints: np.ndarray, history: np.ndarray, count: np.ndarray,
                stats: np.ndarray, z: np.ndarray, rows: np.ndarray, tree: np.ndarray, boxes: np.ndarray,
                parts: np.ndarray, k: int, tau: np.ndarray, best: np.ndarray, stack: np.ndarray,
                bounds: np.ndarray) -> float:
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
    return _score(z, rows, tree, boxes, parts, k, tau, stats, best, stack, bounds)


@numba.njit(cache=True)
def sequence_scores(mode: int, n: int, x: np.ndarray, starts: np.ndarray, ends: np.ndarray, stats: np.ndarray,
                    rows: np.ndarray, tree: np.ndarray, boxes: np.ndarray, parts: np.ndarray, k: int,
                    tau: np.ndarray) -> np.ndarray:
    """(T,) OOD scores of raw inputs x (T, W) (the stream's rows) in sequences [starts[s], ends[s]) that
    cover every row: each row's features by the stream's kernel from the last HISTORY + 1 rows of its
    sequence, then the same score, so the batch is the stream to the bit."""
    out = np.empty(x.shape[0])
    z = np.empty(stats.shape[1])
    best = np.empty(k)
    stack = np.empty(tree.shape[1], np.int64)
    bounds = np.empty(tree.shape[1])
    for s in range(starts.shape[0]):
        a, b = starts[s], ends[s]
        for t in range(a, b):
            lo = max(a, t - HISTORY)
            _stream_features(mode, n, x[lo:t + 1], t + 1 - lo, stats[0], stats[1], z)
            out[t] = _score(z, rows, tree, boxes, parts, k, tau, stats, best, stack, bounds)
    return out


@numba.njit(cache=True)
def part_scores(Z: np.ndarray, ref: np.ndarray, lo: int, hi: int, k: int) -> np.ndarray:
    """(T,) k-NN distances of rows Z (T, F) over columns lo..hi−1 (brute force)."""
    out = np.empty(Z.shape[0])
    best = np.empty(k)
    for t in range(Z.shape[0]):
        out[t] = _knn_score(Z[t], ref, lo, hi, k, best)
    return out


@numba.njit(cache=True)
def batch_scores(Z: np.ndarray, rows: np.ndarray, tree: np.ndarray, boxes: np.ndarray, parts: np.ndarray,
                 k: int, tau: np.ndarray, stats: np.ndarray) -> np.ndarray:
    """(T,) OOD scores of standardised rows Z (T, F) (the same kernel as the stream's)."""
    out = np.empty(Z.shape[0])
    best = np.empty(k)
    stack = np.empty(tree.shape[1], np.int64)
    bounds = np.empty(tree.shape[1])
    for t in range(Z.shape[0]):
        out[t] = _score(Z[t], rows, tree, boxes, parts, k, tau, stats, best, stack, bounds)
    return out


def _tree(m: int, leaf: int) -> np.ndarray:
    """(4, nodes) the k-d tree's shape over m rows (the same for every part: split by count): each
    node's first row, end, left and right child (−1 at a leaf), in preorder."""
    nodes: list[list[int]] = []

    def build(a: int, b: int) -> int:
        me = len(nodes)
        nodes.append([a, b, -1, -1])
        if b - a > leaf:
            h = a + (b - a) // 2
            nodes[me][2] = build(a, h)
            nodes[me][3] = build(h, b)
        return me

    build(0, m)
    return np.ascontiguousarray(np.array(nodes, np.int64).reshape(-1, 4).T)


@dataclass(frozen=True, eq=False)
class KnnIndex:
    """The reference rows (M, F) arranged for the searched scan (module comment above): rows (M·Σw,)
    part after part (spans (P, 2), `part_spans`), each part's block (M, w) contiguous in its tree's
    order; tree (4, nodes) the trees' common shape (`_tree`); boxes (P, nodes, 2, max w) each node's
    bounding box (lo, hi) in its part's columns."""

    rows: np.ndarray
    tree: np.ndarray
    boxes: np.ndarray

    @classmethod
    def of(cls, ref: np.ndarray, parts: np.ndarray, leaf: int = LEAF) -> KnnIndex:
        ref = np.asarray(ref, np.float64)
        m = ref.shape[0]
        tree = _tree(m, leaf)
        spans = [(int(a), int(b)) for a, b in np.asarray(parts, np.int64).reshape(-1, 2)]
        flat = np.empty(m * sum(b - a for a, b in spans))
        boxes = np.zeros((len(spans), tree.shape[1], 2, max([b - a for a, b in spans], default=0)))
        at = 0
        for p, (lo, hi) in enumerate(spans):
            block = ref[:, lo:hi]
            order = np.arange(m)
            for node in range(tree.shape[1]):    # preorder: a node's rows are in place before it splits them
                a, b, left, _ = tree[:, node]
                rows = block[order[a:b]]
                if len(rows):
                    boxes[p, node, 0, :hi - lo] = rows.min(axis=0)
                    boxes[p, node, 1, :hi - lo] = rows.max(axis=0)
                if left >= 0:
                    col = int(np.argmax(np.ptp(rows, axis=0)))
                    order[a:b] = order[a:b][np.argsort(rows[:, col], kind="stable")]
            flat[at:at + m * (hi - lo)] = block[order].ravel()
            at += m * (hi - lo)
        return cls(flat, tree, boxes)


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
