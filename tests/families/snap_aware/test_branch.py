"""Branch labels (the relay the snap-aware model learns), the BranchNet's state decoding and its
head forms."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from ctrkin.errors import ModelError
from ctrkin.families.snap_aware.labels import BAND_DEG, branch_labels, phase_deg, previous_labels
from ctrkin.families.snap_aware.net import UNKNOWN_STATE, BranchNet, relay_scan
from ctrkin.families.snap_aware.recipe import OFFSET_MARGIN_DEG, offset_free_rows


def _turn() -> np.ndarray:
    """α0 0 → 360 → 0° in 1° steps (721 rows)."""
    return np.r_[np.arange(0, 361, 1.0), np.arange(359, -1, -1.0)]


def test_labels_switch_at_the_snaps_and_hold_between_them() -> None:
    a0 = _turn()
    snap = np.zeros(len(a0), bool)
    fwd, back = 205, 361 + (360 - 150)          # forward snap at α0 = 205°, back at 150°
    snap[[fwd, back]] = True
    labels, forced = branch_labels(a0, snap, [(0, len(a0))])
    assert (labels[:fwd] == 0).all() and labels[fwd] == 1          # lower branch until the snap
    held = np.arange(fwd, back)
    held = held[a0[held] < 360]                   # α0 = 360° is α0 = 0°: the phase wraps (forced, 0)
    assert (labels[held] == 1).all() and (labels[back:] == 0).all()   # held until the snap back
    assert labels[360] == 0 and forced[360]
    phi = phase_deg(a0)
    assert forced[np.abs(phi) > 90].all()                           # outside the band: no choice
    assert not forced[(np.abs(phi) < 90) & (np.arange(len(a0)) < fwd)].any()   # bistable before it
    assert forced[fwd + 1: fwd + 5].all()         # past the fold the old branch no longer exists


def test_no_snap_means_the_state_follows_the_phase() -> None:
    a0 = _turn()
    labels, _ = branch_labels(a0, np.zeros(len(a0), bool), [(0, len(a0))])
    assert labels[0] == 0 and labels[300] == 1    # outside the band on each side (φ = α0 − 180°)
    assert labels[360] == 0                       # periodic: 360° is 0°


def test_previous_labels_are_unknown_at_sequence_starts() -> None:
    prev = previous_labels(np.array([1, 0, 1, 1], np.int8), [(0, 2), (2, 4)])
    np.testing.assert_array_equal(prev, [0.5, 1.0, 0.5, 1.0])


def test_relay_scan_holds_its_state() -> None:
    from0 = np.array([0, 0, 1, 0, 0], bool)       # from state 0: switch to 1 at row 2
    from1 = np.array([1, 1, 1, 0, 1], bool)       # from state 1: back to 0 at row 3
    s = relay_scan(from0, from1, np.zeros(5, bool), [(0, 5)])
    np.testing.assert_array_equal(s, [0, 0, 1, 0, 0])


def test_decode_uses_the_head_of_each_rows_state() -> None:
    torch.manual_seed(0)
    net = BranchNet(5, 4, 2, structure="L8|D8", gate_units=4).eval()
    h = torch.randn(12, net.trunk_width)
    y, s = net.decode(h, [(0, 6), (6, 12)])
    with torch.no_grad():
        y0 = net.head_out(h, torch.zeros(12)).numpy()
        y1 = net.head_out(h, torch.ones(12)).numpy()
        start = (net.gate_logit(h, torch.full((12,), UNKNOWN_STATE)) > 0).numpy()
    np.testing.assert_allclose(y, np.where(s[:, None] == 1, y1, y0), atol=1e-6)
    assert s[0] == start[0] and s[6] == start[6]


@pytest.mark.parametrize("structure", ["L8|D8", "L8|D8,D4", "L8|"])
def test_offset_heads_merge_into_two_ordinary_heads(structure) -> None:
    """heads "offset": branch s gives z ± ½d (s = 1: +), and heads() (what the streaming engine and
    the fused step run) gives the same as two ordinary heads of the summed width."""
    torch.manual_seed(0)
    net = BranchNet(5, 6, 2, structure=structure, gate_units=4, heads="offset").eval()
    with torch.no_grad():
        net.out1.weight.normal_()
        net.out1.bias.normal_()
        h = torch.randn(9, net.trunk_width)
        s = torch.tensor([0, 1, 0, 1, 1, 0, 1, 0, 0], dtype=torch.float32)
        _, d = net.offset_out(h, s[:, None])
        y = net.head_out(h, s)
        y0, y1 = net.head_out(h, torch.zeros(9)), net.head_out(h, torch.ones(9))    # z − ½d, z + ½d
        np.testing.assert_allclose((y1 - y0).numpy(), d.numpy(), atol=1e-6)
        np.testing.assert_allclose(y.numpy(), torch.where(s[:, None] > 0.5, y1, y0).numpy(), atol=1e-6)
        assert d.abs().min() > 0
        merged = []
        for layers, out in net.heads():
            x = h
            for layer in layers:
                x = torch.relu(layer(x))
            merged.append(out(x))
    branch = torch.where(s[:, None] > 0.5, merged[1], merged[0])
    np.testing.assert_allclose(branch.numpy(), y.numpy(), atol=1e-5)


def test_head_forms_are_checked() -> None:
    with pytest.raises(ModelError, match="heads must be one of"):
        BranchNet(5, 6, 2, structure="L8|D8", heads="shared")


def test_the_offset_penalty_starts_beyond_the_band_and_the_furthest_training_snap() -> None:
    """offset_free_rows: |φ| > max(BAND_DEG, furthest training snap's |φ| + OFFSET_MARGIN_DEG); a
    snap outside the training rows does not move the edge."""
    alpha0 = np.r_[np.arange(180.0, 360.0), np.arange(180.0, 0.0, -1.0)]     # φ 0 → 179, 0 → −179
    snap = np.zeros(len(alpha0), dtype=bool)
    bounds = [(0, 180), (180, 360)]
    every = np.arange(len(alpha0))
    phi = np.abs(phase_deg(alpha0))
    np.testing.assert_array_equal(offset_free_rows(alpha0, snap, every, bounds), phi > BAND_DEG)
    snap[30] = True                                            # a snap at φ = 30°: the band's edge holds
    np.testing.assert_array_equal(offset_free_rows(alpha0, snap, every, bounds), phi > BAND_DEG)
    snap[180 + 79] = True                                      # one at φ = −79°: the edge moves out
    edge = 79.0 + OFFSET_MARGIN_DEG
    np.testing.assert_array_equal(offset_free_rows(alpha0, snap, every, bounds), phi > edge)
    np.testing.assert_array_equal(offset_free_rows(alpha0, snap, np.arange(180), bounds), phi > BAND_DEG)
