"""The paper's data acquisition protocols as joint plans (Sec. II.B, III.A, IV.A of the paper).

All joints follow the fixed convention q = (α1..αN deg, β1..βN mm), βi ≤ 0. A protocol is written
for the paper's two-tube robot: tube 1 (inner) and tube N (outer) move; on a robot with more tubes
the middle tubes move with the outer tube. d = βN − β1 ≥ 0 is the relative translation (how far the
inner tube's base is behind the outer tube's): on the paper robot the curved sections overlap for
d > 5.5 mm and fully at d = 20 mm (d ≤ 20.5 mm keeps the inner tip in front of the outer tip).
The millimetres below are the paper robot's; on another robot each protocol's relative and outer
translations are carried to the same places of its geometry (its onset and full curved overlap, its
reach and outer curved length: ctrkin.acquisition.ranges), the paper robot keeping the paper's.

Protocols (each returns a `Plan`; every random draw comes from `seed`):
  paper          training data, Sec. III.A: per relative translation level, the outer tube steps
                 through 360° in 10° increments; at each outer angle the inner tube turns 0 → 360 → 0°
                 in 1° increments (721 samples, one sequence). The outer translation cycles over
                 βN ∈ {0, −2.5, −5} mm across the outer angles, so the training data also covers the
                 outer-tube translation range of the `arbitrary` path. Its size per scale
                 (PAPER_SIZES; `ctrkin collect --scale` and `ctrkin reproduce --scale` train on the
                 same): full, the paper's, 8 levels (d = 4, 8, 10, 12, 14, 16, 18, 20 mm, denser
                 where the curved overlap makes the robot nonlinear) × 36 angles × 721 = 207,648
                 samples (the paper: 212,527); quick, d = 4, 10, 15, 20 mm × 18 angles (20° steps)
                 × 721 = 51,912; tiny, d = 4, 20 mm × 4 angles (90° steps) × 721 = 5,768. Each
                 level is one run (parallel).
  sweeps         Fig. 2b, 6, 10a: the outer tube fixed at α = 0, βN = 0; the inner tube turns
                 0 → 360 → 0° at d = 4, 8, 12, 16, 20 mm (the paper's β12 = 15..55), one run.
  snap-turns     ctrkin's test of snap prediction off the protocol grid: full inner turns
                 0 → 360 → 0° at full curved overlap (d = 20 mm) at outer angles and translations the
                 paper protocol never records (αN = 10, 70, …, 310°, βN alternating −1.25 / −3.75 mm),
                 each its own run from rest.
  random-points  Fig. 10b: N random configurations (α uniform in [0, 360)°, d in [4, 20] mm, βN in
                 [−5, 0] mm), each reached by a joint-space move from the previous one; one sequence
                 per move, the target its last sample (is_target).
  arbitrary      Fig. 10c: the paper's outer tube retracts 5 mm while turning 0 → 360° and the inner
                 tube extends 10 mm while turning 360 → 0°, simultaneously. In our convention:
                 βN 0 → −5 mm, β1 −20 → −10 mm (d 20 → 5 mm), αN 0 → 360°, α1 360 → 0°, 361 samples.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ctrkin.acquisition.excitation import excitation
from ctrkin.acquisition.plan import Plan, Run, Segment, move, transition
from ctrkin.acquisition.protocol_base import (  # noqa: F401  (re-exported: the protocols' names)
    PAPER_FULL_LEVELS_MM,
    PAPER_OUTER_BETAS_MM,
    PAPER_SIZES,
    RANDOM_D_RANGE_MM,
    RANDOM_OUTER_BETA_RANGE_MM,
    SCALES,
    PaperSize,
    Scale,
    config,
)
from ctrkin.acquisition.protocol_base import check_levels as _check_levels
from ctrkin.acquisition.protocol_base import check_scale as _check_scale
from ctrkin.acquisition.ranges import ProtocolRanges
from ctrkin.acquisition.trajectories import PAPER_LEVELS_MM
from ctrkin.robots.robot import Robot

ARBITRARY_START = {"alpha_inner": 360.0, "alpha_outer": 0.0, "beta_inner": -20.0, "beta_outer": 0.0}
ARBITRARY_END = {"alpha_inner": 0.0, "alpha_outer": 360.0, "beta_inner": -10.0, "beta_outer": -5.0}


def inner_turn(n_tubes: int, alpha_outer: float, beta_outer: float, d: float,
               step_deg: float = 1.0) -> np.ndarray:
    """The inner tube turning 0 → 360 → 0° in `step_deg` increments, the others fixed.

    Returns
    -------
    ndarray, shape (2·360/step + 1, 2N)
        Joints (deg, mm).
    """
    k = round(360.0 / step_deg)
    fwd = step_deg * np.arange(k + 1)
    a1 = np.r_[fwd, fwd[-2::-1]]
    return config(n_tubes, a1, alpha_outer, beta_outer, d)


def paper(robot: Robot, scale: Scale = "full", seed: int = 0,
          levels: tuple[float, ...] | None = None, step_deg: float = 1.0,
          outer_step_deg: float | None = None) -> Plan:
    """The paper's training protocol (Sec. III.A): one run per level, one sequence per outer angle.

    Parameters
    ----------
    robot : Robot
        The robot whose joints the plan commands.
    scale : {"full", "quick", "tiny"}
        The size (PAPER_SIZES): the levels and outer step used where not given.
    seed : int
        Unused (the protocol is deterministic; the recorder seeds the noise), kept so that every
        protocol has the same signature.
    levels : tuple of float, optional
        Relative translations d (mm) instead of the scale's (which are the paper robot's carried
        over to `robot`, ctrkin.acquisition.ranges).
    step_deg : float
        The inner tube's increment (deg).
    outer_step_deg : float, optional
        The outer tube's increment (deg) instead of the scale's.

    Returns
    -------
    Plan
    """
    _check_scale(scale)
    n = robot.n_tubes
    size = PAPER_SIZES[scale]
    ranges = ProtocolRanges.of(robot)
    lv = tuple(float(v) for v in (levels if levels is not None else ranges.levels(size.levels_mm)))
    outer_betas = tuple(ranges.beta_outer(b) for b in PAPER_OUTER_BETAS_MM)
    outer = outer_step_deg if outer_step_deg is not None else size.outer_step_deg
    if not 0 < outer <= 360:
        raise ValueError(f"outer_step_deg must be in (0, 360], got {outer}")
    angles = tuple(float(a) for a in np.arange(0.0, 360.0 - 1e-9, outer))
    _check_levels(robot, lv, outer_betas)
    runs = []
    for li, d in enumerate(lv):
        segs: list[Segment] = []
        prev = None
        for k, ao in enumerate(angles):
            bo = outer_betas[k % len(outer_betas)]
            q = inner_turn(n, ao, bo, d, step_deg)
            if prev is not None:
                segs.append(transition(prev, q[0], n))
            segs.append(Segment(q, record=True, level=li))
            prev = q[-1]
        runs.append(Run(tuple(segs)))
    params = {"scale": scale, "levels_mm": list(lv), "outer_angles_deg": list(angles),
              "outer_betas_mm": list(outer_betas), "inner_step_deg": step_deg,
              "transition_step": {"deg": 1.0, "mm": 0.1}}
    return Plan("paper", tuple(runs), tuple({"relative_translation_mm": d} for d in lv), params)


def sweeps(robot: Robot, scale: Scale = "full", seed: int = 0,
           levels: tuple[float, ...] | None = None, step_deg: float = 1.0) -> Plan:
    """Full inner rotations forward and back at five relative translations (Fig. 2b, 6, 10a).

    The outer tube at α = 0, βN = 0; one run, the inner tube translating between levels unrecorded.

    Parameters
    ----------
    robot : Robot
    scale : {"full", "quick", "tiny"}
        Unused: the sweeps do not depend on the scale.
    seed : int
        Unused (deterministic).
    levels : tuple of float, optional
        Relative translations d (mm); default d = 4, 8, 12, 16, 20 (the paper's β12 = 15..55) on
        the paper robot, carried over to `robot` (ctrkin.acquisition.ranges).
    step_deg : float
        The inner tube's increment (deg).

    Returns
    -------
    Plan
    """
    _check_scale(scale)
    n = robot.n_tubes
    lv = tuple(float(v) for v in (levels if levels is not None
                                  else ProtocolRanges.of(robot).levels(PAPER_LEVELS_MM)))
    _check_levels(robot, lv, (0.0,))
    segs: list[Segment] = []
    prev = None
    for li, d in enumerate(lv):
        q = inner_turn(n, 0.0, 0.0, d, step_deg)
        if prev is not None:
            segs.append(transition(prev, q[0], n))
        segs.append(Segment(q, record=True, level=li))
        prev = q[-1]
    return Plan("sweeps", (Run(tuple(segs)),), tuple({"relative_translation_mm": d} for d in lv),
                {"scale": scale, "levels_mm": list(lv), "outer_alpha_deg": 0.0, "outer_beta_mm": 0.0,
                 "inner_step_deg": step_deg})


def random_points(robot: Robot, scale: Scale = "full", seed: int = 0, n_points: int = 20) -> Plan:
    """N random configurations (Fig. 10b), each reached by a move from the previous one.

    The moves go in 1° / 0.1 mm steps, starting at rest at α = 0, d = 4 mm, βN = 0; one sequence
    per move, whose last sample is the target (`is_target`).

    Parameters
    ----------
    robot : Robot
    scale : {"full", "quick", "tiny"}
        Unused.
    seed : int
        Draws the configurations (α uniform in [0, 360)°, d in [4, 20] mm, βN in [−5, 0] mm on
        the paper robot, carried over to `robot`: ctrkin.acquisition.ranges).
    n_points : int
        N.

    Returns
    -------
    Plan
    """
    _check_scale(scale)
    if n_points < 1:
        raise ValueError(f"n_points must be >= 1, got {n_points}")
    n = robot.n_tubes
    ranges = ProtocolRanges.of(robot)
    d_range = (ranges.d(RANDOM_D_RANGE_MM[0]), ranges.d(RANDOM_D_RANGE_MM[1]))
    beta_range = (ranges.beta_outer(RANDOM_OUTER_BETA_RANGE_MM[0]),
                  ranges.beta_outer(RANDOM_OUTER_BETA_RANGE_MM[1]))
    _check_levels(robot, d_range, beta_range)
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 0xF1]))
    ai = rng.uniform(0.0, 360.0, n_points)
    ao = rng.uniform(0.0, 360.0, n_points)
    dd = rng.uniform(*d_range, n_points)
    bo = rng.uniform(*beta_range, n_points)
    targets = config(n, ai, ao, bo, dd)
    home = config(n, 0.0, 0.0, 0.0, d_range[0])
    segs = [Segment(home[None, :], record=False)]
    prev = home
    for t in targets:
        path = move(prev, t, n)
        if path.shape[0] == 0:
            path = t[None, :]
        flag = np.zeros(path.shape[0], dtype=bool)
        flag[-1] = True
        segs.append(Segment(path, record=True, is_target=flag))
        prev = t
    return Plan("random-points", (Run(tuple(segs)),), (),
                {"scale": scale, "n_points": n_points, "seed": seed, "targets": targets.tolist(),
                 "d_range_mm": list(d_range),
                 "outer_beta_range_mm": list(beta_range), "home": home.tolist()})


def arbitrary(robot: Robot, scale: Scale = "full", seed: int = 0, samples: int = 361) -> Plan:
    """The paper's simultaneous trajectory (Fig. 10c) in ctrkin's convention.

    βN 0 → −5 mm, β1 −20 → −10 mm, αN 0 → 360°, α1 360 → 0°, linear (d 20 → 5 mm; on another robot
    d and βN carried over, ctrkin.acquisition.ranges).

    Parameters
    ----------
    robot : Robot
    scale : {"full", "quick", "tiny"}
        Unused.
    seed : int
        Unused.
    samples : int
        Steps (361: 1° per step).

    Returns
    -------
    Plan
    """
    _check_scale(scale)
    if samples < 2:
        raise ValueError(f"samples must be >= 2, got {samples}")
    n = robot.n_tubes
    s, e = (_carried(ARBITRARY_START, ProtocolRanges.of(robot)),
            _carried(ARBITRARY_END, ProtocolRanges.of(robot)))
    f = np.linspace(0.0, 1.0, samples)

    def lerp(key: str) -> np.ndarray:
        return s[key] + f * (e[key] - s[key])

    bo = lerp("beta_outer")
    q = config(n, lerp("alpha_inner"), lerp("alpha_outer"), bo, bo - lerp("beta_inner"))
    robot.check_joints(q)
    return Plan("arbitrary", (Run((Segment(q, record=True),)),), (),
                {"scale": scale, "samples": samples, "start": dict(s), "end": dict(e),
                 "paper": "outer beta2 20 -> 15 mm, alpha2 0 -> 360 deg; inner beta1 30 -> 40 mm, "
                          "alpha1 360 -> 0 deg (paper encoder units)"})


def _carried(point: dict[str, float], ranges: ProtocolRanges) -> dict[str, float]:
    """A point of the arbitrary path with its d = βN − β1 and βN carried over to the robot."""
    beta_outer = ranges.beta_outer(point["beta_outer"])
    d = ranges.d(point["beta_outer"] - point["beta_inner"])
    return {**point, "beta_inner": beta_outer - d, "beta_outer": beta_outer}


SNAP_TURN_OUTER_ANGLES_DEG = (10.0, 70.0, 130.0, 190.0, 250.0, 310.0)
SNAP_TURN_OUTER_BETAS_MM = (-1.25, -3.75)


def snap_turns(robot: Robot, scale: Scale = "full", seed: int = 0, d: float | None = None,
               step_deg: float = 1.0) -> Plan:
    """Full inner turns at outer angles and translations the paper protocol never records.

    Parameters
    ----------
    robot : Robot
    scale : {"full", "quick", "tiny"}
        Unused.
    seed : int
        Unused.
    d : float, optional
        Relative translation (mm); default the robot's full curved overlap (20 mm on the paper
        robot; ctrkin.acquisition.ranges). The outer translations are carried over likewise.
    step_deg : float
        The inner tube's increment (deg).

    Returns
    -------
    Plan
        One run, from rest, per turn (outer α = 10, 70, …, 310°).
    """
    _check_scale(scale)
    n = robot.n_tubes
    ranges = ProtocolRanges.of(robot)
    d = ranges.d(PAPER_FULL_LEVELS_MM[-1]) if d is None else float(d)
    betas = tuple(ranges.beta_outer(b) for b in SNAP_TURN_OUTER_BETAS_MM)
    _check_levels(robot, (d,), betas)
    runs = tuple(
        Run((Segment(inner_turn(n, ao, betas[k % 2], d, step_deg), level=0),))
        for k, ao in enumerate(SNAP_TURN_OUTER_ANGLES_DEG))
    return Plan("snap-turns", runs, ({"relative_translation_mm": d},),
                {"scale": scale, "d_mm": d, "outer_angles_deg": list(SNAP_TURN_OUTER_ANGLES_DEG),
                 "outer_betas_mm": list(betas), "inner_step_deg": step_deg})


PROTOCOLS: dict[str, Any] = {"paper": paper, "sweeps": sweeps, "random-points": random_points,
                             "arbitrary": arbitrary, "snap-turns": snap_turns, "excitation": excitation}


def build(name: str, robot: Robot, scale: Scale = "full", seed: int = 0, **kw: Any) -> Plan:
    """The plan of a protocol, its joints checked against the robot.

    Parameters
    ----------
    name : str
        One of `PROTOCOLS`: "paper", "sweeps", "random-points", "arbitrary", "snap-turns".
    robot : Robot
    scale : {"full", "quick", "tiny"}
        The paper protocol's size (`PAPER_SIZES`).
    seed : int
        Random draws of the protocol (random points).
    **kw
        The protocol's own options (e.g. ``levels``, ``n_points``).

    Returns
    -------
    Plan

    Raises
    ------
    ValueError
        An unknown protocol or scale.
    JointError
        A plan the robot cannot perform (e.g. a level beyond its reach).

    Examples
    --------
    >>> from ctrkin.acquisition import protocols
    >>> from ctrkin.robots import paper_robot
    >>> protocols.build("paper", paper_robot(), scale="quick").n_samples
    51912
    """
    if name not in PROTOCOLS:
        raise ValueError(f"unknown protocol {name!r}; choose one of {sorted(PROTOCOLS)}")
    plan: Plan = PROTOCOLS[name](robot, scale=scale, seed=seed, **kw)
    robot.check_joints(plan.all_joints())
    return plan

