"""The OOD score's searched k-NN scan (ctrkin.models.ood) against brute force, to the bit."""

from __future__ import annotations

import numpy as np
import pytest

from ctrkin.models.ood import RANGE_UNIT, KnnIndex, batch_scores, part_scores, part_spans, spans_of


def brute_scores(z: np.ndarray, ref: np.ndarray, parts: np.ndarray, k: int, tau: np.ndarray, lo: np.ndarray,
                 hi: np.ndarray) -> np.ndarray:
    """The score as it was computed before the search: every part's (spans (P, 2)) brute-force k-NN
    distance over its median, the largest, plus the range excess summed column by column."""
    per_part = [part_scores(z, ref, int(a), int(b), k) / t for (a, b), t in zip(parts, tau, strict=True)]
    worst = np.zeros(len(z))
    for d in per_part:
        worst = np.maximum(worst, d)
    out = np.empty(len(z))
    for t in range(len(z)):
        excess = 0.0
        for f in range(z.shape[1]):
            excess += max(z[t, f] - hi[f], 0.0) + max(lo[f] - z[t, f], 0.0)
        out[t] = worst[t] + excess / RANGE_UNIT
    return out


def searched(z: np.ndarray, ref: np.ndarray, parts: np.ndarray, k: int, tau: np.ndarray, lo: np.ndarray,
             hi: np.ndarray) -> np.ndarray:
    ix = KnnIndex.of(ref, parts)
    stats = np.ascontiguousarray(np.vstack([np.zeros_like(lo), np.ones_like(lo), lo, hi]))
    return batch_scores(np.ascontiguousarray(z), ix.rows, ix.tree, ix.boxes, parts, k, tau, stats)


@pytest.mark.parametrize(("k", "split"), [(1, "fine"), (3, "fine"), (5, "fine"), (1, "blocks+translations"),
                                        (5, "blocks+translations")])
def test_searched_scan_is_brute_force_to_the_bit(k, split):
    rng = np.random.default_rng(k)
    parts = part_spans("pose+joints", 2, split)  # fine: 6, 2, 2, 12, 6 columns; else 6, 4, 2 (overlap), 12, 6
    width = int(parts[:, 1].max())
    cov = rng.normal(size=(width, width))
    ref = rng.normal(size=(600, width)) @ cov / 3          # correlated columns, as histories are
    ref[100:110] = ref[100]                                # exact duplicates: ties at the k-th
    ref[200:203, :6] = ref[5, :6]                          # duplicates within one part only
    z = np.vstack([rng.normal(size=(150, width)) @ cov / 3,
                   ref[:20],                               # queries on reference rows: distance 0
                   ref[:20] + 1e-13,                       # and a rounding away from them
                   rng.normal(size=(20, width)) * 50,      # far outside
                   np.full((1, width), 1e200)])            # squares that overflow
    tau = rng.uniform(0.3, 3.0, len(parts))
    lo, hi = ref.min(axis=0), ref.max(axis=0)
    want = brute_scores(z, ref, parts, k, tau, lo, hi)
    assert np.array_equal(searched(z, ref, parts, k, tau, lo, hi), want)


def test_a_part_that_cannot_raise_the_maximum_stops_early_and_changes_nothing():
    rng = np.random.default_rng(7)
    parts = spans_of(np.array([0, 3, 9]))
    ref = rng.normal(size=(800, 9))
    z = rng.normal(size=(200, 9))
    lo, hi = np.full(9, -1e9), np.full(9, 1e9)
    for tau in (np.array([0.01, 100.0]), np.array([100.0, 0.01]), np.array([1.0, 1.0])):
        want = brute_scores(z, ref, parts, 5, tau, lo, hi)
        assert np.array_equal(searched(z, ref, parts, 5, tau, lo, hi), want)


def test_a_nan_query_scores_as_brute_force_does():
    rng = np.random.default_rng(3)
    parts = spans_of(np.array([0, 4, 10]))
    ref = rng.normal(size=(300, 10))
    z = rng.normal(size=(4, 10))
    z[0, 0] = np.nan                       # in a part's first column
    z[1, 7] = np.nan                       # in the second part
    z[2, :] = np.nan
    tau, lo, hi = np.ones(2), ref.min(axis=0), ref.max(axis=0)
    got, want = searched(z, ref, parts, 5, tau, lo, hi), brute_scores(z, ref, parts, 5, tau, lo, hi)
    assert np.array_equal(np.isnan(got), np.isnan(want))
    assert np.array_equal(got[np.isfinite(want)], want[np.isfinite(want)])


def test_the_trees_boxes_hold_their_rows_and_the_leaves_cover_every_row_once():
    rng = np.random.default_rng(0)
    parts = np.array([[0, 2], [2, 5], [1, 4]], np.int64)       # the last overlaps both
    ref = rng.normal(size=(53, 5))
    ix = KnnIndex.of(ref, parts, leaf=4)
    first, end, left, right = ix.tree
    leaves = np.flatnonzero(left < 0)
    assert np.all(end[leaves] - first[leaves] <= 4)
    assert sorted(r for n in leaves for r in range(first[n], end[n])) == list(range(53))
    inner = np.flatnonzero(left >= 0)
    assert np.all(first[left[inner]] == first[inner]) and np.all(end[right[inner]] == end[inner])
    at = 0
    for p, (a, b) in enumerate(parts.tolist()):
        block = ix.rows[at:at + 53 * (b - a)].reshape(53, b - a)
        at += 53 * (b - a)
        assert sorted(map(tuple, block)) == sorted(map(tuple, ref[:, a:b]))
        for node in range(ix.tree.shape[1]):
            rows = block[first[node]:end[node]]
            box = ix.boxes[p, node, :, :b - a]
            assert np.all(rows >= box[0]) and np.all(rows <= box[1])


@pytest.mark.parametrize("leaf", [1, 2, 8, 64, 1000])
def test_every_leaf_size_gives_brute_forces_score(leaf):
    rng = np.random.default_rng(leaf)
    parts = np.array([[0, 4], [4, 10], [2, 6]], np.int64)
    ref = rng.normal(size=(300, 10))
    z = rng.normal(size=(50, 10)) * 1.5
    tau, lo, hi = np.array([0.7, 1.3, 0.4]), ref.min(axis=0), ref.max(axis=0)
    ix = KnnIndex.of(ref, parts, leaf=leaf)
    stats = np.ascontiguousarray(np.vstack([np.zeros(10), np.ones(10), lo, hi]))
    got = batch_scores(z, ix.rows, ix.tree, ix.boxes, parts, 5, tau, stats)
    assert np.array_equal(got, brute_scores(z, ref, parts, 5, tau, lo, hi))


@pytest.mark.parametrize("inputs", ["joints", "pose", "pose+joints"])
def test_the_streams_feature_kernel_is_sequence_features_to_rounding(inputs):
    from ctrkin.models.ood import HISTORY, _stream_features, input_width, mode, sequence_features

    rng = np.random.default_rng(1)
    x = rng.normal(0, 40, (25, input_width(inputs, 3)))
    bounds = [(0, 1), (1, 12), (12, 25)]
    want = sequence_features(inputs, 3, x, bounds)
    got = np.empty_like(want)
    for a, b in bounds:
        for t in range(a, b):
            lo = max(a, t - HISTORY)
            _stream_features(mode(inputs), 3, x[lo:t + 1], t + 1 - lo, np.zeros(want.shape[1]),
                             np.ones(want.shape[1]), got[t])
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("inputs", ["joints", "pose+joints"])
def test_the_translations_part_holds_the_joints_translations_beside_the_blocks(inputs):
    from ctrkin.models.ood import block_widths, input_width, sequence_features

    n = 3
    blocks = spans_of(np.cumsum([0, *block_widths(inputs, n)]))
    spans = part_spans(inputs, n, "blocks+translations")
    extra = [s for s in spans.tolist() if s not in blocks.tolist()]
    assert sorted(spans.tolist()) == sorted(blocks.tolist() + extra) and len(extra) == 1
    lo, hi = extra[0]
    x = np.random.default_rng(2).normal(0, 30, (5, input_width(inputs, n)))
    q = x[:, 6:] if inputs == "pose+joints" else x
    feats = sequence_features(inputs, n, x, [(0, 5)])
    assert np.array_equal(feats[:, lo:hi], q[:, n:])      # β1..βN, as they are
    assert np.array_equal(part_spans("pose", n, "blocks+translations"), part_spans("pose", n, "blocks"))
