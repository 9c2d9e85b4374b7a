"""Dense backbones: a solved equilibrium sampled finely enough to draw.

A solve integrates the TCM on the coarsest grid its tip tolerance allows (on the paper robot 6–7
points: a straight stretch is one exact step, a curved one steps of ~5 mm; docs/mechanics.md:
Numerics), which is all the tip needs and too few points to see the curve. `dense_backbone`
integrates the equilibrium's base twist rates once more on a grid of at most `spacing` mm. The
solve itself is unchanged (and no slower); the extra pass runs only when a backbone is drawn.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ctrkin.mechanics import kernels
from ctrkin.mechanics.pointwise import Equilibrium, Problem, _integrate


@dataclass(frozen=True, eq=False)
class Backbone:
    """The backbone of one equilibrium at a given spacing.

    Attributes
    ----------
    s : ndarray, shape (K,)
        Arc length from the front plate (mm), increasing, from 0 to the innermost tube's tip.
    points : ndarray, shape (K, 3)
        Backbone points in the robot base frame (mm).
    twist : ndarray, shape (K, N)
        Material angle ψ of each tube (deg), NaN past its tip.
    tips : ndarray, shape (N,)
        Arc length of each tube's tip (mm), βi + Li, innermost first (decreasing).
    """

    s: np.ndarray
    points: np.ndarray
    twist: np.ndarray
    tips: np.ndarray

    def extent(self, tube: int) -> tuple[float, float]:
        """Where tube `tube` (0-based, innermost first) is the outermost tube: (start, end) in mm.

        Tube i shows from the next outer tube's tip to its own (the outermost from the front
        plate); that is the part a drawing of the robot shows of it.
        """
        end = max(float(self.tips[tube]), 0.0)
        start = 0.0 if tube == len(self.tips) - 1 else max(float(self.tips[tube + 1]), 0.0)
        return min(start, end), end

    def section(self, start: float, end: float) -> np.ndarray:
        """(M, 3) mm: the backbone points with s in [start, end], the ends included (interpolated)."""
        inside = (self.s > start) & (self.s < end)
        ends = [np.array([np.interp(v, self.s, self.points[:, k]) for k in range(3)]) for v in (start, end)]
        return np.vstack([ends[0], self.points[inside], ends[1]])


def dense_backbone(eq: Equilibrium, spacing: float = 0.5) -> Backbone:
    """The backbone of `eq` with points at most `spacing` mm apart.

    Parameters
    ----------
    eq : Equilibrium
        A solved equilibrium (`ctrkin.solve`, or a row of `ctrkin.follow`'s trajectory).
    spacing : float
        Largest distance along the backbone between two points (mm), > 0.

    Returns
    -------
    Backbone
        Points in the robot base frame. Curved stretches are integrated (M2, M3) from the
        equilibrium's base twist rates `eq.x` with RK4 steps of at most `spacing` (and never
        coarser than the solve's own); on straight stretches the backbone is a straight line and ψ
        linear in s (M1: u_xy = 0), so their points are interpolated exactly. The last point lies
        within the solve's tip tolerance of `eq.tip_position` (1e-3 mm by default; tested).

    Raises
    ------
    ValueError
        If `spacing` is not a positive finite number.
    """
    spacing = float(spacing)
    if not np.isfinite(spacing) or spacing <= 0:
        raise ValueError(f"spacing must be a positive number of mm, got {spacing}")
    pb = eq.problem
    arr = pb.arrays
    bounds, kap, kapy, _present, nsteps, _nsample = pb.grid
    curved = ((kap != 0.0) | (kapy != 0.0)).any(axis=1)
    solve_step = float((np.diff(bounds)[curved] / nsteps[curved]).max(initial=spacing))
    _, _, tips, grid, _ = kernels.prepare(pb.q, arr.lengths, arr.extra, arr.sec_len, arr.sec_kap,
                                          arr.sec_kapy, arr.n_sec, min(spacing, solve_step))
    # the step bounds only the RK4 steps: the breakpoints, and with them the friction stations and
    # their state (the equilibrium's, mechanics.friction), are the solve's; α as the solve saw it
    fine = Problem(arr, pb.q, pb.alpha, pb.beta, pb.tips, grid, int(grid[4].sum()), pb.stations,
                   pb.cvar, pb.state)
    s, points, psi, _uz = _integrate(fine, eq.x, record=True)[3]
    s_dense, rows = _densify(s, spacing)
    return Backbone(s=s_dense, points=_lerp(points, rows), twist=np.degrees(_lerp(psi, rows)),
                    tips=np.asarray(tips, dtype=float).copy())


def _densify(s: np.ndarray, spacing: float) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray]]:
    """New arc lengths with gaps ≤ spacing (points inserted evenly into longer gaps, which are
    straight stretches taken in one step) and, per new point, (interval index, fraction)."""
    gaps = np.diff(s)
    parts = np.maximum(1, np.ceil(gaps / spacing - 1e-9)).astype(np.int64)
    index = np.repeat(np.arange(len(gaps)), parts)
    start = np.repeat(np.cumsum(parts) - parts, parts)
    frac = (np.arange(parts.sum()) - start) / parts[index]
    index = np.r_[index, len(s) - 1]
    frac = np.r_[frac, 0.0]
    return s[index] + frac * np.r_[gaps, 0.0][index], (index, frac)


def _lerp(rec: np.ndarray, rows: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """Records at the new points: exact at a record point (even beside a NaN), linear between."""
    index, frac = rows
    nxt = np.minimum(index + 1, len(rec) - 1)
    f = frac.reshape(-1, *([1] * (rec.ndim - 1)))
    with np.errstate(invalid="ignore"):
        mixed = rec[index] + f * (rec[nxt] - rec[index])
    return np.where(f == 0.0, rec[index], mixed)
