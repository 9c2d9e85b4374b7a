"""Point-wise TCM equilibria: `solve(robot, q, guess)`.

Without a guess, Newton starts from untwisted tubes (uz(0) = 0); if that gives no stable equilibrium,
a fixed set of twisted guesses is tried and the stable equilibrium of lowest elastic energy is kept.
That is a solve with no history: the paper's "TCM" baseline. History (which of several stable
equilibria the robot is in) is the job of `follow` (mechanics.continuation), which builds on the
pieces here: `prepare` (joints to a `Problem`: grid and kernel inputs; `with_alpha`: new α at the
same β, same grid), `newton` (one damped Newton solve, a `NewtonResult`), `search` and
`twisted_guesses` (multi-start), `cold_solution` and `equilibrium` (a NewtonResult as an
`Equilibrium`). With friction (Robot.friction > 0) a configuration is solved for a friction state
(`with_state`: the stuck offsets of the contacts, mechanics.friction); without one every contact is
fresh and carries no friction torque, so `solve` with no state is the frictionless equilibrium.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import NamedTuple, TypeVar

import numpy as np

# sibling modules by full name: `from ctrkin.mechanics import ...` names the package, whose
# lazy table imports this module (an import circle: tests/test_layering.py)
import ctrkin.mechanics.cold as cold
import ctrkin.mechanics.kernels as kernels
from ctrkin.errors import ConvergenceError
from ctrkin.geometry import quat_from_tangent
from ctrkin.mechanics.arrays import RobotArrays, robot_arrays
from ctrkin.mechanics.friction import N_OUT, ContactReport, FrictionState, Stations
from ctrkin.mechanics.settings import DEFAULT_SETTINGS, SolverSettings
from ctrkin.robots.robot import Robot

_T = TypeVar("_T")


@dataclass(frozen=True, eq=False)
class Equilibrium:
    """One TCM equilibrium.

    q: (2N,) joints (deg, mm); x: (N,) base torsional curvatures uz(0) (rad/mm), the state that
    warm-starts the next solve; tip_position (3,) mm; tip_tangent (3,) unit; tip_pose (6,)
    (x, y, z, q0, qx, qy); s (K,) mm, backbone (K, 3) mm, twist (K, N) material angles ψ (deg) and
    torsion (K, N) uz (rad/mm) on the integration grid, NaN where a tube has ended (computed on
    first access);
    stability: det of the shooting Jacobian ∂uz(tips)/∂uz(0) (1 for a straight robot, 0 at a fold);
    conjugate: min over the coupled length of det H (see kernels._relative_det);
    stable: converged and both are > 0; energy: elastic energy (N·mm); problem: the prepared
    configuration it was solved on (grid and kernel inputs, `prepare`); contact: the contacts'
    forces, friction torques and the friction state after this equilibrium (mechanics.friction;
    None without friction and clearance, or if not converged).
    """

    q: np.ndarray
    x: np.ndarray
    tip_position: np.ndarray
    tip_tangent: np.ndarray
    converged: bool
    stability: float
    conjugate: float
    energy: float
    residual: float
    iterations: int
    problem: Problem = field(repr=False)
    contact: ContactReport | None = field(default=None, repr=False)

    @functools.cached_property
    def _records(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Backbone and twist along s, integrated on first use (a solve needs only the tip)."""
        return _integrate(self.problem, self.x, record=True)[3]

    @property
    def s(self) -> np.ndarray:
        """(K,) mm: arc length of the integration grid points."""
        return self._records[0]

    @property
    def backbone(self) -> np.ndarray:
        """(K, 3) mm: backbone points."""
        return self._records[1]

    @property
    def twist(self) -> np.ndarray:
        """(K, N) deg: material angle ψ of each tube (NaN past its tip)."""
        return np.degrees(self._records[2])

    @property
    def torsion(self) -> np.ndarray:
        """(K, N) rad/mm: torsional curvature uz of each tube (NaN past its tip)."""
        return self._records[3]

    @property
    def stable(self) -> bool:
        return bool(self.converged and self.stability > 0 and self.conjugate > 0)

    @property
    def tip_pose(self) -> np.ndarray:
        return np.concatenate([self.tip_position, quat_from_tangent(self.tip_tangent)])

    @property
    def friction_state(self) -> FrictionState | None:
        """The friction state after this equilibrium (to continue from with `solve(..., state=)`),
        None for a robot without contact effects or a failed solve."""
        return None if self.contact is None else self.contact.state

    @property
    def base_twist(self) -> np.ndarray:
        """(N,) deg: twist stored in each tube's transmission, ψi(0) − αi = −βi uiz(0) (M4)."""
        n = self.x.shape[0]
        if self.problem.arrays.rigid:
            return np.zeros(n)
        return np.degrees(-self.problem.beta * self.x)

    def to_dict(self) -> dict[str, object]:
        return {
            "q": self.q.tolist(), "tip_pose": self.tip_pose.tolist(),
            "tip_position_mm": self.tip_position.tolist(), "tip_tangent": self.tip_tangent.tolist(),
            "converged": self.converged, "stable": self.stable, "stability": self.stability,
            "conjugate_min": self.conjugate if math.isfinite(self.conjugate) else None,
            "energy_nmm": self.energy, "residual": self.residual, "iterations": self.iterations,
            "base_uz_rad_per_mm": self.x.tolist(), "base_twist_deg": self.base_twist.tolist(),
        }


@dataclass(frozen=True, eq=False)
class Problem:
    """A joint configuration prepared for the kernels (`prepare`): arrays of the robot, q (2N,),
    α (N,) rad, β − transmission length (N,) mm, tips (N,) mm, the grid of grid.build_grid
    (bounds, κx, κy, present, nsteps, nsample) and, with contact effects, its friction stations and
    the friction state they are solved for (`with_state`), as the kernels' cvar (K + P,): the
    stations' stuck offsets and the pairs' translations since the state
    (mechanics.contact.apply_stations)."""

    arrays: RobotArrays
    q: np.ndarray
    alpha: np.ndarray  # rad
    beta: np.ndarray   # mm, for the kernels' transmission: βi − extra transmission length
    tips: np.ndarray
    grid: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]
    n_rk4: int         # RK4 steps of one integration pass (grid[4] summed once, not per solve)
    stations: Stations | None = None
    cvar: np.ndarray | None = None
    state: FrictionState | None = None   # the state cvar was gathered from

    @property
    def length(self) -> float:
        return float(max(self.tips.max(), 1e-9))


def prepare(robot: Robot, q: np.ndarray, settings: SolverSettings, checked: bool = False,
            arr: RobotArrays | None = None) -> Problem:
    """Validate q (unless checked) and build the integration grid; arr: robot_arrays(robot)."""
    qa = np.asarray(q, dtype=float) if checked else robot.check_joints(q)
    if qa.ndim != 1:
        raise ValueError("solve takes one configuration q (2N,); use solve_many for (T, 2N)")
    if arr is None:
        arr = robot_arrays(robot)
    h = rk4_step(arr, settings)
    # α less whole turns (whole_turns_removed, in the kernel: numpy's calls on N angles cost more)
    alpha, beta, tips, grid, code = kernels.prepare(qa, arr.lengths, arr.extra, arr.sec_len,
                                                    arr.sec_kap, arr.sec_kapy, arr.n_sec, h)
    n_rk4 = int(grid[5].sum())  # the steps the stretches would take if none were straight
    if n_rk4 > settings.max_rk4_steps:
        raise ConvergenceError(
            f"the TCM grid at q = {qa.tolist()} needs {n_rk4} RK4 steps (> SolverSettings."
            f"max_rk4_steps = {settings.max_rk4_steps}): tube lengths {arr.lengths.tolist()} mm at "
            f"a step of {h:.3g} mm; check the robot's lengths (mm) and "
            "curvatures (1/mm) or raise max_rk4_steps")
    stations = None
    if arr.contact:
        stations = Stations.build(arr, grid[0], grid[3], code, tips, settings)
    # the kernels read β only as the twisting length −β of the compliant transmission (M4)
    pb = Problem(arr, qa, alpha, beta, tips, grid, int(grid[4].sum()), stations)
    return with_state(pb, None)


_KEEP = object()


def with_alpha(pb: Problem, q: np.ndarray, state: FrictionState | object | None = _KEEP) -> Problem:
    """The problem at valid joints q (2N,) whose translations β are those of pb.q: the grid, tips,
    transmission lengths and friction stations depend on β alone (kernels.prepare), so only α is
    new (a rotation step of a continuation needs no new grid). state: the friction state to solve
    for (default: pb's)."""
    out = Problem(pb.arrays, q, reduced_radians(q, pb.alpha.shape[0]), pb.beta,
                  pb.tips, pb.grid, pb.n_rk4, pb.stations, pb.cvar, pb.state)
    return out if state is _KEEP else with_state(out, state)  # type: ignore[arg-type]


def with_state(pb: Problem, state: FrictionState | None) -> Problem:
    """The problem solved for friction state `state` (None: every contact fresh, no friction
    torque): the stations' stuck offsets and each pair's relative translation since the state."""
    st = pb.stations
    if st is None:
        return pb
    cvar = st.relaxed if state is None else state.gather(st, pb.q)
    return Problem(pb.arrays, pb.q, pb.alpha, pb.beta, pb.tips, pb.grid, pb.n_rk4, st, cvar, state)


def whole_turns_removed(alpha_deg: np.ndarray) -> np.ndarray:
    """α (N,) deg less its whole turns, in (−180°, 180°], exactly: fmod is exact in floating point,
    and so is the one ±360° that follows (Sterbenz), so every α + k·360° gives the same bits and α in
    (−180°, 180°] passes unchanged. The equilibrium depends on α only through its angle, but sin and
    cos of a huge angle lose every digit (α + 1e12° did not converge, α + 1e15° was 0.01 mm off): the
    solver sees the reduced angle, the result keeps the α given."""
    r = np.fmod(alpha_deg, 360.0)
    r = np.where(r > 180.0, r - 360.0, r)
    return np.where(r <= -180.0, r + 360.0, r)


def reduced_radians(q: np.ndarray, n: int) -> np.ndarray:
    """(n,) rad: np.radians(whole_turns_removed(q[:n])), bit for bit (the same C fmod, the same
    ±360° and the same product by π/180 as numpy's radians), on Python floats: for the two or
    three angles of a continuation step numpy's calls cost 5× more (issue 26)."""
    out = []
    for a in q[:n].tolist():
        r = math.fmod(a, 360.0)
        if r > 180.0:
            r -= 360.0
        if r <= -180.0:
            r += 360.0
        out.append(math.radians(r))
    return np.array(out)


@functools.lru_cache(maxsize=64)
def rk4_step(arr: RobotArrays, settings: SolverSettings) -> float:
    """Largest RK4 step (mm) where a tube is curved: SolverSettings.step, or less where the robot
    bends or twists faster than SolverSettings.angle_step rad per step, or where the tip error
    estimate e(h) = κ*⁴ ℓc h⁴ / 120 (SolverSettings) would exceed tip_tol, if set:
    h_tol = (120 tip_tol / ℓc)^¼ / κ*, written so that no power of a tiny κ* underflows."""
    kap = arr.kappa_scale
    if kap <= 0.0 or arr.curved_length <= 0.0:
        return settings.step
    if settings.tip_tol is None:
        return min(settings.step, settings.angle_step / kap)
    h_tol = (120.0 * settings.tip_tol / arr.curved_length) ** 0.25 / kap
    return min(settings.step, settings.angle_step / kap, h_tol)


_NO_BODY = np.full(7, np.nan)
_NO_BODY.setflags(write=False)


class NewtonResult(NamedTuple):
    """One damped Newton solve (kernels.newton). x (N,) rad/mm: the root (the start where the
    numerics broke down); converged: residual below tol and the sanity checks of kernels.sane passed;
    iterations; residual |r|∞ (rad/mm); det_j: det ∂r/∂x, the stability measure; det_h: min det H,
    the conjugate-point test; body (7,): tip (3,) mm, unit tangent (3,), elastic energy (N·mm) from
    the final pass, NaN if not converged; stations (K, 8): the friction stations' outputs at x
    (contact.station), None without contact effects."""

    x: np.ndarray
    converged: bool
    iterations: int
    residual: float
    det_j: float
    det_h: float
    body: np.ndarray
    stations: np.ndarray | None = None

    @property
    def modes(self) -> bytes:
        """The stick/slip pattern of the friction elements (empty without friction)."""
        return b"" if self.stations is None else self.stations[:, 3].tobytes()

    @property
    def stable(self) -> bool:
        return bool(self.converged and self.det_j > 0 and self.det_h > 0)

    @property
    def energy(self) -> float:
        return float(self.body[6])

    @classmethod
    def failed(cls, x: np.ndarray, det_j: float = math.nan) -> NewtonResult:
        """Not converged at x (NaN pose); det_j: the last stability measure known, if any."""
        return cls(x, False, 0, math.inf, det_j, math.nan, _NO_BODY)


def newton(pb: Problem, x0: np.ndarray, settings: SolverSettings, work: list[int] | None = None
           ) -> NewtonResult:
    """Damped Newton from x0 (N,) rad/mm (kernels.newton); work, if given, gets the RK4 steps spent
    added to work[0]."""
    a = pb.arrays
    x0 = np.asarray(x0, dtype=float)
    x = np.empty(x0.shape[0])
    body = np.empty(7)
    ct = contact_arrays(pb)
    try:  # converged: |r| < tol and kernels.sane (a finite root and body), checked in the kernel
        conv, it, rn, det_j, det_h, shoots = kernels.newton(
            x0, pb.alpha, pb.beta, pb.tips, a.rigid, a.k, a.gj, *pb.grid,
            settings.tol, settings.max_iter, settings.max_step, x, body, *ct)
    except (np.linalg.LinAlgError, ZeroDivisionError, OverflowError, FloatingPointError):
        return NewtonResult.failed(x0.copy())  # numerics broke down
    if work is not None:
        work[0] += shoots * pb.n_rk4
    return NewtonResult(x, conv, it, rn, det_j, det_h, body if conv else _NO_BODY, ct[4])


_NO_CONTACT = (None, None, None, None, None)


def contact_arrays(pb: Problem) -> tuple[np.ndarray | None, ...]:
    """The kernels' contact arrays of pb (cst, cpr, cvar, cprm, cout:
    mechanics.contact.apply_stations), with a fresh output array; five None without contact
    effects."""
    st = pb.stations
    if st is None or pb.cvar is None:
        return _NO_CONTACT
    return st.table, st.pairs, pb.cvar, st.prm, np.empty((st.count, N_OUT))


def _integrate(pb: Problem, x: np.ndarray, record: bool
               ) -> tuple[np.ndarray, np.ndarray, float,
                          tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
    """Tip position, tangent, energy and (if record) the grid records at base torsion x."""
    a = pb.arrays
    n = x.shape[0]
    if record:
        nrec = 1 + pb.n_rk4
        recs = (np.empty(nrec), np.empty((nrec, 3)), np.empty((nrec, n)), np.empty((nrec, n)))
    else:
        recs = (np.empty(1), np.empty((1, 3)), np.empty((1, n)), np.empty((1, n)))
    body = np.empty(7)
    kernels.integrate_full(x, pb.alpha, pb.beta, pb.tips, a.rigid, a.k, a.gj, *pb.grid, record,
                           *recs, body, *contact_arrays(pb))
    return body[:3], body[3:6], float(body[6]), recs


def equilibrium(pb: Problem, sol: NewtonResult, state: FrictionState | None = None) -> Equilibrium:
    """The Equilibrium of a Newton result on problem pb; state: the friction state after it, if
    the caller has it already (friction_after)."""
    x = sol.x
    if sol.converged:  # the final Newton pass integrated the backbone and energy (kernels.sane passed)
        tip, tan, energy = sol.body[:3], sol.body[3:6], sol.energy
    else:
        try:
            energy = _integrate(pb, x, record=False)[2]
        except (ZeroDivisionError, OverflowError, FloatingPointError):
            energy = math.nan
        tip, tan = np.full(3, np.nan), np.full(3, np.nan)
    contact = None
    if sol.converged and pb.stations is not None and sol.stations is not None:
        contact = ContactReport(pb.stations, sol.stations, state or friction_after(pb, sol))
    return Equilibrium(q=pb.q, x=x, tip_position=tip, tip_tangent=tan, converged=sol.converged,
                       stability=sol.det_j, conjugate=sol.det_h, energy=energy,
                       residual=sol.residual, iterations=sol.iterations, problem=pb, contact=contact)


def friction_after(pb: Problem, sol: NewtonResult) -> FrictionState:
    """The friction state after a converged solve of pb (FrictionState.after)."""
    assert pb.stations is not None and sol.stations is not None
    return FrictionState.after(pb.stations, sol.stations, pb.q,
                               max(pb.alpha.shape[0] - 1, 0) * pb.arrays.slots)


def twisted_guesses(pb: Problem, around: np.ndarray) -> list[np.ndarray]:
    """Guesses with relative twist between tube i and the outermost tube, zero net torque.

    Rate scale π / (robot length): the twist needed to turn one tube half a turn against another.
    """
    gj = pb.arrays.gj
    n = gj.shape[0]
    u0 = math.pi / pb.length
    out = []
    for i in range(n - 1):
        d = np.zeros(n)
        d[i] = 1.0 / gj[i]
        d[-1] = -1.0 / gj[-1]
        d /= 1.0 / gj[i] + 1.0 / gj[-1]  # unit relative rate x_i − x_N
        for m in (0.5, -0.5, 1.0, -1.0, 1.5, -1.5, 2.0, -2.0, 3.0, -3.0):
            out.append(around + m * u0 * d)
    return out


def search(pb: Problem, guesses: list[np.ndarray], settings: SolverSettings,
           work: list[int] | None = None) -> list[NewtonResult]:
    """Distinct converged solutions from several guesses, tried in order until the RK4 steps spent
    exceed SolverSettings.max_search_steps (a bound on the time of a multi-start search); work: a
    counter shared with the caller (work[0], RK4 steps spent so far)."""
    found: list[NewtonResult] = []
    work = [0] if work is None else work
    for g in guesses:
        if work[0] > settings.max_search_steps:
            break
        sol = newton(pb, g, settings, work)
        if not sol.converged:
            continue
        if all(np.abs(sol.x - f.x).max() * pb.length > 1e-6 for f in found):
            found.append(sol)
    return found


def solve(robot: Robot, q: np.ndarray, guess: Equilibrium | np.ndarray | None = None,
          settings: SolverSettings = DEFAULT_SETTINGS, strict: bool = False,
          state: FrictionState | None = None) -> Equilibrium:
    """Equilibrium of the TCM at joints q (2N,) = (α deg, β mm).

    guess: an Equilibrium the robot was in (the previous step of a loop), or a raw Newton start x
    (N,) rad/mm. Newton starts from it and stays on that branch if it can. From an Equilibrium, a
    start that gives no stable equilibrium means the branch has ended at a fold: the robot snapped,
    and, as in `follow`, the result is the stable equilibrium nearest the guess (`recover`), so a
    loop `prev = solve(robot, q, guess=prev)` stays converged through a snap. A raw x is a plain
    Newton start (the result may be unstable: that is how an unstable branch is reached on purpose).
    Without a guess, the lowest-energy stable equilibrium found from untwisted and twisted starts is
    returned.
    state: the friction state to solve for (an earlier equilibrium's `friction_state`; one step of
    the rate-independent friction law from there to q, docs/mechanics.md: Friction and clearance);
    None: every contact fresh, so a robot with friction gives its frictionless equilibrium (there is
    no history to carry). The result's `friction_state` continues the path.
    Invalid joints raise JointError. A failed solve returns converged=False with a NaN pose, or
    raises ConvergenceError if strict.
    """
    eq = _cold(robot, q, settings) if guess is None and state is None else None
    if eq is None:
        pb = with_state(prepare(robot, q, settings), state)
        eq = solve_prepared(pb, guess, settings)
    if strict and not eq.converged:
        raise ConvergenceError(f"no TCM equilibrium found at q = {pb.q.tolist()} "
                               f"(residual {eq.residual:.3g} rad/mm)")
    return eq


def _cold(robot: Robot, q: np.ndarray, settings: SolverSettings) -> Equilibrium | None:
    """A cold solve by cold.cold_start (prepare and the first Newton solve in one compiled call),
    for q a float (2N,) array on a robot without contact effects: what solve_prepared(prepare(q),
    None) gives (tested), or None where the Python path is to run (another q, invalid joints or
    too fine a grid, whose errors it raises, or numerics that broke down, which it reports)."""
    arr = robot_arrays(robot)
    n = arr.lengths.shape[0]
    if type(q) is not np.ndarray or q.dtype != np.float64 or q.shape != (2 * n,) or arr.contact:
        return None
    x, body = np.empty(n), np.empty(7)
    try:
        status, alpha, beta, tips, grid, n_rk4, conv, it, rn, det_j, det_h, passes = cold.cold_start(
            q, robot._lengths, arr.lengths, arr.extra, arr.sec_len, arr.sec_kap, arr.sec_kapy,
            arr.n_sec, rk4_step(arr, settings), settings.max_rk4_steps, arr.rigid, arr.k, arr.gj,
            settings.tol, settings.max_iter, settings.max_step, x, body)
    except (np.linalg.LinAlgError, ZeroDivisionError, OverflowError, FloatingPointError):
        return None
    if status != cold.VALID:
        return None
    pb = made(Problem, arrays=arr, q=q, alpha=alpha, beta=beta, tips=tips, grid=grid, n_rk4=n_rk4,
              stations=None, cvar=None, state=None)
    first = NewtonResult(x, conv, it, rn, det_j, det_h, body if conv else _NO_BODY)
    if not first.stable:  # cold_solution's search from this first solve, or (one tube) the solve
        return equilibrium(pb, first if n == 1 else cold_solution(pb, settings, [passes * n_rk4],
                                                                  first))
    return made(Equilibrium, q=q, x=x, tip_position=body[:3], tip_tangent=body[3:6],
                converged=conv, stability=det_j, conjugate=det_h, energy=first.energy,
                residual=rn, iterations=it, problem=pb, contact=None)


def made(cls: type[_T], **fields: object) -> _T:
    """An instance of the frozen dataclass cls with these fields (every one of them), made without
    its __init__: a frozen __init__ sets each field through object.__setattr__, and a warm step's
    Problem and Equilibrium took ~3 µs of the step that way (issue 26). The instance is the same:
    its __dict__ holds every field."""
    obj = object.__new__(cls)
    obj.__dict__.update(fields)
    return obj


def solve_prepared(pb: Problem, guess: Equilibrium | np.ndarray | None,
                   settings: SolverSettings) -> Equilibrium:
    """`solve` on a prepared problem (joints already checked)."""
    n = pb.alpha.shape[0]
    if guess is not None:
        x0 = guess.x if isinstance(guess, Equilibrium) else np.asarray(guess, float)
        if x0.shape != (n,):
            raise ValueError(f"guess must have shape ({n},) (uz(0) per tube, rad/mm)")
        sol = newton(pb, x0, settings)
        if isinstance(guess, Equilibrium) and not sol.stable:
            sol = recover(pb, x0, settings)  # the branch of the guess ended: a snap (issue 24)
        return equilibrium(pb, sol)
    return equilibrium(pb, cold_solution(pb, settings))


def recover(pb: Problem, x: np.ndarray, settings: SolverSettings, work: list[int] | None = None
            ) -> NewtonResult:
    """Where the robot goes when its branch, last at state x (N,) rad/mm, has no stable equilibrium
    at pb: the stable equilibrium nearest x in twist (the basin the released twist falls into),
    found from x and twisted starts around x and around zero; the cold solution if none is stable.
    The snap of a continuation (`follow`) and of `solve` from a previous equilibrium."""
    work = [0] if work is None else work
    guesses = [x, *twisted_guesses(pb, x), *twisted_guesses(pb, np.zeros_like(x))]
    found = [c for c in search(pb, guesses, settings, work) if c.stable]
    if found:
        return min(found, key=lambda c: twist_distance(c.x, x, pb.arrays.lengths))
    return cold_solution(pb, settings, work)


def twist_distance(a: np.ndarray, b: np.ndarray, lengths: np.ndarray) -> float:
    """Largest change of twist (rad) a change of base torsion a − b (rad/mm) makes over a tube.
    A loop on Python floats: N ≤ a handful, and numpy's reductions (or its scalars) cost 3× more
    on so few (every step)."""
    out = 0.0
    for u, v, w in zip(a.tolist(), b.tolist(), lengths.tolist(), strict=True):
        out = max(out, abs((u - v) * w))
    return out


def cold_solution(pb: Problem, settings: SolverSettings, work: list[int] | None = None,
                  first: NewtonResult | None = None) -> NewtonResult:
    """Newton from untwisted tubes; if that is not stable, the stable solution of least energy
    among twisted starts (else the least-energy converged one, else the first attempt). first:
    that Newton solve, made already (its work counted in `work`)."""
    n = pb.alpha.shape[0]
    work = [0] if work is None else work
    if first is None:
        first = newton(pb, np.zeros(n), settings, work)
    if first.stable or n == 1:
        return first
    cands = search(pb, [first.x, *twisted_guesses(pb, np.zeros(n))], settings, work)
    pool = [c for c in cands if c.stable] or cands
    if not pool:
        return first
    return min(pool, key=lambda c: c.energy)  # the energy of the final Newton pass


def solve_many(robot: Robot, Q: np.ndarray, settings: SolverSettings = DEFAULT_SETTINGS
               ) -> list[Equilibrium]:
    """Independent point-wise solves (no history) of Q (T, 2N); rows are validated first."""
    Qa = robot.check_joints(np.atleast_2d(Q))
    return [solve_prepared(prepare(robot, qr, settings, checked=True), None, settings)
            for qr in Qa]


def tip_poses(eqs: list[Equilibrium]) -> np.ndarray:
    """(T, 6) tip poses of a list of equilibria."""
    return np.array([e.tip_pose for e in eqs]).reshape(len(eqs), 6)
