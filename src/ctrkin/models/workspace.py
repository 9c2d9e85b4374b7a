"""Is an IK target inside the workspace the model was trained on? (paper IV.C: outside it, a learned
IK silently returns invalid joints.)

Two checks on the target pose, min-max normalised with the model's input normalisation:
1. range: every component within [−margin, 1 + margin] of the training range;
2. support: the nearest training target (KD-tree, 6-D normalised pose) is closer than `threshold`.
   The threshold is calibrated on held-out data: 1.5 × the 99th percentile of the distance from the
   validation targets (whole sequences the model never trained on) to their nearest training target.
"""

from __future__ import annotations

import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from ctrkin.errors import ModelError
from ctrkin.geometry import POSE_COLUMNS, POSE_UNITS
from ctrkin.models.normalize import MinMax
from ctrkin.util.files import atomic_path

WORKSPACE_FILE = "workspace.npz"


@dataclass(eq=False)
class Workspace:
    """points: (M, 6) normalised training target poses; norm: pose min-max; threshold: normalised
    distance beyond which a target counts as unseen; margin: allowed range overshoot (normalised)."""

    points: np.ndarray
    norm: MinMax
    threshold: float
    margin: float = 0.05
    joints: np.ndarray | None = None     # (M, 2N) the joints of each training target (IK starts)

    def __post_init__(self) -> None:
        self.points = np.ascontiguousarray(self.points, dtype=np.float64)
        self._tree = cKDTree(self.points)
        if self.joints is not None and len(self.joints) != len(self.points):
            raise ModelError(f"workspace joints ({len(self.joints)}) and targets ({len(self.points)}) differ")

    def nearest_joints(self, pose: np.ndarray) -> np.ndarray:
        """(2N,) joints of the training target nearest to `pose` (6,) (normalised 6-D distance)."""
        if self.joints is None:
            raise ModelError("this workspace holds no training joints (retrain the IK model)")
        _, k = self._tree.query(self.norm.transform(np.asarray(pose, float)), k=1)
        return np.array(self.joints[int(k)], dtype=np.float64)

    @classmethod
    def fit(cls, train_poses: np.ndarray, val_poses: np.ndarray, norm: MinMax, factor: float = 1.5,
            quantile: float = 0.99, train_joints: np.ndarray | None = None) -> Workspace:
        """train_poses, val_poses: (M, 6) raw poses (mm, unit quaternion); norm: their min-max;
        train_joints: (M, 2N) the joints at train_poses (kept for IK refinement starts)."""
        pts = norm.transform(train_poses)
        tree = cKDTree(pts)
        if len(val_poses):
            d, _ = tree.query(norm.transform(val_poses), k=1)
        else:  # no held-out data: nearest-other-point spacing of the training set
            d = tree.query(pts, k=2)[0][:, 1]
        thr = float(factor * np.quantile(d, quantile))
        return cls(pts, norm, max(thr, 1e-6), joints=train_joints)

    def check(self, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[str]]:
        """poses: (T, 6) raw targets -> (in_workspace (T,) bool, distance (T,) normalised, reasons),
        reasons[t] = "" when in the workspace. distance is the nearest training target's, or inf where
        none lies within the threshold or the range test already failed (the tree search is bounded:
        far targets would otherwise cost a full tree walk)."""
        p = np.atleast_2d(np.asarray(poses, dtype=np.float64))
        z = self.norm.transform(p)
        bad_range = ((z < -self.margin) | (z > 1 + self.margin)).any(axis=1)
        dist = np.full(len(p), np.inf)          # not searched where the range test already failed
        if (~bad_range).any():
            dist[~bad_range] = self._tree.query(z[~bad_range], k=1,
                                                distance_upper_bound=self.threshold * (1 + 1e-9))[0]
        far = dist > self.threshold
        reasons = [""] * len(p)
        for t in np.nonzero(bad_range | far)[0]:
            reasons[t] = self._reason(p[t], z[t], float(dist[t]))
        return ~(bad_range | far), dist, reasons

    def check_one(self, pose: np.ndarray, hint: int) -> tuple[bool, str, int]:
        """Streaming check of one raw target (6,), the same verdict as `check`, usually without a tree
        query: a target within `threshold` of the training point `hint` (the previous target's nearest)
        is inside. Returns (in_workspace, reason, new hint)."""
        z = self.norm.transform(pose)
        if not (np.all(z >= -self.margin) and np.all(z <= 1 + self.margin)):
            return False, self._reason(pose, z, np.inf), hint
        diff = z - self.points[hint]
        if float(diff @ diff) <= self.threshold * self.threshold:
            return True, "", hint
        d, nearest = self._tree.query(z, k=1, distance_upper_bound=self.threshold * (1 + 1e-9))
        if d <= self.threshold:
            return True, "", int(nearest)
        return False, self._reason(pose, z, float(d)), hint

    def _reason(self, p: np.ndarray, z: np.ndarray, dist: float) -> str:
        parts = []
        for k in np.nonzero((z < -self.margin) | (z > 1 + self.margin))[0]:
            lo, hi = self.norm.lo[k], self.norm.hi[k]
            parts.append(f"{POSE_COLUMNS[k]} = {p[k]:.4g}{POSE_UNITS[k]} is outside the training range "
                         f"[{lo:.4g}, {hi:.4g}]{POSE_UNITS[k]}")
        if dist > self.threshold and not parts:
            parts.append(f"no training target within {self.threshold:.3g} (normalised 6-D pose distance, "
                         f"calibrated on held-out sequences)")
        return "; ".join(parts)

    def save(self, folder: str | Path) -> None:
        with atomic_path(Path(folder) / WORKSPACE_FILE) as tmp:
            with open(tmp, "wb") as fh:
                arrays: dict[str, object] = dict(
                    points=self.points.astype(np.float32), lo=self.norm.lo, span=self.norm.span,
                    threshold=self.threshold, margin=self.margin)
                if self.joints is not None:
                    arrays["joints"] = np.asarray(self.joints, np.float32)
                np.savez_compressed(fh, **arrays)  # type: ignore[arg-type]

    @classmethod
    def load(cls, folder: str | Path) -> Workspace:
        path = Path(folder) / WORKSPACE_FILE
        try:
            with np.load(path) as z:
                joints = z["joints"].astype(np.float64) if "joints" in z.files else None
                return cls(z["points"].astype(np.float64), MinMax(z["lo"], z["span"]),
                           float(z["threshold"]), float(z["margin"]), joints)
        except (OSError, KeyError, ValueError, EOFError, zipfile.BadZipFile) as e:
            raise ModelError(f"cannot read the IK workspace {path}: {e}") from None
