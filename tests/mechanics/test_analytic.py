"""The solver against closed-form results: circular arcs and the two-tube snapping criterion."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from ctrkin import Robot, SolverSettings, Tube, follow, solve

# Closed-form geometry is checked with a fine 0.5 mm RK4 step, ~1e-9 mm from exact on these arcs
# (local error ∝ (κh)^5), against one tolerance of 1e-6 mm: three orders of margin, and any
# modelling error (a wrong sign or factor) moves the tip by millimetres. The default step's own
# accuracy is tested against the reference integration in test_pointwise.py.
FINE = SolverSettings(step=0.5)
ARC_TOL_MM = 1e-6


def arc_tip(kappa: float, straight: float, curved: float, alpha_deg: float) -> np.ndarray:
    """Tip of a straight stretch then a circular arc bending towards −y in the tube frame
    (û = (κ, 0, 0)), turned about z by α."""
    th = kappa * curved
    p = np.array([0.0, -(1 - math.cos(th)) / kappa, straight + math.sin(th) / kappa])
    a = math.radians(alpha_deg)
    rz = np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])
    return rz @ p


@pytest.mark.parametrize("alpha", [0.0, 37.0, 200.0])
@pytest.mark.parametrize("beta", [0.0, -12.0, -30.0])
def test_single_tube_is_exact_circular_arc(alpha: float, beta: float) -> None:
    kappa = 1 / 25.0
    robot = Robot((Tube(1.0, 0.8, straight_length=30.0, curved_length=20.0, curvature=kappa),))
    eq = solve(robot, [alpha, beta], settings=FINE)
    assert eq.converged and eq.stable
    exposed_straight = max(30.0 + beta, 0.0)
    exposed_curved = min(20.0, 50.0 + beta)
    expected = arc_tip(kappa, exposed_straight, exposed_curved, alpha)
    np.testing.assert_allclose(eq.tip_position, expected, atol=ARC_TOL_MM)
    th = kappa * exposed_curved
    a = math.radians(alpha)
    tangent = np.array([math.sin(a) * math.sin(th), -math.cos(a) * math.sin(th), math.cos(th)])
    np.testing.assert_allclose(eq.tip_tangent, tangent, atol=ARC_TOL_MM)


@pytest.mark.parametrize("kappas", [(1 / 30.0, 1 / 30.0), (1 / 20.0, 1 / 45.0)])
def test_aligned_tubes_give_combined_arc(kappas: tuple[float, float]) -> None:
    """Aligned tubes carry no torque; on the overlap the curvature is Σ kκ / Σ k (eq. M1)."""
    inner = Tube(0.8, 0.6, 40.0, 15.0, kappas[0])
    outer = Tube(1.2, 0.9, 25.0, 15.0, kappas[1])
    robot = Robot((inner, outer))
    # both curved parts on s ∈ [0, 15], tips together
    eq = solve(robot, [30.0, 30.0, -40.0, -25.0], settings=FINE)
    assert eq.converged and eq.stable
    k1, k2 = inner.bending_stiffness, outer.bending_stiffness
    kappa = (k1 * kappas[0] + k2 * kappas[1]) / (k1 + k2)
    np.testing.assert_allclose(eq.tip_position, arc_tip(kappa, 0.0, 15.0, 30.0), atol=ARC_TOL_MM)
    np.testing.assert_allclose(eq.x, 0.0, atol=1e-12)


def test_straight_outer_tube_stiffens_the_arc() -> None:
    """A straight tube adds stiffness but no curvature: κ_eff = k1 κ1 / (k1 + k2)."""
    inner = Tube(0.8, 0.6, 40.0, 15.0, 1 / 20.0)
    outer = Tube(1.2, 0.9, 25.0, 15.0, 0.0)
    eq = solve(Robot((inner, outer)), [10.0, 70.0, -40.0, -25.0], settings=FINE)
    k1, k2 = inner.bending_stiffness, outer.bending_stiffness
    expected = arc_tip(k1 / 20.0 / (k1 + k2), 0.0, 15.0, 10.0)
    np.testing.assert_allclose(eq.tip_position, expected, atol=ARC_TOL_MM)


# --- two-tube snapping criterion (docs/mechanics.md: Model) ------------------------------------

KAPPA, NU = 1 / 30.0, 0.33


def _robot(curved: float, straight_inner: float, straight_outer: float, rigid: bool) -> Robot:
    inner = Tube(0.8, 0.6, straight_inner, curved, KAPPA, poisson_ratio=NU)
    outer = Tube(1.2, 0.9, straight_outer, curved, KAPPA, poisson_ratio=NU)
    return Robot((inner, outer), transmission="rigid" if rigid else "compliant")


def critical_overlap(straight_inner: float, straight_outer: float, rigid: bool) -> float:
    """Curved overlap L* with λ tan λ = L / b (compliant) or λ = π/2 (rigid), λ = L √c."""
    c = (1 + NU) * KAPPA * KAPPA
    if rigid:
        return math.pi / 2 / math.sqrt(c)
    probe = _robot(10.0, straight_inner, straight_outer, rigid)
    g1, g2 = (t.torsional_stiffness for t in probe.tubes)
    b = (straight_inner / g1 + straight_outer / g2) / (1 / g1 + 1 / g2)
    return brentq(lambda L: L * math.sqrt(c) * math.tan(L * math.sqrt(c)) - L / b,
                  1e-6, math.pi / 2 / math.sqrt(c) - 1e-9)


def _full_turn_sweep(robot: Robot, straight_inner: float, straight_outer: float):
    a = np.r_[np.arange(0, 361), np.arange(359, -1, -1)].astype(float)
    z = np.zeros_like(a)
    # curved parts start at s = 0 and end together: the straight parts are the transmission
    Q = np.c_[a, z, z - straight_inner, z - straight_outer]
    return a, follow(robot, Q)


CASES = [(60.0, 30.0, False), (20.0, 10.0, False), (100.0, 100.0, False), (50.0, 20.0, True)]


@pytest.mark.parametrize(("si", "so", "rigid"), CASES)
def test_no_snap_below_critical_overlap(si: float, so: float, rigid: bool) -> None:
    lc = critical_overlap(si, so, rigid)
    _, traj = _full_turn_sweep(_robot(0.97 * lc, si, so, rigid), si, so)
    assert traj.n_snaps == 0
    assert traj.stable.all()
    fwd, bwd = traj.tip_positions[:361], traj.tip_positions[360:][::-1]
    np.testing.assert_allclose(fwd, bwd, atol=1e-6)  # no hysteresis without a fold


@pytest.mark.parametrize(("si", "so", "rigid"), CASES)
def test_snap_above_critical_overlap_symmetric(si: float, so: float, rigid: bool) -> None:
    lc = critical_overlap(si, so, rigid)
    a, traj = _full_turn_sweep(_robot(1.03 * lc, si, so, rigid), si, so)
    idx = np.nonzero(traj.snaps)[0]
    assert len(idx) == 2, f"expected one forward and one backward snap, got steps {idx}"
    fwd_angle, bwd_angle = a[idx[0]], a[idx[1]]
    assert idx[0] < 361 <= idx[1]
    assert 180.0 < fwd_angle < 360.0
    assert fwd_angle == pytest.approx(360.0 - bwd_angle, abs=1.0)  # α* and 360° − α*
    assert np.abs(np.diff(traj.azimuth))[idx - 1].min() > 10.0  # a snap by the paper's rule too
    assert traj.stable.all()


@pytest.mark.parametrize(("si", "so", "rigid"), [(60.0, 30.0, False), (50.0, 20.0, True)])
def test_untwisted_antialigned_state_loses_stability_at_criterion(si: float, so: float,
                                                                   rigid: bool) -> None:
    """At α = π the untwisted state ψ ≡ π exists; linearisation: stable iff λ tan λ < L / b."""
    lc = critical_overlap(si, so, rigid)
    for factor, expect_stable in ((0.97, True), (1.03, False)):
        robot = _robot(factor * lc, si, so, rigid)
        eq = solve(robot, [180.0, 0.0, -si, -so], guess=np.zeros(2))
        assert eq.converged
        np.testing.assert_allclose(eq.x, 0.0, atol=1e-12)
        assert eq.stable is expect_stable
