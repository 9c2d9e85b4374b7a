"""Where a robot's protocols move: the paper's translations carried over to any robot
(docs/protocols.md: Other robots).

The paper's protocols are written in the paper robot's millimetres: relative translations
d = βN − β1 from 4 to 20 mm (sweeps, training levels, random points, the arbitrary path, the snap
turns) and outer translations βN from 0 to −5 mm. What those numbers mean on the paper robot is
geometric: its curved sections start to overlap at d = 5.5 mm (the onset) and overlap fully at
d = 20 mm (the full overlap, 14.5 mm, the outer tube's curved length), and d ≤ 20.5 mm keeps the
inner tip in front of the outer tube's (the reach, L1 − L2). The outer tube retracts by up to 5 mm,
a third of its 14.5 mm curved section. `ProtocolRanges.of(robot)` finds the same places on any
robot and maps the paper's numbers onto them:

    d' = d_full − (20 − d)·k,   k = min((d_full − d_onset) / 14.5, d_full / 20)
    βN' = βN · r / 5,           r = 5 · ℓN / 14.5  (ℓN the outer tube's curved length; a straight
                                                   outer tube: 5 · LN / 51.5, its length's share)

so 20 mm lands on the robot's full overlap, 5.5 mm on its onset (the paper's levels keep their places
relative to the nonlinearity: one level below the onset, the others through the overlap), and
k ≤ d_full / 20 keeps the lowest level (4 mm) at ≥ 0.2·d_full when the onset is near 0. On the paper
robot k = 1 and r = 5 exactly: every protocol keeps the paper's numbers, bit for bit. The onset and
full overlap are read at βN = 0 with the middle tubes moving with the outer tube (as every protocol
moves them: ctrkin.acquisition.protocols.config); a robot whose curved overlap does not change with d
(one curved tube) spans its reach instead (onset 0, full overlap at the reach). Derived values are
rounded to 0.01 mm (a fifth of the lead screw's backlash) and kept within [0, reach].
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ctrkin.errors import JointError
from ctrkin.robots.overlap import curved_overlap, curved_sections
from ctrkin.robots.robot import Robot

PAPER_ONSET_MM = 5.5           # paper robot: the curved sections start to overlap
PAPER_FULL_MM = 20.0           # and overlap fully (14.5 mm)
PAPER_RETRACT_MM = 5.0         # the outer tube's largest retraction in the protocols
PAPER_OUTER_CURVED_MM = 14.5   # the paper robot's outer curved length
PAPER_OUTER_LENGTH_MM = 51.5   # and its whole length
RESOLUTION_DECIMALS = 2        # derived translations are rounded to 0.01 mm


@dataclass(frozen=True)
class ProtocolRanges:
    """A robot's landmarks along the relative translation d (mm) and its outer-tube retraction.

    Attributes
    ----------
    onset_mm : float
        The largest d below the full overlap at which the curved overlap is still at its least.
    full_mm : float
        The least d with the most curved overlap (within reach).
    reach_mm : float
        The largest d that keeps the inner tip in front of the next tube's (L1 − L2).
    retract_mm : float
        The outer tube's largest retraction r (mm, ≥ 0) in the protocols.
    """

    onset_mm: float
    full_mm: float
    reach_mm: float
    retract_mm: float

    @classmethod
    def of(cls, robot: Robot) -> ProtocolRanges:
        """The landmarks of `robot` (module docstring).

        Raises
        ------
        JointError
            A robot whose inner tube is not longer than the next one (no relative translation
            keeps its tip in front).
        """
        lengths = robot.lengths
        reach = float(lengths[0] - lengths[1]) if robot.n_tubes > 1 else 0.0
        if robot.n_tubes < 2 or reach <= 0:
            raise JointError(f"robot {robot.name!r}: the protocols translate the inner tube behind the "
                             "others, so it must have two or more tubes with the inner one the longest "
                             f"(L1 - L2 = {reach:g} mm)")
        d = _breakpoints(robot, reach)
        q = np.zeros((len(d), 2 * robot.n_tubes))
        q[:, robot.n_tubes] = -d                      # β1 = −d, the others at 0 (protocols.config)
        overlap = curved_overlap(robot, q)
        most, least = overlap.max(), overlap.min()
        if most - least <= 1e-9:                       # nothing changes with d: span the reach
            onset, full = 0.0, reach
        else:
            full = float(d[np.argmax(overlap >= most - 1e-9)])
            below = d <= full
            onset = float(d[below][overlap[below] <= overlap[below].min() + 1e-9].max())
        outer_curved = sum(length for i, _off, length in curved_sections(robot) if i == robot.n_tubes - 1)
        retract = (PAPER_RETRACT_MM * outer_curved / PAPER_OUTER_CURVED_MM if outer_curved > 0
                   else PAPER_RETRACT_MM * float(lengths[-1]) / PAPER_OUTER_LENGTH_MM)
        return cls(onset, full, reach, min(retract, float(lengths[-1])))

    @property
    def scale(self) -> float:
        """k: mm of this robot's d per mm of the paper robot's (module docstring)."""
        return min((self.full_mm - self.onset_mm) / (PAPER_FULL_MM - PAPER_ONSET_MM),
                   self.full_mm / PAPER_FULL_MM)

    def d(self, paper_d: float) -> float:
        """The relative translation (mm) at the place of the paper robot's `paper_d` (mm)."""
        out = self.full_mm - (PAPER_FULL_MM - float(paper_d)) * self.scale
        return min(max(_round(out), 0.0), self.reach_mm)

    def levels(self, paper_levels: tuple[float, ...]) -> tuple[float, ...]:
        """`d` of each level, in order, without repeats (a robot whose overlap changes within less
        than a few hundredths of a mm may merge neighbouring levels)."""
        out: list[float] = []
        for v in paper_levels:
            d = self.d(v)
            if d not in out:
                out.append(d)
        return tuple(out)

    def beta_outer(self, paper_beta: float) -> float:
        """The outer translation βN (mm, ≤ 0) at the place of the paper robot's `paper_beta`."""
        return _round(float(paper_beta) * self.retract_mm / PAPER_RETRACT_MM)

    def to_dict(self) -> dict[str, float]:
        return {"onset_mm": self.onset_mm, "full_mm": self.full_mm, "reach_mm": self.reach_mm,
                "retract_mm": self.retract_mm}


def _round(mm: float) -> float:
    return round(mm, RESOLUTION_DECIMALS) + 0.0       # + 0.0: no −0.0


def _breakpoints(robot: Robot, reach: float) -> np.ndarray:
    """(K,) the d in [0, reach] at which the curved overlap (βN = 0, middle tubes with the outer)
    can change slope: where an end of an inner curved section passes an end of another tube's, or
    the front plate. Between them the overlap is linear in d, so its extremes lie among them."""
    sections = curved_sections(robot)
    inner = [e for i, off, length in sections if i == 0 for e in (off, off + length)]
    other = [e for i, off, length in sections if i > 0 for e in (off, off + length)]
    cands = {0.0, reach, *inner, *(a - b for a in inner for b in other)}
    return np.array(sorted(c for c in cands if 0.0 <= c <= reach))
