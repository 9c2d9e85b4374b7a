"""The play-operator form of a snap's delay (ctrkin.families.snap_aware.play): the operators, and its
identification recovering a known delay from a synthetic history."""

from __future__ import annotations

import numpy as np
import pytest

from ctrkin.families.snap_aware import play

WIDTHS = (2.0, 5.0, 15.0, 45.0)


def test_play_lag_is_bounded_and_follows_a_reversal() -> None:
    x = np.r_[np.arange(0, 31.0), np.arange(29.0, 9.0, -1.0)]          # 0 → 30 → 10 deg
    q = np.column_stack([x, np.zeros_like(x), np.zeros_like(x), np.zeros_like(x)])
    lags = play.path_lags(q, [(0, len(x))], 2, angle_widths=WIDTHS)
    inner = lags.inner * WIDTHS                                          # deg
    assert np.all(lags.outer == 0.0) and np.all(lags.slide == 0.0)
    assert np.all(np.abs(lags.inner) <= 1.0 + 1e-12)
    np.testing.assert_allclose(inner[30], [2.0, 5.0, 15.0, 30.0])       # wound forward, up to its width
    np.testing.assert_allclose(inner[-1], [-2.0, -5.0, -5.0, 10.0])      # 20° back: the wider ones still rest


def test_a_run_carries_the_lags_and_a_new_one_starts_at_rest() -> None:
    x = np.r_[np.arange(0, 11.0), np.arange(10.0, 21.0)]
    q = np.column_stack([x, np.zeros_like(x), np.zeros_like(x), np.zeros_like(x)])
    bounds = [(0, 11), (11, 22)]
    carried = play.path_lags(q, bounds, 2, runs=np.zeros(22, int), angle_widths=WIDTHS).inner * WIDTHS
    fresh = play.path_lags(q, bounds, 2, runs=np.r_[np.zeros(11, int), np.ones(11, int)],
                           angle_widths=WIDTHS).inner
    np.testing.assert_allclose(carried[11], [2.0, 5.0, 10.0, 10.0])
    np.testing.assert_allclose(fresh[11], 0.0)


def test_the_slide_play_follows_the_relative_translation() -> None:
    d = np.r_[np.full(3, 16.0), np.linspace(16.0, 20.0, 41), np.full(3, 20.0)]      # the inner slides back
    q = np.column_stack([np.zeros_like(d), np.zeros_like(d), -d, np.zeros_like(d)])
    lags = play.path_lags(q, [(0, len(d))], 2, slide_widths=(0.05, 1.0))
    np.testing.assert_allclose(lags.slide[-1], [1.0, 1.0])             # both wound fully
    both = np.column_stack([np.zeros_like(d), np.zeros_like(d), -d, 16.0 - d])     # both tubes together
    assert not play.path_lags(both, [(0, len(d))], 2).slide.any()


def _synthetic(seed: int) -> tuple[play.SnapRows, dict[str, float]]:
    """Snaps of a known form: full inner turns after random outer steps and inner slides, one run
    each; the tubes snap where φ − w·L(α1) + v·L(αN) crosses ±(c − u·L(d)) + g·φ± (φ± = ±30°)."""
    rng = np.random.default_rng(seed)
    truth = {"c": 12.0, "g": 1.1, "w": 3.0, "v": 36.0, "u": 5.0}
    # deg when fully wound: w on the 5° play, v on the 45°, u on the 0.05 mm one
    rows = []
    for run in range(12):
        outer0 = rng.uniform(0, 360)
        step = rng.choice([-1, 1]) * rng.uniform(5, 40)
        outer = np.r_[np.full(1, outer0), outer0 + np.linspace(0, step, 10)]
        a0 = np.r_[np.arange(0.0, 361.0), np.arange(359.0, -1.0, -1.0)] + 180.0 - 90.0
        q = np.zeros((len(outer) + len(a0), 4))
        q[:len(outer), 1] = outer
        q[:len(outer), 0] = outer + a0[0]
        q[len(outer):, 1] = outer[-1]
        q[len(outer):, 0] = outer[-1] + a0
        q[:, 2] = -20.0 + np.r_[np.linspace(rng.choice([0.0, 0.03, 0.3]), 0.0, len(outer)), np.zeros(len(a0))]
        lags = play.path_lags(q, [(0, len(q))], 2, angle_widths=WIDTHS, slide_widths=(0.05, 1.0))
        inner, lag_out, slide = lags.inner, lags.outer, lags.slide
        phi = (q[:, 0] - q[:, 1]) % 360.0 - 180.0
        eff = phi - truth["w"] * inner[:, 1] + truth["v"] * lag_out[:, 3]
        narrow = truth["u"] * slide[:, 0]
        state = 0
        for t in range(len(outer) + 1, len(q)):
            s = int(np.sign((q[t, 0] - q[t, 1]) - (q[t - 1, 0] - q[t - 1, 1])))
            fold = 30.0 * s
            c = truth["c"] - narrow[t]
            if abs(phi[t]) < 90 and ((state == 0 and s > 0 and eff[t] >= truth["g"] * fold + c)
                                     or (state == 1 and s < 0 and eff[t] < truth["g"] * fold - c)):
                state = 1 - state
                # the snap mid-way between rows t−1 and t: the data's convention (play.snap_rows)
                rows.append((s, fold, phi[t] - 0.5 * s, lags.mid(t), run))
    s_, f_, p_, l_, r_ = zip(*rows, strict=True)
    mid = play.Lags(*(np.concatenate([getattr(lg, k) for lg in l_]) for k in ("inner", "outer", "slide")))
    return play.SnapRows(np.array(s_, float), np.array(f_), np.array(p_), mid, np.array(r_)), truth


def test_identify_recovers_a_known_play_delay() -> None:
    rows, truth = _synthetic(0)
    assert len(rows.sign) >= 20
    ident = play.identify(rows)
    assert np.isfinite(ident.cv_rms_deg) and ident.cv_rms_deg < 1.0       # 12 runs, leave one out
    A, b = rows.design()
    x = ident.x
    assert np.sqrt(np.mean((A @ x - b) ** 2)) < 0.75                       # the row grid is 1°
    # the delay the form predicts on every snap agrees with the truth's (the weights may share a
    # lag between widths where the data wind both fully: compare what they predict)
    true_x = np.r_[truth["c"], truth["g"], [0, truth["w"], 0, 0], [0, 0, 0, truth["v"]], [truth["u"], 0]]
    assert np.abs(A @ x - A @ true_x).max() < 1.5
    assert np.all(x[1:] >= 0)
    # the narrowing after a slide: 5° at the saturated 0.05 mm play (lags 1, 0.3), 3° after 0.03 mm
    assert ident.slide @ [1.0, 0.3] == pytest.approx(5.0, abs=1.0)
    assert ident.slide @ [0.6, 0.03] == pytest.approx(3.0, abs=1.0)


def test_identify_without_snaps_is_the_plain_fold() -> None:
    k = len(WIDTHS)
    lags = play.Lags(np.zeros((0, k)), np.zeros((0, k)), np.zeros((0, 2)))
    empty = play.SnapRows(np.zeros(0), np.zeros(0), np.zeros(0), lags, np.zeros(0, np.int64))
    ident = play.identify(empty)
    assert ident.widen_deg == 0.0 and ident.fold_scale == 1.0 and not ident.inner.any()
