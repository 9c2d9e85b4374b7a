"""A training-only protocol that excites the histories a robot is used in (issue 21).

The paper protocol turns the inner tube 0 → 360 → 0° at fixed levels: it never reverses a tube
mid-turn, never slides one tube against the other right before a turn, and always starts a turn
from the same state. With friction between the tubes the tip's state after a reversal or a slide
depends on that history (hysteresis tens of degrees wide; snaps shifted by the slide), so a model
trained on the paper protocol alone never sees it (docs/learned_kinematics.md: What the learned
models assume about the robot). `excitation` records what the paper protocol leaves out:

    many short runs, each from rest at a random configuration (recorded for REST_SAMPLES steps at
    rest, so the start is in the data), then moves until the run has RUN_SAMPLES samples; each move
    is, with probability SLIDE_PROBABILITY, a slide (the inner tube against the outer one, the outer
    against the inner one, or both together: a random d = βN − β1 and/or βN step, scaled to the
    robot), followed by a turn of the inner tube (probability INNER_PROBABILITY) or the outer
    tube (the middle tubes move with it) made of 1..MAX_LEGS legs of random length (TURN_LEG_DEG)
    in alternating directions: reversals at random angles.

The ranges are the robot's (ctrkin.acquisition.ranges: d within the paper's 4..20 mm carried over,
βN within its 0..−5 mm carried over, both α within [0, 360]°, the ranges of the paper protocol, so
the normalisation of a model trained on both does not stretch). The starts and the slides' ends lie
in the high-overlap part d(18)..d(20) with HIGH_OVERLAP_PROBABILITY: the curved sections overlap
most there, and that is where a two-tube robot is bistable and snaps (on the paper robot with its
default effects every recorded snap of the paper protocol is at d = 20 mm), so the runs' turns
cross snaps after slides. Every draw comes from `seed`.

Size: EXCITATION_FRACTION (20 %) of the paper protocol's samples at the same scale, in runs of
RUN_SAMPLES: quick 10 runs, 10,400 samples (the paper protocol 51,912); full 40 runs, 41,600
(207,648); tiny 1 run, 1,040 (5,768). A fifth keeps the paper protocol the bulk of the training
rows (the reproduction of the paper's grids trains on the paper protocol only) and the extra
collection time a fifth of the paper protocol's; docs/reproduction.md measures what it buys.

It is training data only. It shares no path with the held-out experiments: the sweeps, the snap
turns and the mid-turn reversals of benchmarks/bench_generalisation.py turn from fixed poses along
fixed angles; these runs draw their starts, slides, legs and reversal angles at random, with their own
seed (ctrkin.evaluation.datasets.SEEDS).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ctrkin.acquisition.plan import Plan, Run, Segment, move
from ctrkin.acquisition.protocol_base import (
    PAPER_SIZES,
    RANDOM_D_RANGE_MM,
    RANDOM_OUTER_BETA_RANGE_MM,
    check_levels,
    check_scale,
    config,
)
from ctrkin.acquisition.ranges import ProtocolRanges
from ctrkin.robots.robot import Robot

EXCITATION_FRACTION = 0.2          # of the paper protocol's samples at the same scale
RUN_SAMPLES = 1040                 # recorded samples per run (rest included)
REST_SAMPLES = 5                   # recorded at rest at each run's start
SLIDE_PROBABILITY = 0.7            # a slide before a turn
INNER_PROBABILITY = 0.6            # the turn is the inner tube's (else the outer tube's)
MAX_LEGS = 3                       # legs per turn (2 or 3: one or two mid-turn reversals)
TURN_LEG_DEG = (30.0, 360.0)       # a leg's length, uniform
HIGH_OVERLAP_MM = (18.0, 20.0)      # d where the curved sections overlap most (paper robot; carried over)
HIGH_OVERLAP_PROBABILITY = 0.7     # a start or a slide's end d drawn there (else anywhere in the range)
SMALL_SLIDE_PROBABILITY = 0.3      # a short slide (SMALL_SLIDE_MM) instead of one to a drawn d
SMALL_SLIDE_MM = (0.05, 1.0)       # its length on the paper robot, uniform (scaled to the robot)
SLIDE_MM = (0.3, 6.0)              # the both-tubes move's length on the paper robot (scaled)
MIN_LEG_DEG = 5.0                  # a leg shorter than this (at a bound) turns the other way instead
SEED_SALT = 0xE7C1                 # keeps the draws apart from the other protocols' for the same seed


def n_runs(paper_samples: int) -> int:
    """Runs at a scale whose paper protocol records `paper_samples` (at least 1)."""
    return max(1, round(EXCITATION_FRACTION * paper_samples / RUN_SAMPLES))


def excitation(robot: Robot, scale: str = "full", seed: int = 0, runs: int | None = None) -> Plan:
    """Short runs from rest with slides before turns and mid-turn reversals (module docstring).

    Parameters
    ----------
    robot : Robot
        The robot whose joints the plan commands (two or more tubes).
    scale : {"full", "quick", "tiny"}
        Sizes the protocol: `n_runs` of the paper protocol's samples at this scale.
    seed : int
        Every random draw (starts, slides, turns).
    runs : int, optional
        The number of runs instead of the scale's.

    Returns
    -------
    Plan
        One recorded sequence per run (RUN_SAMPLES samples each), level −1.
    """
    check_scale(scale)
    if runs is None:
        runs = n_runs(PAPER_SIZES[scale].n_samples())
    if runs < 1:
        raise ValueError(f"runs must be >= 1, got {runs}")
    ranges = ProtocolRanges.of(robot)
    bounds = Bounds(d=(ranges.d(RANDOM_D_RANGE_MM[0]), ranges.d(RANDOM_D_RANGE_MM[1])),
                    high=(ranges.d(HIGH_OVERLAP_MM[0]), ranges.d(HIGH_OVERLAP_MM[1])),
                    beta=(ranges.beta_outer(RANDOM_OUTER_BETA_RANGE_MM[0]), 0.0),
                    slide=(SLIDE_MM[0] * ranges.scale, SLIDE_MM[1] * ranges.scale),
                    small=(SMALL_SLIDE_MM[0] * ranges.scale, SMALL_SLIDE_MM[1] * ranges.scale))
    check_levels(robot, bounds.d, bounds.beta)
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), SEED_SALT]))
    plan_runs = tuple(_run(robot.n_tubes, bounds, rng) for _ in range(runs))
    params = {"scale": scale, "seed": seed, "runs": runs, "run_samples": RUN_SAMPLES,
              "rest_samples": REST_SAMPLES, "d_range_mm": list(bounds.d),
              "outer_beta_range_mm": list(bounds.beta),
              "high_overlap_d_mm": list(bounds.high), "slide_mm": list(bounds.slide),
              "small_slide_mm": list(bounds.small), "high_overlap_probability": HIGH_OVERLAP_PROBABILITY,
              "small_slide_probability": SMALL_SLIDE_PROBABILITY, "turn_leg_deg": list(TURN_LEG_DEG),
              "max_legs": MAX_LEGS,
              "slide_probability": SLIDE_PROBABILITY, "inner_probability": INNER_PROBABILITY}
    return Plan("excitation", plan_runs, (), params)


@dataclass(frozen=True)
class Bounds:
    """Where the runs move (mm): the d range and its high-overlap part, the βN range, the lengths of
    the both-tubes moves and of the short slides."""

    d: tuple[float, float]
    high: tuple[float, float]
    beta: tuple[float, float]
    slide: tuple[float, float]
    small: tuple[float, float]

    def draw_d(self, rng: np.random.Generator) -> float:
        """A relative translation: in the high-overlap part with HIGH_OVERLAP_PROBABILITY, else anywhere."""
        return float(rng.uniform(*(self.high if rng.uniform() < HIGH_OVERLAP_PROBABILITY else self.d)))


def _run(n_tubes: int, b: Bounds, rng: np.random.Generator) -> Run:
    """One run: REST_SAMPLES at rest at a random start, then slide-and-turn moves, RUN_SAMPLES in all."""
    # state: α inner, α outer, βN, d
    s = np.array([rng.uniform(0, 360), rng.uniform(0, 360), rng.uniform(*b.beta), b.draw_d(rng)])
    last = config(n_tubes, *s)
    path = [np.repeat(last[None], REST_SAMPLES, axis=0)]
    total = REST_SAMPLES
    while total < RUN_SAMPLES:
        targets = []
        if rng.uniform() < SLIDE_PROBABILITY:
            s = _slide(s, b, rng)
            targets.append(s.copy())
        tube = 0 if rng.uniform() < INNER_PROBABILITY else 1
        for angle in _legs(float(s[tube]), rng):
            s[tube] = angle
            targets.append(s.copy())
        for t in targets:
            step = move(last, config(n_tubes, *t), n_tubes)
            if len(step):
                path.append(step)
                total += len(step)
                last = step[-1]
    q = np.concatenate(path)[:RUN_SAMPLES]
    return Run((Segment(q, record=True),))


def _slide(s: np.ndarray, b: Bounds, rng: np.random.Generator) -> np.ndarray:
    """A slide: the inner tube against the outer (d), the outer against the inner (βN and d, β1 fixed)
    or both together (βN, d fixed), kept within the bounds. A slide of one tube against the other goes
    to a drawn d (Bounds.draw_d), or is short (SMALL_SLIDE_PROBABILITY) in a random direction; the
    both-tubes move has a random length (SLIDE_MM) and direction."""
    out = s.copy()
    sign = rng.choice((-1.0, 1.0))
    if rng.uniform() < SMALL_SLIDE_PROBABILITY:
        length = rng.uniform(*b.small) * sign
    else:
        length = b.draw_d(rng) - s[3]
    kind = rng.integers(3)
    if kind == 0:                                   # inner tube slides: β1 moves, βN fixed
        out[3] = np.clip(s[3] + length, *b.d)
    elif kind == 1:                                 # outer tube slides: βN and d move alike, β1 fixed
        lo = max(b.beta[0] - s[2], b.d[0] - s[3])
        hi = min(b.beta[1] - s[2], b.d[1] - s[3])
        step = float(np.clip(length, min(lo, 0.0), max(hi, 0.0)))
        out[2], out[3] = s[2] + step, s[3] + step
    else:                                           # both together: βN moves, d fixed
        out[2] = np.clip(s[2] + rng.uniform(*b.slide) * sign, *b.beta)
    return out


def _legs(angle: float, rng: np.random.Generator) -> list[float]:
    """The end angles (deg, within [0, 360]) of a turn of 1..MAX_LEGS legs in alternating directions."""
    direction = rng.choice((-1.0, 1.0))
    out = []
    for _ in range(int(rng.integers(1, MAX_LEGS + 1))):
        end = float(np.clip(angle + direction * rng.uniform(*TURN_LEG_DEG), 0.0, 360.0))
        if abs(end - angle) < MIN_LEG_DEG:          # at a bound: turn the other way
            end = float(np.clip(angle - direction * rng.uniform(*TURN_LEG_DEG), 0.0, 360.0))
        out.append(round(end, 6))
        angle, direction = end, -np.sign(end - angle) if end != angle else -direction
    return out
