"""Friction between the tubes (issue 20, goal 1; docs/mechanics.md: Friction and clearance).

The proofs: μ = 0 is today's TCM; an analytic stick/slip case and an independent integration of a
fully overlapped curved pair; loop width and snap delay grow with μ; the lag follows the direction
of motion; a reversal draws a minor loop inside the major one; the state carried by `solve`.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from ctrkin import Robot, SolverSettings, Tube, follow, paper_robot, solve
from ctrkin.acquisition.trajectories import rotation_sweep
from ctrkin.mechanics import kernels
from ctrkin.mechanics.friction import SLIP, STICK, FrictionState
from ctrkin.mechanics.pointwise import contact_arrays, prepare, with_state
from ctrkin.robots import timclab_robot
from tests.mechanics.reference_friction import reference_pair

PAPER = paper_robot()
GOLDEN = Path(__file__).parent / "data" / "tcm_94a32c9.json"
NO_DIST = SolverSettings(distributed_friction=False)
# elements ten times stiffer than the default (ε 0.2 µm): the analytic tests compare with the
# rigid-plastic limit, which the solver reaches within ε / r_c
STIFF = SolverSettings(stick_mm=2e-4)
STIFF_NO_DIST = SolverSettings(stick_mm=2e-4, distributed_friction=False)


def with_friction(mu: float, robot: Robot = PAPER, **kw: float) -> Robot:
    return dataclasses.replace(robot, friction=mu, **kw)


def loop(traj, half: int = 361) -> np.ndarray:
    """|T(L) forward − T(L) backward| (deg) at each inner angle of a 0 → 360 → 0 sweep."""
    return np.abs(traj.azimuth[:half] - traj.azimuth[half - 1:][::-1])


def test_zero_friction_is_the_tcm_of_main() -> None:
    """With μ = 0 (and no clearance) the TCM is the one of main 94a32c9: tips to 1e-9 mm on a
    snapping sweep and at random points of the paper and TIMClab robots (golden values recorded
    with that commit's code)."""
    gold = json.loads(GOLDEN.read_text())
    tr = follow(PAPER, rotation_sweep(2, 20.0, step_deg=10.0))
    np.testing.assert_allclose(tr.tip_positions, gold["paper_sweep20_step10"], atol=1e-9, rtol=0)
    assert np.nonzero(tr.snaps)[0].tolist() == gold["paper_sweep20_snaps"]
    for q, tip in zip(gold["paper_points_q"], gold["paper_points"], strict=True):
        np.testing.assert_allclose(solve(PAPER, q).tip_position, tip, atol=1e-9, rtol=0)
    for q, tip in zip(gold["timclab_q"], gold["timclab"], strict=True):
        np.testing.assert_allclose(solve(timclab_robot(), q).tip_position, tip, atol=1e-9, rtol=0)


def test_vanishing_friction_through_the_friction_path_is_the_tcm() -> None:
    """The friction elements themselves (stations, state, stick/slip) with μ → 0 leave the TCM:
    a snapping sweep with μ = 1e-12 is the frictionless one to 1e-9 mm, snaps included."""
    Q = rotation_sweep(2, 20.0, step_deg=2.0)
    a, b = follow(PAPER, Q), follow(with_friction(1e-12), Q)
    assert b.equilibria[10].contact is not None
    np.testing.assert_allclose(b.tip_positions, a.tip_positions, atol=1e-9, rtol=0)
    assert (a.snaps == b.snaps).all()


def _straight_outer_pair(mu: float, length: float = 30.0, kap: float = 1 / 25, b: float = 40.0
                         ) -> Robot:
    inner = Tube.from_sections(0.4, 0.2, [(length, kap)])
    outer = Tube.from_sections(0.635, 0.48, [(length, 0.0)])
    return Robot((inner, outer), transmission_length=(b, b), friction=mu)


def _play(x: np.ndarray, w: float) -> np.ndarray:
    """Play operator of half width w started centred at 0."""
    out = np.empty_like(x)
    y = 0.0
    for t, v in enumerate(x):
        y = min(max(y, v - w), v + w)
        out[t] = y
    return out


def test_analytic_stick_slip_of_a_straight_outer_pair() -> None:
    """A curved inner tube in a straight outer one, flush, fully overlapped: no elastic torsion
    coupling (u ∥ v1), contacts at s = 0 and s = L with the same bound T = μ r N (N = 2|ΔM|/ℓ,
    |ΔM| = k1 k2 κ / (k1 + k2)). Transmission springs b c and segment spring L c
    (c = 1/GJ1 + 1/GJ2) in series with the two elements make, in the rigid-plastic limit, the
    relative twist at the tip a play operator of the base rotation with half width
    w = c T (2b + L): stuck until the transmission carries both bounds, then lagging by w, and
    after every reversal (minor loops included) stuck for 2w. The solver follows it within the
    elements' elastic range (two elements, ε / r_c = 0.9e-3 rad each at ε = 0.2 µm, STIFF)."""
    length, kap, b, mu = 30.0, 1 / 25, 40.0, 0.2
    robot = _straight_outer_pair(mu, length, kap, b)
    inner, outer = robot.tubes
    k1, k2 = inner.bending_stiffness, outer.bending_stiffness
    dm = k1 * k2 / (k1 + k2) * kap
    gap = 0.5 * (outer.id - inner.od)
    ell = np.clip(np.sqrt(12 * gap * (k1 * k2 / (k1 + k2)) / dm), inner.od, length)
    bound = mu * 0.25 * (inner.od + outer.id) * 2 * dm / ell
    w = (1 / inner.torsional_stiffness + 1 / outer.torsional_stiffness) * bound * (2 * b + length)
    a = np.r_[np.arange(0, 91, 1.0), np.arange(89, -91, -1.0), np.arange(-89, 1, 1.0),
              np.arange(-1, -31, -1.0), np.arange(-29, 61, 1.0)]       # a minor loop at the end
    tr = follow(robot, np.c_[a, np.zeros((len(a), 3))], settings=STIFF_NO_DIST)
    phi_tip = np.array([np.radians(e.twist[-1, 0] - e.twist[-1, 1]) for e in tr.equilibria])
    expected = _play(np.radians(a), w)
    assert np.degrees(w) > 8.0                               # a loop 17° wide: a real test
    np.testing.assert_allclose(phi_tip, expected, atol=2.5e-3, rtol=0)  # 2 ε_t + RK4
    full = tr.equilibria[90].contact
    assert full is not None and (full.mode == SLIP).all()
    np.testing.assert_allclose(full.bound, bound, rtol=1e-9)
    np.testing.assert_allclose(np.abs(full.torque), bound, rtol=1e-9)


def _curved_pair(mu: float, length: float = 25.0) -> Robot:
    inner = Tube.from_sections(0.4, 0.2, [(length, 1 / 27)])
    outer = Tube.from_sections(0.635, 0.48, [(length, 1 / 24)])
    return Robot((inner, outer), transmission_length=(60.0, 40.0), friction=mu)


@pytest.mark.parametrize("shift", [-0.3, -2e-4, 5e-4, 0.2])   # rad: slip −, stick, stick, slip +
def test_curved_pair_matches_an_independent_integration(shift: float) -> None:
    """A fully overlapped pair of constant curvature (both tubes curved over their whole length,
    flush, at the plate) with stuck offsets that make the elements slip or stick: the same
    equilibrium as scipy DOP853 + root with the friction law written out (reference_friction.py),
    at a tight tolerance."""
    robot = _curved_pair(0.3)
    settings = SolverSettings(tip_tol=1e-7, distributed_friction=False)
    q = np.array([140.0, 0.0, 0.0, 0.0])
    relaxed = solve(robot, q, settings=settings)
    assert relaxed.contact is not None
    state = relaxed.friction_state
    assert state is not None
    theta = state.theta.copy()
    st = relaxed.problem.stations
    assert st is not None and st.count == 2
    theta[st.slot] += shift
    eq = solve(robot, q, guess=relaxed, settings=settings, state=FrictionState(theta, state.q))
    assert eq.converged and eq.contact is not None
    eps = settings.stick_mm / (0.25 * (robot.tubes[0].od + robot.tubes[1].id))   # rad, ε / r_c
    mode = STICK if abs(shift) < eps else SLIP
    assert (eq.contact.mode == mode).all()
    tip, x = reference_pair(robot, q[:2], theta[st.slot], eq.x, eps)
    np.testing.assert_allclose(eq.x, x, rtol=0, atol=1e-9)
    np.testing.assert_allclose(eq.tip_position, tip, rtol=0, atol=1e-6)
    if mode == SLIP:                                # the bound moved the tip, by tens of µm
        assert np.linalg.norm(eq.tip_position - relaxed.tip_position) > 0.02


def test_jacobian_with_friction_matches_finite_differences() -> None:
    """The shooting Jacobian with friction elements (stick, slip, distributed contact, an axial
    slip, the clearance tilt) is the exact derivative of the residual."""
    robot = with_friction(0.3, clearance=1.0)
    Q = rotation_sweep(2, 16.0)
    prev = follow(robot, Q[:120]).equilibria[-1]
    # (at the state's own joints a slipping element sits on its yield surface, a kink: step off it)
    for dq, expect in ((np.array([1.0, 0, 0, 0]), SLIP), (np.array([-0.01, 0, 0, 0]), STICK),
                       (np.array([0, 0, -0.3, 0]), SLIP)):
        pb = with_state(prepare(robot, Q[119] + dq, SolverSettings()), prev.friction_state)
        a = pb.arrays

        def res(x: np.ndarray, var: bool = False, pb=pb, a=a) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            r, jac, ct = np.empty(2), np.empty((2, 2)), contact_arrays(pb)
            kernels.shoot(x, pb.alpha, pb.beta, pb.tips, a.rigid, a.k, a.gj, *pb.grid, r, jac, var, *ct)
            return r, jac, ct[4]

        x = prev.x
        _, jac, out = res(x, True)
        assert (out[1:, 3] == expect).any()
        h = 1e-8
        fd = np.column_stack([(res(x + h * e)[0] - res(x - h * e)[0]) / (2 * h) for e in np.eye(2)])
        np.testing.assert_allclose(jac, fd, rtol=1e-6, atol=1e-9 * np.abs(jac).max())


def test_loop_width_and_snap_delay_grow_with_friction() -> None:
    """Paper robot: the T(L) loop at d = 12 mm (no snap at any μ) and the delay of the forward
    snap at d = 20 mm past the frictionless fold grow strictly with μ."""
    widths, delays = [], []
    ref = np.nonzero(follow(PAPER, rotation_sweep(2, 20.0)).snaps)[0][0]
    for mu in (0.0, 0.05, 0.1, 0.2, 0.3):
        robot = with_friction(mu)
        tr = follow(robot, rotation_sweep(2, 12.0, step_deg=2.0))
        assert tr.n_snaps == 0
        widths.append(loop(tr, 181).max())
        delays.append(np.nonzero(follow(robot, rotation_sweep(2, 20.0)).snaps)[0][0] - ref)
    assert widths[0] < 1e-6 and delays[0] == 0
    assert np.all(np.diff(widths) > 1.0), widths      # deg of T(L)
    assert np.all(np.diff(delays) >= 2), delays       # deg of inner rotation


def test_lag_follows_the_direction_of_motion() -> None:
    """Turning up, the inner tube's tip trails the frictionless one (its material angle there is
    smaller), turning down it trails from above; the transmission's extra wind-up opposes the
    motion."""
    Q = rotation_sweep(2, 12.0, step_deg=2.0)
    free, fric = follow(PAPER, Q), follow(with_friction(0.2), Q)
    tip_angle = [np.array([e.twist[-1, 0] for e in tr.equilibria]) for tr in (free, fric)]
    wind = [np.array([e.base_twist[0] for e in tr.equilibria]) for tr in (free, fric)]
    lag, extra = tip_angle[1] - tip_angle[0], wind[1] - wind[0]
    up = np.arange(20, 170)                     # well into each half (the start is relaxed)
    down = np.arange(200, 350)
    assert (lag[up] < -1.0).all() and (lag[down] > 1.0).all()        # deg
    assert (extra[up] < 0).all() and (extra[down] > 0).all()


def test_reversal_draws_a_minor_loop_inside_the_major_one() -> None:
    """d = 12 mm: the major loop 0 → 360 → 0°; a reversal at 200° back to 150° and up again to
    360°: the minor branch lies between the major ones, and past the reversal point the path
    rejoins the major forward branch (return-point memory of the play elements)."""
    step = 2.0
    Q = rotation_sweep(2, 12.0, step_deg=step)
    robot = with_friction(0.2)
    major = follow(robot, Q)
    half = len(Q) // 2 + 1
    up, down = major.azimuth[:half], major.azimuth[half - 1:][::-1]
    a = np.r_[np.arange(0, 200 + step, step), np.arange(200 - step, 150 - step, -step),
              np.arange(150 + step, 360 + step, step)]
    minor = follow(robot, np.c_[a, np.zeros_like(a), np.full_like(a, Q[0, 2]), np.full_like(a, Q[0, 3])])
    idx = (a / step).astype(int)
    back = np.arange(101, 101 + 25)             # the reversed stretch 198 → 150
    lo, hi = np.minimum(up, down)[idx[back]], np.maximum(up, down)[idx[back]]
    assert ((minor.azimuth[back] >= lo - 0.2) & (minor.azimuth[back] <= hi + 0.2)).all()
    assert (hi - lo)[5:].min() > 5.0            # a real loop to be inside of
    rejoin = np.nonzero(a[back[-1]:] > 230)[0] + back[-1]
    np.testing.assert_allclose(minor.azimuth[rejoin], up[idx[rejoin]], atol=0.3)


def test_solve_with_a_state_continues_a_path() -> None:
    """solve(q, state=previous.friction_state) step by step is follow on a smooth stretch; without
    a state a robot with friction gives its frictionless equilibrium."""
    robot = with_friction(0.2)
    Q = rotation_sweep(2, 12.0, step_deg=2.0)[:60]
    tr = follow(robot, Q)
    eq = solve(robot, Q[0])
    for q in Q[1:]:
        eq = solve(robot, q, guess=eq, state=eq.friction_state)
    np.testing.assert_allclose(eq.tip_position, tr.tip_positions[-1], atol=1e-6)
    np.testing.assert_allclose(solve(robot, Q[-1]).tip_position, solve(PAPER, Q[-1]).tip_position,
                               atol=1e-9)
    assert np.linalg.norm(eq.tip_position - solve(PAPER, Q[-1]).tip_position) > 0.1


def test_translation_releases_the_torsional_stick() -> None:
    """Coulomb's law for combined sliding: a translation takes the friction axially, so the
    transmission wound up by a rotation unwinds when the tubes then slide (Ha et al. 2019). The
    law is isotropic at the contact surface: rotating and translating at once, the torsional share
    of the bound is r Δφ / √((r Δφ)² + Δd²) (with stiff elements, STIFF: the elastic part they
    carry in is then small against a step's slip)."""
    robot = with_friction(0.3)
    Q = rotation_sweep(2, 12.0, step_deg=2.0)[:60]
    wound = follow(robot, Q, settings=STIFF).equilibria[-1]
    q = Q[-1].copy()
    path = np.array([q + np.array([0, 0, -0.5 * k, 0]) for k in range(1, 5)])
    slid = follow(robot, path, start=wound, settings=STIFF).equilibria[-1]
    free = solve(PAPER, path[-1])
    assert abs(wound.base_twist[0]) > 5 * abs(slid.base_twist[0] - free.base_twist[0])
    # one step turning the inner tube by Δα while it slides by Δd: the slipping elements' torque
    # is the bound times the torsional share of the slip at the surface
    st = wound.problem.stations
    assert st is not None
    rc = 0.25 * (robot.tubes[0].od + robot.tubes[1].id)
    def rel(eq: object, at: np.ndarray) -> np.ndarray:   # ψ1 − ψ2 (rad) at arc lengths `at`
        return np.radians([np.interp(a, eq.s, eq.twist[:, 0] - eq.twist[:, 1]) for a in at])

    for da, dd in ((2.0, 0.05), (2.0, 0.01)):
        step = follow(robot, (q + np.array([da, 0, -dd, 0]))[None, :], start=wound,
                      settings=STIFF).equilibria[-1]
        rep = step.contact
        assert rep is not None
        slip = (rep.mode == SLIP) & (rep.bound > 0)
        assert slip.sum() >= 2
        # the elastic part a = ±1 the element carried in is small against the step's slip
        eps_t = STIFF.stick_mm / rc
        dphi = rel(step, rep.s[slip]) - rel(wound, rep.s[slip])
        share = np.abs(rc * dphi + np.sign(dphi) * rc * eps_t) / np.hypot(rc * dphi, dd)
        assert (share < 0.9).all()
        np.testing.assert_allclose(np.abs(rep.torque[slip]), share * rep.bound[slip], rtol=0.15)


def test_a_tube_crossing_180_degrees_keeps_its_stuck_twist() -> None:
    """The solver removes whole turns of α (α in (−180°, 180°]), so the relative angle of a pair
    jumps by 360° where the inner tube crosses 180°; the friction element must see only the slip.
    Turning both tubes by the same angle turns the whole robot about z, so the path with the inner
    tube crossing 180° equals, turned by 180°, the same path 180° lower, which crosses nothing."""
    rough = with_friction(0.2)
    a = np.arange(120.0, 241.0, 2.0)
    Q = np.c_[a, 0 * a, np.full(len(a), -8.0), 0 * a]
    crossing = follow(rough, Q).tip_poses[:, :3]
    shifted = follow(rough, Q - [180.0, 180.0, 0.0, 0.0]).tip_poses[:, :3]
    turned = shifted * [-1.0, -1.0, 1.0]                       # Rz(180°)
    np.testing.assert_allclose(crossing, turned, atol=1e-6)
    assert np.abs(crossing - follow(PAPER, Q).tip_poses[:, :3]).max() > 0.05   # friction acts
