"""A calibrated TCM under a learned FK (TrainConfig.tcm_prior; docs/learned_kinematics.md: A
calibrated TCM under the FK): the network learns the position's residual from a physics prior and
the prior is added back wherever the model predicts.

The prior is the TCM calibrated on (a seeded subsample of) the training rows as `ctrkin reproduce
--scale quick` calibrates it (every group and μ, ctrkin.calibration), followed along each recorded
run from rest with its branch and friction state (CalibratedTCM.predict_continued; a row where no
equilibrium converged takes the row before it):

    p_model = p_prior(q_1..q_t) + p_net(window)           (positions, mm, tracker frame)

and in the outer tube's frame (ctrkin.models.frame), whose map is affine in position, the prior is
taken to that frame with the same angle, so that adding it back before `to_world` is exact. The
orientation is learned as without a prior. The model folder stores the calibrated robot file
(TCM_PRIOR_FILE, `CalibratedTCM.from_file` reads it).
"""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np

from ctrkin.calibration.model import CalibratedTCM, TCMStream
from ctrkin.data.dataset import Dataset
from ctrkin.errors import CtrkinError, ModelError
from ctrkin.util.files import atomic_write_text

TCM_PRIOR_FILE = "tcm_prior.toml"
# rows, least-squares evaluations and friction samples of the prior's calibration: reproduce's quick
# budget (ctrkin.evaluation.reproduce.CALIBRATION_BUDGET["quick"], tested equal), ~10 s on a laptop
PRIOR_BUDGET = (1000, 30, 10_000)


def run_bounds(ds: Dataset) -> list[tuple[int, int]]:
    """[(start, stop)) row ranges of the dataset's recorded runs (its `run` column, contiguous in
    file order); a dataset without one: each sequence its own run."""
    if "run" not in ds.frame.columns:
        return ds.sequence_bounds()
    run = ds.frame["run"].to_numpy()
    cuts = np.flatnonzero(run[1:] != run[:-1]) + 1
    edges = np.r_[0, cuts, len(run)]
    if len(np.unique(run)) != len(edges) - 1:
        raise ModelError("a run's rows are not contiguous in file order: the TCM prior cannot follow it")
    return [(int(a), int(b)) for a, b in itertools.pairwise(edges)]


def calibrate_prior(ds: Dataset, train: np.ndarray, seed: int = 0) -> CalibratedTCM:
    """The TCM calibrated on up to PRIOR_BUDGET[0] of the training rows `train` (seeded draw)."""
    from ctrkin.calibration.fit import calibrate
    from ctrkin.calibration.params import FRICTION, GROUPS

    n_rows, nfev, samples = PRIOR_BUDGET
    rows = np.sort(np.random.default_rng(seed).choice(train, min(n_rows, len(train)), replace=False))
    try:
        return calibrate(ds, ds.robot, (*GROUPS, FRICTION), rows=rows, max_nfev=nfev,
                         friction_samples=samples).model
    except CtrkinError as e:
        raise ModelError(f"tcm_prior: the TCM could not be calibrated on the training rows ({e}); "
                         "train without --tcm-prior") from None


def prior_poses(tcm: CalibratedTCM, joints: np.ndarray, bounds: list[tuple[int, int]]) -> np.ndarray:
    """(T, 6) tracker-frame poses of the prior along joints (T, 2N) (deg, mm) as given, followed
    from rest at each of `bounds`; a row that did not converge takes the row before it (the first
    of a run: the origin, identity orientation, as a stream starts)."""
    poses = tcm.predict_continued(np.asarray(joints, float), bounds)
    starts = {a for a, _ in bounds}
    for t in np.flatnonzero(~np.isfinite(poses).all(axis=1)):
        poses[t] = poses[t - 1] if t not in starts and t > 0 else np.nan_to_num(poses[t])
    return poses


def dataset_prior(tcm: CalibratedTCM, ds: Dataset) -> np.ndarray:
    """prior_poses of a dataset along its recorded runs (run_bounds)."""
    return prior_poses(tcm, ds.joints(), run_bounds(ds))


class PriorStream:
    """The prior streamed: TCMStream with prior_poses' rule for a step that does not converge."""

    def __init__(self, tcm: CalibratedTCM) -> None:
        self._stream = TCMStream(tcm)

    def reset(self) -> None:
        self._stream.reset()

    def step(self, joints: np.ndarray) -> np.ndarray:
        """Joints (2N,) as given -> the prior's (6,) tracker-frame pose."""
        return np.nan_to_num(self._stream.step(joints))


def save_prior(tcm: CalibratedTCM, folder: Path) -> None:
    """The calibrated robot file into a model folder (written atomically)."""
    atomic_write_text(folder / TCM_PRIOR_FILE, tcm.to_toml(f"{tcm.robot.name}-calibrated",
                                                           purpose="tcm_prior of this model folder"))


def load_prior(folder: Path, n_tubes: int) -> CalibratedTCM:
    """The prior of a model folder trained with tcm_prior; ModelError naming the file where it is
    missing or not a calibrated robot file of n_tubes tubes."""
    path = folder / TCM_PRIOR_FILE
    if not path.is_file():
        raise ModelError(f"{folder} was trained with tcm_prior but lacks {TCM_PRIOR_FILE}; train it again")
    try:
        tcm = CalibratedTCM.from_file(path)
    except (CtrkinError, OSError, ValueError) as e:
        raise ModelError(f"{path}: the model's TCM prior is not a readable calibrated robot file ({e}); "
                         "train the model again") from None
    if tcm.robot.n_tubes != n_tubes:
        raise ModelError(f"{path}: the TCM prior has {tcm.robot.n_tubes} tubes, the model {n_tubes}")
    return tcm
