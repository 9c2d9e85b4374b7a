"""Joint trajectories (T, 2N) of the paper's experiments, in the fixed joint convention.

Relative translation: d = β_N − β_1 ≥ 0 (mm), how far the inner tube's base is behind the outer
tube's. On the paper robot the curved sections start to overlap at d = 5.5 mm and overlap fully
(14.5 mm) at d = 20 mm. The paper reports five levels β12 = 15, 25, 35, 45, 55 (its own encoder
offsets, from low nonlinearity to snapping); we map them linearly onto d = 4, 8, 12, 16, 20 mm
(curved overlap 0, 2.5, 6.5, 10.5, 14.5 mm).
"""

from __future__ import annotations

import numpy as np

PAPER_LEVELS_PAPER_UNITS = (15.0, 25.0, 35.0, 45.0, 55.0)
PAPER_LEVELS_MM = (4.0, 8.0, 12.0, 16.0, 20.0)


def paper_level_to_relative_translation(beta12_paper: float) -> float:
    """The paper's level β12 (its encoder units, 15..55) as ctrkin's relative translation.

    Parameters
    ----------
    beta12_paper : float

    Returns
    -------
    float
        d = βN − β1 = 0.4 β12 − 2 (mm): 4..20 mm.
    """
    return 0.4 * beta12_paper - 2.0


def relative_translation_to_paper_level(d_mm: float) -> float:
    """The inverse of `paper_level_to_relative_translation`: β12 = (d + 2) / 0.4 (paper units)."""
    return (d_mm + 2.0) / 0.4


def rotation_sweep(n_tubes: int, relative_translation: float, outer_beta: float = 0.0,
                   outer_alpha: float = 0.0, step_deg: float = 1.0, turns: float = 1.0,
                   start_deg: float = 0.0) -> np.ndarray:
    """Paper Fig. 2b: the inner tube turning forward and back, the other tubes fixed.

    Parameters
    ----------
    n_tubes : int
        N.
    relative_translation : float
        d = βN − β1 (mm); the inner tube's β is outer_beta − d.
    outer_beta : float
        β of the other tubes (mm).
    outer_alpha : float
        α of the other tubes (deg).
    step_deg : float
        Increment of the inner rotation (deg).
    turns : float
        How far it turns: start → start + 360°·turns → start.
    start_deg : float
        Where the inner rotation starts (deg).

    Returns
    -------
    ndarray, shape (T, 2N)
        Joints, T = 2·(360·turns / step) + 1.
    """
    n_half = round(360.0 * turns / step_deg)
    fwd = start_deg + step_deg * np.arange(n_half + 1)
    a1 = np.r_[fwd, fwd[-2::-1]]
    q = np.zeros((a1.shape[0], 2 * n_tubes))
    q[:, 0] = a1
    q[:, 1:n_tubes] = outer_alpha
    q[:, n_tubes:] = outer_beta
    q[:, n_tubes] = outer_beta - relative_translation
    return q
