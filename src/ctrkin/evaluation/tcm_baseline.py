"""The paper's TCM baseline as a predictor: nominal robot, point-wise solve from the default guess with
no history (so it cannot know which branch a snapping robot is on), mapped to the tracker frame by a
registration fitted on training data, and timed per point. The continued TCM (`predict_continued`)
is the second physics row: the same nominal robot followed along each sequence's joint path by
continuation (ctrkin.follow), so it carries a branch and snaps where the nominal model folds.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ctrkin.geometry import Registration
from ctrkin.mechanics import follow, solve
from ctrkin.robots.robot import Robot
from ctrkin.util.progress import progress_bar


@dataclass(eq=False)
class TCMBaseline:
    """robot: the nominal robot (the robot file, not the true one); registration: robot -> tracker."""

    robot: Robot
    registration: Registration = field(default_factory=Registration.identity)
    last_times: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def predict_robot_frame(self, joints: np.ndarray, desc: str = "TCM") -> np.ndarray:
        """joints (T, 2N) -> (T, 6) poses in the robot base frame; per-point times in last_times (s).
        Configurations with no converged equilibrium give NaN rows."""
        Q = self.robot.check_joints(np.atleast_2d(joints))
        out = np.empty((len(Q), 6))
        times = np.empty(len(Q))
        with progress_bar(total=len(Q), desc=desc, leave=False) as bar:
            for i, q in enumerate(Q):
                t0 = time.perf_counter()
                out[i] = solve(self.robot, q).tip_pose
                times[i] = time.perf_counter() - t0
                bar.update(1)
        self.last_times = times
        return out

    def predict(self, joints: np.ndarray, desc: str = "TCM") -> np.ndarray:
        """joints (T, 2N) -> (T, 6) poses in the tracker frame."""
        return self.registration.apply(self.predict_robot_frame(joints, desc))

    def fit_registration(
        self, joints: np.ndarray, measured: np.ndarray, max_points: int = 2000, seed: int = 0
    ) -> Registration:
        """Fit robot -> tracker on (a seeded subsample of) training rows: joints (T, 2N), measured
        poses (T, 6). Uses positions only (the tangents then follow the fitted rotation)."""
        rng = np.random.default_rng(seed)
        idx = np.arange(len(joints))
        if len(idx) > max_points:
            idx = np.sort(rng.choice(idx, max_points, replace=False))
        pred = self.predict_robot_frame(joints[idx], desc="TCM registration")
        self.registration = Registration.fit(pred[:, :3], np.asarray(measured, float)[idx, :3])
        return self.registration

    def predict_continued(self, joints: np.ndarray, bounds: list[tuple[int, int]]
                          ) -> tuple[np.ndarray, np.ndarray]:
        """joints (T, 2N), sequences `bounds` -> (T, 6) tracker-frame poses of the nominal robot
        followed along each sequence from a point-wise solve at its first row, and (T,) its snap
        flags (a fold crossed on the way into the row)."""
        Q = self.robot.check_joints(np.atleast_2d(joints))
        out = np.empty((len(Q), 6))
        snaps = np.zeros(len(Q), bool)
        for a, b in bounds:
            traj = follow(self.robot, Q[a:b])
            out[a:b], snaps[a:b] = traj.tip_poses, traj.snaps
        return self.registration.apply(out), snaps
