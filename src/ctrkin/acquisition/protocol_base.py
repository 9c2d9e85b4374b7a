"""What every protocol shares (ctrkin.acquisition.protocols, ctrkin.acquisition.excitation): the
scales and the paper protocol's size at each, the joints from the protocols' coordinates, and the
checks of a plan's scale and translations against the robot."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from ctrkin.errors import JointError
from ctrkin.robots.robot import Robot

Scale = Literal["tiny", "quick", "full"]
SCALES = ("tiny", "quick", "full")


@dataclass(frozen=True)
class PaperSize:
    """The size of the paper protocol at one scale.

    Parameters
    ----------
    levels_mm : tuple of float
        Relative translations d = βN − β1 (mm), one run each.
    outer_step_deg : float
        The outer tube's increment (deg) between the recorded inner turns.
    """

    levels_mm: tuple[float, ...]
    outer_step_deg: float

    def n_samples(self, inner_step_deg: float = 1.0) -> int:
        """Recorded samples: levels × outer angles × one inner turn 0 → 360 → 0°."""
        per_turn = 2 * round(360.0 / inner_step_deg) + 1
        return len(self.levels_mm) * len(np.arange(0.0, 360.0 - 1e-9, self.outer_step_deg)) * per_turn


PAPER_FULL_LEVELS_MM = (4.0, 8.0, 10.0, 12.0, 14.0, 16.0, 18.0, 20.0)
# One table for `ctrkin collect --scale` and `ctrkin reproduce --scale` (evaluation/scales.py reads it)
PAPER_SIZES = {
    "full": PaperSize(PAPER_FULL_LEVELS_MM, 10.0),          # the paper's: 207,648 samples
    "quick": PaperSize((4.0, 10.0, 15.0, 20.0), 20.0),      # 51,912: the README's main job
    "tiny": PaperSize((4.0, 20.0), 90.0),                   # 5,768: the CI test of the pipeline
}
PAPER_OUTER_BETAS_MM = (0.0, -2.5, -5.0)
RANDOM_D_RANGE_MM = (4.0, 20.0)
RANDOM_OUTER_BETA_RANGE_MM = (-5.0, 0.0)


def config(n_tubes: int, alpha_inner: float | np.ndarray, alpha_outer: float | np.ndarray,
           beta_outer: float | np.ndarray, d: float | np.ndarray) -> np.ndarray:
    """Joints from the protocols' coordinates; middle tubes follow the outer tube.

    Parameters
    ----------
    n_tubes : int
        N.
    alpha_inner, alpha_outer : float or ndarray, shape (T,)
        Rotations of the inner and the outer tube (deg).
    beta_outer : float or ndarray, shape (T,)
        The outer tube's translation βN (mm).
    d : float or ndarray, shape (T,)
        Relative translation d = βN − β1 (mm).

    Returns
    -------
    ndarray, shape (T, 2N) or (2N,)
        Joints (deg, mm); (2N,) for scalar inputs.
    """
    ai, ao, bo, dd = np.broadcast_arrays(*(np.asarray(v, dtype=float)
                                           for v in (alpha_inner, alpha_outer, beta_outer, d)))
    q = np.empty((*ai.shape, 2 * n_tubes))
    q[..., 0] = ai
    q[..., 1:n_tubes] = ao[..., None]
    q[..., n_tubes:] = bo[..., None]
    q[..., n_tubes] = bo - dd
    return q


def check_scale(scale: str) -> None:
    if scale not in SCALES:
        raise ValueError(f"scale must be one of {SCALES}, got {scale!r}")


def check_levels(robot: Robot, levels: tuple[float, ...], outer_betas: tuple[float, ...]) -> None:
    reach = float(robot.lengths[0] - robot.lengths[min(1, robot.n_tubes - 1)])
    for d in levels:
        if not 0 <= d <= reach:
            raise JointError(f"relative translation level d = {d} mm is outside 0..{reach:g} mm for "
                             f"robot {robot.name!r} (d <= L1 - L2 keeps the inner tip in front, the "
                             "middle tubes moving with the outer one); pass levels the robot can reach")
    for b in outer_betas:
        if not -float(robot.lengths[-1]) <= b <= 0:
            raise JointError(f"outer translation {b} mm is outside -{robot.lengths[-1]:g}..0 mm for "
                             f"robot {robot.name!r}")
