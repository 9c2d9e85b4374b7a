"""Transmission: the dead band, the play operator, mechanical stops."""

from __future__ import annotations

import numpy as np
import pytest

from ctrkin.acquisition.protocols import config
from ctrkin.virtual import VirtualConfig
from ctrkin.virtual.transmission import clip_to_valid, dead_band, play


def test_dead_band_grows_with_overlap(robot):
    """The lumped overlap-dependent wind-up, an option since friction between the tubes models it
    (its default is 0): set explicitly here."""
    c = VirtualConfig(friction_deg_per_mm=0.8)
    q = config(2, 0.0, 0.0, 0.0, np.array([4.0, 12.0, 20.0]))
    w = dead_band(robot, c, q)
    base = c.gear_backlash_deg + c.friction_deg
    np.testing.assert_allclose(w[:, 0], base + c.friction_deg_per_mm * np.array([0.0, 6.5, 14.5]))
    np.testing.assert_allclose(w[:, 2:], c.leadscrew_backlash_mm)


def test_play_lags_by_half_the_band_after_a_reversal():
    m = np.r_[np.arange(0.0, 11.0), np.arange(9.0, -1.0, -1.0)][:, None]  # 0..10..0
    out = np.empty_like(m)
    play(m, np.full_like(m, 4.0), np.zeros(1), out)
    # forward: the base trails by 2 once the play is taken up; at the reversal it stays put
    assert out[10, 0] == pytest.approx(8.0)
    np.testing.assert_allclose(out[11:13, 0], 8.0)  # motor 9, 8: still inside the band
    assert out[-1, 0] == pytest.approx(2.0)  # motor back at 0, base still 2 ahead
    assert np.all(np.abs(out - m) <= 2.0 + 1e-12)


def test_clip_to_valid_only_moves_invalid_translations(robot, rng):
    q = np.column_stack([rng.uniform(0, 360, (200, 2)), rng.uniform(-80, 10, (200, 2))])
    c = clip_to_valid(robot, q)
    assert robot.is_valid(c).all()
    ok = robot.is_valid(q)
    np.testing.assert_array_equal(c[ok], q[ok])
    np.testing.assert_array_equal(c[:, :2], q[:, :2])
