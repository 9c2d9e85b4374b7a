"""Where a robot snaps: the folds of its innermost-outermost pair, as a function of the translations.

At full curved overlap a tube pair is bistable in a band of relative rotation around α0 = α1 − αN =
180° (docs/mechanics.md: Model, ψ'' = c·sin ψ about ψ = π). Turning α0 up through the band the robot
stays on its branch until that branch ends at a fold and snaps; turning back it snaps at the mirror
fold. With φ = α0 − 180° wrapped to [−180°, 180°):

    forward fold  φ+ (≥ 0): the first snap of a continuation from φ = −band up to +band
    backward fold φ− (≤ 0): the first snap of a continuation from φ = +band down to −band

Both are 0 where the pair is not bistable (no snap: the branches join continuously at φ = 0). Only
the translations change where the folds are (a common rotation of all tubes does not), so a table
over β is a complete description of the nominal robot's snapping for this pair; the other tubes
(N > 2) are held at the outermost tube's rotation.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ctrkin.mechanics.continuation import follow
from ctrkin.mechanics.settings import DEFAULT_SETTINGS, SolverSettings
from ctrkin.robots.robot import Robot


def fold_angles(robot: Robot, betas: np.ndarray, step_deg: float = 0.5, band_deg: float = 90.0,
                settings: SolverSettings = DEFAULT_SETTINGS,
                progress: Callable[[int], None] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """betas (P, N) translations (mm) -> forward φ+ (P,) and backward φ− (P,) fold angles (deg).

    Each is the phase of the first row flagged as a snap by `follow` on a sweep of α1 at `step_deg`
    (so it lies at most one step past the fold), 0 where the sweep does not snap. Translations the
    robot cannot take are first moved to the nearest it can (Robot.project_joints, the mechanical
    stops). progress: called with the index of each finished translation."""
    betas = np.atleast_2d(np.asarray(betas, dtype=float))
    n = robot.n_tubes
    phi = np.arange(-band_deg, band_deg + 0.5 * step_deg, step_deg)
    fwd, bwd = np.zeros(len(betas)), np.zeros(len(betas))
    valid = robot.project_joints(np.concatenate([np.zeros_like(betas), betas], axis=1))[:, n:]
    for p, beta in enumerate(valid):
        q = np.zeros((len(phi), 2 * n))
        q[:, 0] = 180.0 + phi                          # α1; α2..αN = 0
        q[:, n:] = beta
        up = follow(robot, q, settings=settings)
        down = follow(robot, q[::-1], settings=settings)
        if up.snaps[1:].any():
            fwd[p] = max(phi[1:][up.snaps[1:]][0], 0.0)
        if down.snaps[1:].any():
            bwd[p] = min(phi[::-1][1:][down.snaps[1:]][0], 0.0)
        if progress:
            progress(p)
    return fwd, bwd
