"""How the snap-aware FK learns (docs/learned_kinematics.md: Snap-aware FK): the paper's windows and
MAE (ctrkin.models.recipe.WindowRecipe), plus the branch labels from the dataset's snap flags
(ctrkin.families.snap_aware.labels), the gate's cross-entropy beside the MAE of the true branch's
head, and at the end the fold gate from the nominal robot's folds (ctrkin.families.snap_aware.fold_gate),
kept in use unless the validation rows prefer the learned gate (ctrkin.families.snap_aware.gate_choice).

The gate sees the previous label (teacher forcing), hidden as "unknown" with probability
`unknown_prob` and flipped on rows whose label does not depend on history (so a wrong state
recovers); its loss counts `boost` times within `width` rows of a change of branch, where the
switching point is learned. With the offset head form (ctrkin.families.snap_aware.net) the MAE is of
z ± ½d and an L1 penalty holds the jump d at 0 where one branch alone exists (offset_free_rows;
docs/learned_kinematics.md: The offset head form).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import torch

from ctrkin.data.schema import sequence_bounds
from ctrkin.families.snap_aware.fold_gate import FoldGate, build_fold_gate, slide_lags
from ctrkin.families.snap_aware.gate_choice import GateChoice, judge_gates
from ctrkin.families.snap_aware.labels import BAND_DEG, branch_labels, phase_deg, previous_labels, snap_events
from ctrkin.families.snap_aware.net import BranchNet
from ctrkin.families.snap_aware.predictor import SnapAwarePredictor
from ctrkin.models.motion import recorded_motion
from ctrkin.models.recipe import Log, Prepared, TrainingData, WindowRecipe, inputs_and_targets
from ctrkin.models.seqnet import UNKNOWN_STATE
from ctrkin.models.store import ModelBundle

# Weight of the L1 penalty on the offset form's jump d (heads "offset", ctrkin.families.snap_aware.net),
# on the rows where one branch alone exists (offset_free_rows), so that d has nothing to hold there
# and a wrong state costs nothing. Not in the band, where the rows of both branches fit d and a
# penalty would only shrink the jump. Below 1 a jump that rows demand is kept. Not tuned.
OFFSET_L1 = 0.1
# the penalty starts this far beyond the furthest training snap from φ = 0 (and never inside the
# labels' band): a smooth d cannot fall from the full jump to 0 in the few degrees between a snap at
# |φ| = 79° (the default robot's) and the band's edge at 90°
OFFSET_MARGIN_DEG = 30.0


@dataclass(eq=False)
class BranchBatch:
    """Branch labels of the training rows (teacher forcing) and the augmentation of the gate input."""

    state: torch.Tensor          # (M,) labels
    state_prev: torch.Tensor     # (M,) previous labels, 0.5 at sequence starts
    forced: torch.Tensor         # (M,) label independent of history
    one_branch: torch.Tensor     # (M,) float: where one branch alone exists (offset_free_rows)
    gate_rows: torch.Tensor      # (M,) per-row weight of the gate loss
    unknown_prob: float
    weight: float
    pose_loss: Callable[[torch.nn.Module, torch.Tensor, torch.Tensor, torch.Tensor], torch.Tensor]

    def loss(self, net: BranchNet, x: torch.Tensor, y: torch.Tensor, idx: torch.Tensor,
             gen: torch.Generator) -> torch.Tensor:
        dev = x.device        # the labels and draws stay on the CPU (the same draws on any device)
        s, forced = self.state[idx].to(dev), self.forced[idx].to(dev)
        prev = self.state_prev[idx].to(dev, copy=True)
        u = torch.rand((len(idx), 2), generator=gen).to(dev)
        flip = forced & (u[:, 0] < 0.5) & (prev != UNKNOWN_STATE)     # a wrong state must recover
        prev = torch.where(flip, 1.0 - prev, prev)
        prev = torch.where(u[:, 1] < self.unknown_prob, torch.full_like(prev, UNKNOWN_STATE), prev)
        h = net.trunk(x)
        if net.head_form == "offset":      # the offset's L1 keeps it 0 where one branch alone exists
            y_hat, d = net.offset_out(h, s.reshape(-1, 1))
            pose_loss = (self.pose_loss(net, y_hat, y, idx)
                         + OFFSET_L1 * (d.abs() * self.one_branch[idx].to(dev).reshape(-1, 1)).mean())
        else:
            pose_loss = self.pose_loss(net, net.head_out(h, s), y, idx)       # MAE (paper IV.A)
        gate_loss = torch.nn.functional.binary_cross_entropy_with_logits(
            net.gate_logit(h, prev), s, weight=self.gate_rows[idx].to(dev))
        return pose_loss + self.weight * gate_loss


def offset_free_rows(alpha0: np.ndarray, snap: np.ndarray, train: np.ndarray,
                     bounds: list[tuple[int, int]]) -> np.ndarray:
    """(T,) bool: rows where one branch alone exists, for the offset form's penalty: |φ| beyond the
    labels' band (labels.BAND_DEG) and beyond the training rows' furthest snap from φ = 0 by
    OFFSET_MARGIN_DEG (identified from the data, as the snaps lie on this robot)."""
    phi = np.abs(phase_deg(alpha0))
    chosen = np.zeros(len(phi), dtype=bool)
    chosen[train] = True
    events = [t for a, b in bounds for t in snap_events(snap, a, b) if chosen[t]]
    edge = max(BAND_DEG, float(phi[events].max()) + OFFSET_MARGIN_DEG if events else 0.0)
    return phi > edge


def near_switch(state: np.ndarray, bounds: list[tuple[int, int]], width: int = 5, boost: float = 10.0
                ) -> np.ndarray:
    """(T,) float32 gate-loss weights: `boost` within `width` rows of a change of branch (where the
    switching point is learned; a few rows per sequence), 1 elsewhere."""
    w = np.ones(len(state), dtype=np.float32)
    for a, b in bounds:
        for t in np.nonzero(np.diff(state[a:b]))[0] + a + 1:
            w[max(a, t - width):min(b, t + width + 1)] = boost
    return w


def decode_rows(net: BranchNet, X: np.ndarray, rows: np.ndarray, bounds: list[tuple[int, int]]
                ) -> np.ndarray:
    """Normalised outputs (len(rows), O) of windows X[rows], the state carried through the whole
    sequences (bounds) that hold `rows` (the state needs their history)."""
    starts = np.array([a for a, _ in bounds])
    seqs = np.unique(np.searchsorted(starts, rows, side="right") - 1)
    idx = np.concatenate([np.arange(*bounds[k]) for k in seqs]) if len(seqs) else np.zeros(0, np.int64)
    local, pos = [], 0
    for k in seqs:
        a, b = bounds[k]
        local.append((pos, pos + b - a))
        pos += b - a
    net.eval()
    with torch.inference_mode():
        h = torch.cat([net.trunk(torch.from_numpy(X[idx[a:a + 8192]])) for a in range(0, len(idx), 8192)]) \
            if len(idx) else torch.zeros((0, net.trunk_width))
        y, _ = net.decode(h, local)
    where = np.full(len(X), -1, dtype=np.int64)
    where[idx] = np.arange(len(idx))
    return y[where[rows]]


class BranchRecipe(WindowRecipe):
    """The snap-aware FK's training (module docstring)."""

    def prepare(self, data: TrainingData) -> Prepared:
        prepared = super().prepare(data)
        ds, train = data.ds, self.rows["train"]
        n = ds.n_tubes
        joints = ds.joints()
        self.state, forced = branch_labels(joints[:, 0] - joints[:, n - 1], ds.frame["snap"].to_numpy(),
                                           self.bounds)
        state_prev = previous_labels(self.state, self.bounds)
        one_branch = offset_free_rows(joints[:, 0] - joints[:, n - 1], ds.frame["snap"].to_numpy(), train,
                                      self.bounds)
        self.batch = BranchBatch(torch.from_numpy(self.state[train].astype(np.float32)),
                                 torch.from_numpy(state_prev[train]), torch.from_numpy(forced[train]),
                                 torch.from_numpy(one_branch[train].astype(np.float32)),
                                 torch.from_numpy(near_switch(self.state, self.bounds)[train]),
                                 self.cfg.unknown_prob, self.cfg.gate_weight, self.pose_loss)
        return prepared

    def loss(self, net: torch.nn.Module, x: torch.Tensor, y: torch.Tensor, idx: torch.Tensor,
             gen: torch.Generator) -> torch.Tensor:
        assert isinstance(net, BranchNet)
        return self.batch.loss(net, x, y, idx, gen)

    def predict_rows(self, net: torch.nn.Module, rows: np.ndarray, X: np.ndarray | None = None
                     ) -> np.ndarray:
        assert isinstance(net, BranchNet)
        return decode_rows(net, self.X if X is None else X, rows, self.bounds)

    def finish(self, bundle: ModelBundle, folder: Path, log: Log) -> dict[str, Any]:
        log("tabulating the nominal robot's folds for the fold gate")
        gate = fold_gate(self.data.ds, self.rows["train"], self.cfg.fold_scale)
        metrics = super().finish(bundle, folder, log)    # the frame's field settled before the choice
        choice = self.gate_choice(bundle, gate)
        if choice is not None:
            metrics["gate"] = choice.to_dict()
            used = "fold gate" if choice.use_fold else "learned gate"
            log(f"gate on the validation rows: fold {choice.fold_mm:.3f} mm, learned {choice.learned_mm:.3f} "
                f"mm, learned better in {100 * choice.p_learned_better:.0f} % of resamples:"
                f" {used} used")
            gate = replace(gate, in_use=choice.use_fold)
        gate.save(folder)
        return metrics

    def gate_choice(self, bundle: ModelBundle, gate: FoldGate) -> GateChoice | None:
        """Fold against learned gate on the validation rows (ctrkin.families.snap_aware.gate_choice),
        each predicted along the whole dataset; None without validation rows."""
        val = self.rows["val"]
        if len(val) == 0:
            return None
        ds = self.data.ds
        target = inputs_and_targets(ds, "fk", self.cfg.pose_source)[1]
        return judge_gates(SnapAwarePredictor(bundle, gate), ds, val, target)


def fold_gate(ds: Any, rows: np.ndarray, fold_scale: bool = False) -> FoldGate:
    """The fold gate of a snap-aware model (ctrkin.families.snap_aware.fold_gate): folds of the
    dataset's nominal robot over the translations of `rows` (the training rows, sorted), fitted to
    their snaps; the outer tube's last rotation and the slide memory's lags are followed over the
    whole dataset (runs cross the split), and the runs are the slide memory's cross-validation folds;
    fold_scale: also fit the folds' scale g (fold_gate module docstring; the recommended FK's)."""
    f = ds.frame
    q = ds.joints()
    motion, _ = recorded_motion(f, q, ds.sequence_bounds(), ds.n_tubes)
    slide = slide_lags(ds, q, ds.sequence_bounds(), ds.n_tubes)
    runs = (f["run"] if "run" in f.columns else f["sequence_id"]).to_numpy()
    bounds = sequence_bounds(f["sequence_id"].to_numpy()[rows])
    return build_fold_gate(ds.robot, q[rows], f["snap"].to_numpy()[rows], bounds, motion[rows],
                           slide=slide[rows], groups=runs[rows], fold_scale=fold_scale)
