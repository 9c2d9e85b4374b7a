"""How the follow IK learns (ctrkin.families.follow.features): MAE on the joint change from perturbed
current joints to the true next joints, a fresh perturbation every epoch, early stopping on a fixed
perturbed validation draw. The network is rolled out and scored by its own streaming step
(ctrkin.families.follow.stepper), the one its predictor runs.

Rollouts (DAgger-like): at ROLLOUT_AT of the epochs the network follows the training sequences, and
from then on part of each epoch starts from the joints it reached, where it stayed near the recorded
branch: training then covers the states its own errors lead to.

Catch-up (TrainConfig.catch_up, the recommended IK's 0.25): that share of each draw's rows start,
unperturbed, from the joints the recording had 1 to CATCH_UP_ROWS rows earlier in the same sequence,
and are labelled with the recorded next joints: the robot behind on its own path. On a robot with
friction between the tubes, a reversal opens a dead band in which the joints turn and the tip stays;
an IK that followed the still targets has not turned through it when they move again, and the
recorded steps (1° each) never teach the jump that catches up. No friction law is assumed: the
recording's own earlier joints are the states.

With the play lags (FeatureLayout.play) each row's inputs hold the lags of the recorded target path
up to and including its target (ctrkin.models.play_lags.target_lags: along each run from rest, glitch
rows at the last believed position), as the stepper computes them from the targets it is given.

It keeps no per-epoch checkpoint (`checkpoints = False`): a killed run starts over (the quick budget
trains in about a minute), and a finished folder of the same configuration and data is reused.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import torch

from ctrkin.data.schema import sequence_bounds
from ctrkin.errors import ModelError
from ctrkin.families.follow.features import follow_features, joint_noise, previous_rows
from ctrkin.families.follow.stepper import (
    ARRIVE_ITERATIONS,
    DEAD_ZONE,
    OUTER_INVERSION,
    SUBSTEP_CAP,
    Follower,
)
from ctrkin.metrics import metrics_json_joint_errors, wrap_deg
from ctrkin.models.features import check_raw
from ctrkin.models.normalize import MinMax
from ctrkin.models.play_lags import recorded_target_lags
from ctrkin.models.recipe import (
    Log,
    Prepared,
    TrainingData,
    TrainSettings,
    fit_outer_frame,
    inputs_and_targets,
)
from ctrkin.models.store import ModelBundle
from ctrkin.models.workspace import Workspace

SETTLE_ITERATIONS = 5        # net applications at a sequence start (from the nearest training joints)
STEP_QUANTILE = 0.95         # sub-step length: this quantile of the training targets' step lengths
ROLLOUT_AT = (0.5, 0.75)     # fractions of the epochs at which the network follows the training sequences
ONPOLICY_FRACTION = 0.5
ONPOLICY_DEG, ONPOLICY_MM = 20.0, 2.0
CATCH_UP_ROWS = 60           # catch-up rows start up to this many rows back (TrainConfig.catch_up)


class FollowRecipe:
    """The follow IK's training (module docstring)."""

    checkpoints = False

    def __init__(self, cfg: TrainSettings) -> None:
        if cfg.val_smoothing or cfg.max_seconds is not None:
            raise ModelError("the follow IK's training takes no val_smoothing or max_seconds (its epochs "
                             "are cheap; set max_epochs and patience)")
        self.cfg = cfg

    def prepare(self, data: TrainingData) -> Prepared:
        cfg, ds = self.cfg, data.ds
        self.data, self.rows = data, data.rows
        self.n = ds.n_tubes
        self.layout = cfg.layout(self.n)
        self.poses, self.joints = inputs_and_targets(ds, "ik", cfg.pose_source)
        self.bounds = ds.sequence_bounds()
        self.prev = previous_rows(self.bounds)
        self.first = np.zeros(len(self.prev), dtype=np.int64)      # each row's sequence start
        for a, b in self.bounds:
            self.first[a:b] = a
        self.lags = (recorded_target_lags(ds.frame, self.poses, self.bounds)
                     if self.layout.play else None)
        tr, va = self.rows["train"], self.rows["val"]
        lagged, _ = fit_outer_frame(ds, self.joints, self.poses, tr, cfg.seed)  # the stepper inverts its lag
        self.frame = replace(lagged, lag=(0.0, 0.0))                 # the network's frame: the commanded αN
        self.visited: np.ndarray | None = None   # (T, 2N) the stepper's own joints before each row (rollouts)
        self.rng = np.random.default_rng(cfg.seed)
        X, Y = self._draw(tr, self.rng)
        self.x_norm, self.y_norm = MinMax.fit(X), MinMax.fit(Y)
        self.X, self.Y = X, Y
        self.Xv, self.Yv = self._tensors(*self._draw(va, np.random.default_rng(cfg.seed + 1)))
        steps = np.linalg.norm(self.poses[tr, :3] - self.poses[self.prev[tr], :3], axis=1)
        moved = steps[steps > 0]
        follow = {"max_step_mm": float(np.quantile(moved, STEP_QUANTILE)) if len(moved) else 1.0,
                  "settle_iterations": SETTLE_ITERATIONS, "arrive_iterations": ARRIVE_ITERATIONS,
                  "outer_lag_deg": list(lagged.lag), "outer_inversion": OUTER_INVERSION,
                  "dead_zone": list(DEAD_ZONE), "substep_cap": list(SUBSTEP_CAP)}
        epochs = cfg.max_epochs or 0       # the engine hands a recipe its resolved budget
        self.rollouts = {int(epochs * f) for f in ROLLOUT_AT} - {0}
        return Prepared(self.layout, self.x_norm, self.y_norm, self.frame, {"follow": follow})

    def _draw(self, r: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """Features and joint changes of rows r from perturbed current joints, a share from joints
        the recording had earlier in the sequence (catch-up), and half of them (after a rollout, where
        it stayed on the recorded branch) from the joints the stepper itself reached."""
        prev, joints = self.prev, self.joints
        current = joints[prev[r]] + joint_noise(rng, len(r), self.n)
        if self.cfg.catch_up > 0:                                  # behind on the path (docstring)
            back = np.maximum(self.first[r], r - 1 - rng.integers(1, CATCH_UP_ROWS + 1, len(r)))
            behind = rng.random(len(r)) < self.cfg.catch_up
            current[behind] = joints[back[behind]]
        if self.visited is not None:
            own = self.visited[prev[r]]
            near = _on_branch(own, joints[prev[r]], self.n) & (rng.random(len(r)) < ONPOLICY_FRACTION)
            current[near] = own[near]
        lags = None if self.lags is None else self.lags[r]
        return (follow_features(self.frame, self.n, self.poses[r], self.poses[prev[r]], current, lags,
                                self.layout.outer_angle),
                joints[r] - current)

    def _tensors(self, x: np.ndarray, y: np.ndarray) -> tuple[torch.Tensor, torch.Tensor]:
        return (torch.from_numpy(self.x_norm.transform(x)[:, None, :].astype(np.float32)),
                torch.from_numpy(self.y_norm.transform(y).astype(np.float32)))

    def epoch_tensors(self, epoch: int, bundle: ModelBundle) -> tuple[torch.Tensor, torch.Tensor]:
        if epoch in self.rollouts:
            bundle.net.eval()
            self.visited = _rollout(bundle, self.poses, self.joints, self.bounds, self.rows["train"])
        if epoch:
            self.X, self.Y = self._draw(self.rows["train"], self.rng)
        return self._tensors(self.X, self.Y)

    def loss(self, net: torch.nn.Module, x: torch.Tensor, y: torch.Tensor, idx: torch.Tensor,
             gen: torch.Generator) -> torch.Tensor:
        return torch.nn.functional.l1_loss(net(x), y)               # MAE loss (paper IV.A)

    def val_loss(self, net: torch.nn.Module) -> float:
        net.eval()
        with torch.inference_mode():
            return float(torch.mean(torch.abs(net(self.Xv) - self.Yv)))

    def attach(self, net: torch.nn.Module) -> None:     # nothing trains beside the network
        pass

    def detach(self, net: torch.nn.Module) -> None:
        pass

    def finish(self, bundle: ModelBundle, folder: Path, log: Log) -> dict[str, Any]:
        tr, va = self.rows["train"], self.rows["val"]
        workspace = Workspace.fit(self.poses[tr], self.poses[va], MinMax.fit(self.poses[tr]),
                                  train_joints=self.joints[tr])
        workspace.save(folder)
        return _evaluate(bundle, workspace, self.data, self.poses, self.joints)


def _on_branch(q: np.ndarray, ref: np.ndarray, n: int) -> np.ndarray:
    """(M,) rows whose joints q are within ONPOLICY_DEG / ONPOLICY_MM of ref (the recorded branch:
    the recorded next joints are then the right label; on a mirror solution they are not)."""
    da = np.abs(wrap_deg(q[:, :n] - ref[:, :n])).max(axis=1)
    return (da < ONPOLICY_DEG) & (np.abs(q[:, n:] - ref[:, n:]).max(axis=1) < ONPOLICY_MM)


def _rollout(bundle: ModelBundle, poses: np.ndarray, joints: np.ndarray, bounds: list[tuple[int, int]],
             train_rows: np.ndarray) -> np.ndarray:
    """(T, 2N) the joints the current network reaches at every row of the training sequences,
    following their recorded targets from their recorded start joints (NaN elsewhere)."""
    follower = Follower(bundle, None)
    follower.lag = (0.0, 0.0)     # recorded joints already carry the recording's outer lag
    follower.dead_zone = (0.0, 0.0)   # the states the network's own answers lead to, each one made
    follower.substep_cap = None       # ... and none held back
    used = np.zeros(len(joints), bool)
    used[train_rows] = True
    followed = [(a, b) for a, b in bounds if used[a:b].any()]
    out, _ = follower.run(poses, followed, [joints[a] for a, _ in followed])
    return out


def _evaluate(bundle: ModelBundle, workspace: Workspace, data: TrainingData, poses: np.ndarray,
              joints: np.ndarray) -> dict[str, Any]:
    """Joint errors of following the validation and test sequences from the nearest training joints
    (as the predictor runs a follow IK)."""
    follower = Follower(bundle, workspace)
    sid = data.ds.frame["sequence_id"].to_numpy()
    res: dict[str, Any] = {}
    for part in ("val", "test"):
        r = data.rows[part]
        if len(r):
            pred, _ = follower.run(check_raw(bundle.layout, poses[r]), sequence_bounds(sid[r]))
            errors = metrics_json_joint_errors(pred, joints[r], data.ds.n_tubes)
            res[part] = {"rows": len(r), "joints": errors}
    return res
