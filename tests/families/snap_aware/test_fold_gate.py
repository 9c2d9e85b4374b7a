"""The fold gate: its relay, the outer tube's last rotation, its slide memory, the fit of its offsets,
its file."""

from __future__ import annotations

import numpy as np
import pytest

from ctrkin.errors import ModelError
from ctrkin.families.snap_aware.fold_gate import SLIDE_WIDTHS_MM, FoldGate, _fit_offsets, slide_lags


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
    # beyond +90° going up (at φ = +band exactly the state is held, as the labels hold it), the wrap
    # at α0 = 360° (φ = −180°) and back, beyond −90° going down
    np.testing.assert_array_equal(a0[np.nonzero(np.diff(s))[0] + 1], [271.0, 360.0, 359.0, 89.0])


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
    c_fit, lag_fit, slide, g = _fit_offsets(gate, np.array(rows), np.array(snap), bounds, np.array(motion), 2)
    assert slide == () and g == 1.0                 # no slide memory and no fold scale asked for
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


def _slid_turns(c: float, u_total: float, slid: tuple[bool, ...]
                ) -> tuple[np.ndarray, np.ndarray, list, np.ndarray]:
    """One run per turn (α0 90 → 270 → 90°, d = 20 mm); a turn after a slide of the inner tube onto d
    (d − 2 → d: each play taken up) snaps at ±(20 + c − u_total), one from rest at ±(20 + c).
    Returns joints (T, 4) [α1, α2, β1, β2], snap flags, bounds, runs."""
    rows, snap, bounds, runs = [], [], [], []
    for k, s in enumerate(slid):
        start = len(rows)
        if s:                                   # the slide: d from 18 to 20 mm at α0 = 90° (no snap)
            for d in np.linspace(18.0, 20.0, 9):
                rows.append([90.0, 0.0, -d, 0.0])
                snap.append(False)
        a0 = _turn()
        phi = a0 - 180.0
        up = np.arange(len(a0)) < len(a0) // 2
        w = 20.0 + c - (u_total if s else 0.0)
        flags = np.zeros(len(a0), bool)
        flags[np.argmax(up & (phi >= w))] = True
        flags[np.argmax(~up & (phi < -w))] = True
        rows.extend([[a, 0.0, -20.0, 0.0] for a in a0])
        snap.extend(flags)
        bounds.append((start, len(rows)))
        runs.extend([k] * (len(rows) - start))
    return np.array(rows), np.array(snap), bounds, np.array(runs)


def test_the_slide_memory_is_identified_from_snaps_after_slides_and_moves_the_switch() -> None:
    """Turns from rest snap 8° later than turns after a slide: the fit finds c and u (Σu ≈ 8°), the
    gate then switches at each turn's own snap in batch and in streaming alike."""
    c, u_total = 5.0, 8.0
    q, snap, bounds, runs = _slid_turns(c, u_total, (False, True, False, True, True, False))
    ell = slide_lags(None, q, bounds, 2)                # each run from rest
    assert np.abs(ell[bounds[1][0] + 9]) == pytest.approx(np.ones(len(SLIDE_WIDTHS_MM)))   # after the slide
    assert not ell[bounds[2][0]:bounds[2][1]].any()                                    # a run from rest
    table = _gate(20.0)
    c_fit, lag_fit, u, _ = _fit_offsets(table, q, snap, bounds, np.zeros(len(q)), 2, ell, runs)
    assert c_fit == pytest.approx(c, abs=1.0) and sum(u) == pytest.approx(u_total, abs=1.0)
    gate = FoldGate(table.axes, table.forward, table.backward, c_fit, lag_fit, slide_weights_deg=u)
    assert gate.slides
    a0 = q[:, 0] - q[:, 1]
    motion = np.zeros(len(q))
    states = gate.states(a0, q[:, 2:], motion, bounds, [False] * len(bounds), ell)
    switched = np.nonzero(np.diff(states.astype(int)))[0] + 1
    snapped = np.nonzero(snap)[0]
    assert len(switched) == len(snapped) and np.abs(switched - snapped).max() <= 1
    play, stream = gate.slide_state(2), []
    for a, b in bounds:
        assert play is not None
        play.reset()
        cur = -1
        for t in range(a, b):
            lags, y = play.after(q[t])
            play.advance(y)
            cur = gate.step(cur, a0[t], q[t, 2:], 0, lags)
            stream.append(cur)
    np.testing.assert_array_equal(states, stream)
    with pytest.raises(ModelError, match="slide"):
        gate.states(a0, q[:, 2:], motion, bounds)


def test_no_slide_memory_where_no_snap_follows_a_slide_or_it_does_not_help() -> None:
    """Every turn from rest: no lag to identify, u = (); slides that do not move the snaps: the
    leave-one-run-out check keeps the form without the memory."""
    table = _gate(20.0)
    for slid in ((False,) * 4, (False, True, False, True)):
        q, snap, bounds, runs = _slid_turns(5.0, 0.0, slid)
        ell = slide_lags(None, q, bounds, 2)
        assert _fit_offsets(table, q, snap, bounds, np.zeros(len(q)), 2, ell, runs)[2] == ()


def test_a_slide_memory_round_trips_and_a_malformed_one_is_refused(tmp_path) -> None:
    table = _gate(20.0)
    gate = FoldGate(table.axes, table.forward, table.backward, 3.0, 1.0, slide_weights_deg=(2.0, 1.0, 0.0))
    gate.save(tmp_path)
    assert FoldGate.load(tmp_path).slide_weights_deg == (2.0, 1.0, 0.0)
    d = gate.to_dict()
    d.pop("slide_weights_deg"), d.pop("slide_widths_mm")        # a gate written before the memory
    assert FoldGate.from_dict(d).slide_weights_deg == () and not FoldGate.from_dict(d).slides
    for bad in ({"slide_weights_deg": [2.0, -1.0, 0.0]}, {"slide_widths_mm": [0.1, 0.2, 1.0]},
                {"slide_weights_deg": [1.0]}):
        with pytest.raises(ModelError):
            FoldGate.from_dict({**gate.to_dict(), **bad})


def test_a_recording_without_snaps_gives_a_gate_without_folds(monkeypatch) -> None:
    """No snap in the training rows (a robot whose friction carries it across the nominal folds):
    the nominal folds are not assumed, and the gate's states are the labels the heads learned
    (they change only outside the band); with a snap in them the nominal folds are tabulated."""
    from ctrkin import paper_robot
    from ctrkin.families.snap_aware import fold_gate as fg
    from ctrkin.families.snap_aware.labels import branch_labels

    tabulated = []

    def folds(robot, grid, step_deg, progress=None):
        tabulated.append(len(grid))
        return np.full(len(grid), 20.0), np.full(len(grid), -20.0)

    monkeypatch.setattr(fg, "fold_angles", folds)
    turn = np.r_[np.arange(0.0, 361.0), np.arange(359.0, -1.0, -1.0)]     # across the band and out
    a0 = np.r_[turn, turn + 0.5, turn + 35.5]     # 1° steps from 0°: φ exactly ±band (90°) too
    joints = np.c_[a0, np.zeros_like(a0), np.full_like(a0, -10.0), np.zeros_like(a0)]
    bounds = [(k * len(turn), (k + 1) * len(turn)) for k in range(3)]
    snap = np.zeros(len(a0), bool)
    gate = fg.build_fold_gate(paper_robot(), joints, snap, bounds, np.zeros(len(a0)))
    assert tabulated == [] and not gate.forward.any() and not gate.backward.any()
    states = gate.states(a0, joints[:, 2:], np.zeros(len(a0)), bounds)
    np.testing.assert_array_equal(states, branch_labels(a0, snap, bounds)[0])
    snap[np.argmax(a0 - 180.0 >= 20.0)] = True
    gate = fg.build_fold_gate(paper_robot(), joints, snap, bounds, np.zeros(len(a0)))
    assert tabulated == [1] and gate.forward.max() > 0


def _levels_gate() -> FoldGate:
    """A fold table that grows with the overlap: φ± = ±(10 + β1) over β1 0..20 mm (10° .. 30°)."""
    axes = (np.array([0.0, 10.0, 20.0]), np.array([0.0]))
    table = np.array([[10.0], [20.0], [30.0]])
    return FoldGate(axes, table, -table)


def test_a_fold_scale_is_fitted_only_where_asked_and_only_where_it_helps() -> None:
    """Snaps at ±(g·φ±(β) + c) at five overlaps, one run each: with fold_scale the fit recovers g
    and c and the gate switches there; without it g = 1; snaps at ±(φ± + c) keep g = 1."""
    table = _levels_gate()

    def turns(g: float, c: float) -> tuple[np.ndarray, np.ndarray, list, np.ndarray]:
        rows, snap, bounds, runs = [], [], [], []
        for k, beta in enumerate((2.0, 6.0, 10.0, 14.0, 18.0)):
            a0, start = _turn(), len(rows)
            phi, up = a0 - 180.0, np.arange(len(a0)) < len(a0) // 2
            w = g * (10.0 + beta) + c
            flags = np.zeros(len(a0), bool)
            flags[np.argmax(up & (phi >= w))] = True
            flags[np.argmax(~up & (phi < -w))] = True
            rows.extend([[a, 0.0, beta, 0.0] for a in a0])
            snap.extend(flags)
            bounds.append((start, len(rows)))
            runs.extend([k] * len(a0))
        return np.array(rows), np.array(snap), bounds, np.array(runs)

    q, snap, bounds, runs = turns(0.5, 12.0)
    zero = np.zeros(len(q))
    c_fit, _, _, g = _fit_offsets(table, q, snap, bounds, zero, 2, None, runs, fold_scale=True)
    assert g == pytest.approx(0.5, abs=0.05) and c_fit == pytest.approx(12.0, abs=1.0)
    assert _fit_offsets(table, q, snap, bounds, zero, 2, None, runs)[3] == 1.0
    gate = FoldGate(table.axes, table.forward, table.backward, c_fit, fold_scale=g)
    states = gate.states(q[:, 0] - q[:, 1], q[:, 2:], zero, bounds)
    switched = np.nonzero(np.diff(states.astype(int)))[0] + 1
    switched = switched[~np.isin(switched, [a for a, _ in bounds])]          # not a sequence start
    assert np.abs(switched - np.nonzero(snap)[0]).max() <= 1
    q, snap, bounds, runs = turns(1.0, 3.0)
    assert _fit_offsets(table, q, snap, bounds, zero, 2, None, runs, fold_scale=True)[3] == 1.0


def test_a_fold_scale_round_trips_and_an_older_gate_has_none(tmp_path) -> None:
    table = _levels_gate()
    gate = FoldGate(table.axes, table.forward, table.backward, 3.0, fold_scale=0.6)
    np.testing.assert_allclose(gate.folds(np.array([[10.0, 0.0]]))[0], [12.0])       # g·φ+
    gate.save(tmp_path)
    assert FoldGate.load(tmp_path).fold_scale == 0.6
    d = gate.to_dict()
    d.pop("fold_scale")                                     # a gate written before the scale
    assert FoldGate.from_dict(d).fold_scale == 1.0
    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(ModelError, match="fold_scale"):
            FoldGate.from_dict({**d, "fold_scale": bad})


def test_in_use_round_trips_an_older_gate_is_in_use_and_a_malformed_flag_is_refused(tmp_path) -> None:
    from dataclasses import replace

    gate = replace(_gate(20.0, c=1.5), in_use=False)
    gate.save(tmp_path)
    back = FoldGate.load(tmp_path)
    assert back.in_use is False and back.widen_deg == 1.5
    d = gate.to_dict()
    d.pop("in_use")                                         # a gate written before the choice
    assert FoldGate.from_dict(d).in_use is True
    with pytest.raises(ModelError, match="in_use"):
        FoldGate.from_dict({**d, "in_use": "no"})
