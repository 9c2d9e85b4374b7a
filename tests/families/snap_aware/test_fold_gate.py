"""The fold gate: its relay, the outer tube's last rotation, the fit of its offsets, its file."""

from __future__ import annotations

import numpy as np
import pytest

from ctrkin.errors import ModelError
from ctrkin.families.snap_aware.fold_gate import FoldGate, _fit_offsets


def _gate(fold: float = 20.0, c: float = 0.0, lag: float = 0.0) -> FoldGate:
    axes = (np.array([-20.0, 0.0]), np.array([0.0]))
    table = np.full((2, 1), fold)
    return FoldGate(axes, table, -table, c, lag)


def _turn(step: float = 1.0) -> np.ndarray:
    """α0 from 90° up to 270° and back (φ −90 .. 90 .. −90), β fixed."""
    a = np.r_[np.arange(90.0, 270.0 + step / 2, step), np.arange(270.0 - step, 90.0 - step / 2, -step)]
    return a


def _switches(gate: FoldGate, a0: np.ndarray, motion: int = 0) -> list[float]:
    s = gate.states(a0, np.zeros((len(a0), 2)), np.full(len(a0), motion), [(0, len(a0))])
    return [float(a0[t] - 180.0) for t in np.nonzero(np.diff(s))[0] + 1]


def test_relay_switches_at_each_fold_in_its_direction_and_holds_between() -> None:
    assert _switches(_gate(20.0), _turn()) == [20.0, -21.0]          # φ ≥ θ+ up, φ < θ− down
    assert _switches(_gate(20.0, c=3.0), _turn()) == [23.0, -24.0]   # a wider band


def test_outer_tube_lag_shifts_both_folds_the_same_way() -> None:
    gate = _gate(20.0, lag=5.0)
    assert _switches(gate, _turn(), motion=1) == [15.0, -26.0]
    assert _switches(gate, _turn(), motion=-1) == [25.0, -16.0]


def test_no_fold_means_the_state_changes_only_outside_the_band() -> None:
    """Where the pair does not snap the state follows the labels' convention: it changes beyond
    ±band only, never back and forth near φ = 0."""
    a0 = np.r_[np.arange(0.0, 361.0), np.arange(359.0, -1.0, -1.0)]
    s = _gate(0.0, c=2.0, lag=5.0).states(a0, np.zeros((len(a0), 2)), np.ones(len(a0)), [(0, len(a0))])
    # at +90° going up (θ+ = band), the wrap at α0 = 360° (φ = −180°) and back, beyond −90° going down
    np.testing.assert_array_equal(a0[np.nonzero(np.diff(s))[0] + 1], [270.0, 360.0, 359.0, 89.0])


def test_step_equals_states() -> None:
    gate = _gate(20.0, c=1.0, lag=4.0)
    a0 = _turn(0.7)
    betas = np.tile([-10.0, 0.0], (len(a0), 1))
    batch = gate.states(a0, betas, np.ones(len(a0)), [(0, len(a0))])
    cur, stream = -1, []
    for a in a0:
        cur = gate.step(cur, a, betas[0], 1)
        stream.append(cur)
    np.testing.assert_array_equal(batch, stream)


def test_offsets_are_recovered_from_the_snaps() -> None:
    """Snaps made at θ± = ±(20 + c) − κ m_N on turns with the outer tube at rest and after a forward
    move: the fit recovers c and κ (to the data's 1° step)."""
    c, lag = 2.0, 6.0
    gate = _gate(20.0)
    rows, snap, motion, bounds = [], [], [], []
    for m in (0, 1, 1, 1):
        a0 = _turn()
        phi = a0 - 180.0
        up = np.arange(len(a0)) < len(a0) // 2
        flags = np.zeros(len(a0), bool)
        flags[np.argmax(up & (phi >= 20.0 + c - lag * m))] = True
        flags[np.argmax(~up & (phi < -20.0 - c - lag * m))] = True
        start = len(rows)
        rows.extend(np.c_[a0, np.zeros_like(a0), np.zeros_like(a0), np.zeros_like(a0)])
        snap.extend(flags)
        motion.extend([m] * len(a0))
        bounds.append((start, len(rows)))
    c_fit, lag_fit = _fit_offsets(gate, np.array(rows), np.array(snap), bounds, np.array(motion), 2)
    assert c_fit == pytest.approx(c, abs=1.0)
    assert lag_fit == pytest.approx(lag, abs=1.0)


def test_file_round_trip_and_malformed_files(tmp_path) -> None:
    gate = _gate(20.0, c=1.5, lag=3.0)
    gate.save(tmp_path)
    back = FoldGate.load(tmp_path)
    assert back.widen_deg == gate.widen_deg and back.outer_lag_deg == 3.0
    np.testing.assert_array_equal(back.forward, gate.forward)
    (tmp_path / "fold_gate.json").write_text('{"axes_mm": [[0, 0]], "forward_deg": [1, 2]}')
    with pytest.raises(ModelError):
        FoldGate.load(tmp_path)
    (tmp_path / "fold_gate.json").write_text("{not json")
    with pytest.raises(ModelError):
        FoldGate.load(tmp_path)


def test_a_sequence_that_continues_its_run_keeps_the_branch() -> None:
    """A turn that ends on the upper branch inside the band (φ = 10° after a forward snap at 20°),
    then a new sequence of the same run starting there: it stays on branch 1; from rest the gate
    could only guess by the sign of φ (also 1 here), so start the second one at φ = −5°."""
    gate = _gate(20.0)
    first = np.arange(170.0, 211.0)                       # φ −10 .. 30: the forward snap at 20
    second = np.arange(175.0, 160.0, -1.0)                # φ −5 .. −19: inside the band, going down
    a0 = np.r_[first, second]
    bounds = [(0, len(first)), (len(first), len(a0))]
    betas, motion = np.zeros((len(a0), 2)), np.zeros(len(a0))
    kept = gate.states(a0, betas, motion, bounds, [False, True])
    fresh = gate.states(a0, betas, motion, bounds, [False, False])
    assert kept[len(first) - 1] == 1 and kept[len(first):].tolist() == [1] * len(second)
    assert fresh[len(first):].tolist() == [0] * len(second)
