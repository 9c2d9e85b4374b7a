"""The `state` arms of benchmarks/bench_memory.py: an LSTM whose state is carried over each whole
recorded run, so that its memory does not depend on a window's length (issue 21, goal 1's FK;
docs/learned_kinematics.md: Memory of the recommended FK).

The network is the paper structure's layers (L128|D64: an LSTM of 128 units, a Dense ReLU layer of
64, the output with the recipe's output activation, paper eq. 3-7) applied at every step of a run, not
to a window: h_t, c_t = LSTM(x_t, h_{t-1}, c_{t-1}) from h_0 = c_0 = 0 at the run's first step, and
the pose at t from h_t alone. The inputs x_t are the paper's per-step features (α1..αN, β1..βN, α0,
Δα0; ctrkin.models.features, Δα0 = 0 at each sequence's first step as the window arms have it),
optionally with the play-operator lags (bench_memory.play_columns), min-max fitted on the training
rows, Δα0 clipped to its training range as `Kinematics.predict` clips it.

Training (truncated backpropagation through time with stored states): every run is cut into pieces
of CHUNK steps (the first piece of a random length in [1, CHUNK], drawn anew each epoch, so that the
cuts move). Each epoch first runs the state over every run from its first step with the current
weights and stores the state at every cut (this pass also gives the validation loss), then takes the
pieces that hold training rows in a random order, PIECES_PER_BATCH at a time, each started from its
stored state (no gradient across a cut), one Adam step per batch on the MAE of its training rows.
Walking the runs in time order instead (the state carried from piece to piece within the epoch) fits
the weights to each run's last sequences by the end of every epoch: the quick paper data has 4 runs,
so every batch would hold the same moment of the protocol. Validation and test rows inside a run are
stepped through (their commanded joints are inputs a robot would have) but never enter the loss.
Early stopping watches the MAE on the validation rows with the state run from each run's start,
exactly as it is evaluated: the held-out rows' poses come from the state carried from their run's
first step, as a robot streaming its joints would carry it.

What it assumes: nothing about friction or any simulator parameter; it needs the recorded runs to
start from a known state (rest, the same as every run's first step) and to be recorded without gaps,
since the state is everything the robot did since that first step.
"""

from __future__ import annotations

import itertools
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import torch
from torch import nn

from ctrkin.data.dataset import Dataset
from ctrkin.data.tracker_view import recorded_tracker_view
from ctrkin.metrics import metrics_json_pose_errors
from ctrkin.models.base import KinematicsNet
from ctrkin.models.features import FeatureLayout, delta_columns, postprocess, sequence_features
from ctrkin.models.normalize import MinMax
from ctrkin.models.recipe import inputs_and_targets
from ctrkin.models.tcm_prior import run_bounds
from ctrkin.training.config import TrainConfig
from ctrkin.training.data import split_rows
from ctrkin.training.engine import _early_stopping, _learning_rate, _optimizer

CHUNK = 128             # steps per truncated-BPTT chunk
PIECES_PER_BATCH = 2    # pieces of CHUNK steps per Adam step (256 rows)
HIDDEN, HEAD = 128, 64  # the paper structure L128|D64

State = tuple[torch.Tensor, torch.Tensor]


class StateNet(KinematicsNet):
    """x: (B, L, F) normalised features of L consecutive steps of B runs, state: (h, c) each
    (1, B, HIDDEN) or None (zeros: a run's first step) -> (y (B, L, O) normalised poses, state after
    the last step)."""

    def __init__(self, n_inputs: int, n_outputs: int, output_activation: str = "relu",
                 hidden: int = HIDDEN, head: int = HEAD) -> None:
        super().__init__(n_inputs, n_outputs, 1, output_activation)
        self.lstm = nn.LSTM(n_inputs, hidden, batch_first=True)     # eq. (3), (4), state carried
        self.head = nn.Linear(hidden, head)                          # eq. (6)
        self.out = nn.Linear(head, n_outputs)                        # eq. (7)
        self.init_output_bias()

    def forward(self, x: torch.Tensor, state: State | None = None) -> tuple[torch.Tensor, State]:
        h, state = self.lstm(x, state)
        return self.finish(self.out(torch.relu(self.head(h)))), state

    def step(self, x: torch.Tensor, state: State | None) -> tuple[torch.Tensor, State]:
        """One streaming step: x (B, F) -> (y (B, O), the state to give the next step)."""
        y, state = self(x[:, None, :], state)
        return y[:, 0], state


def padded(values: np.ndarray, runs: list[tuple[int, int]]) -> np.ndarray:
    """(R, L, C) float32 of (T, C) rows laid out by run, each padded with zeros at its end
    (L the longest run)."""
    out = np.zeros((len(runs), max(b - a for a, b in runs), values.shape[1]), np.float32)
    for i, (a, b) in enumerate(runs):
        out[i, :b - a] = values[a:b]
    return out


def predict_runs(net: StateNet, X: np.ndarray, runs: list[tuple[int, int]]) -> np.ndarray:
    """(T, O) normalised outputs of every row of X (T, F), the state run from zero at each run's
    first row (all runs side by side; padding only ever follows a run's rows)."""
    net.eval()
    with torch.inference_mode():
        y, _ = net(torch.from_numpy(padded(X, runs)))
    y_np = y.numpy()
    out = np.empty((len(X), y_np.shape[2]), np.float32)
    for i, (a, b) in enumerate(runs):
        out[a:b] = y_np[i, :b - a]
    return out


@dataclass
class StateModel:
    """A trained state arm: the net, the feature layout and the min-max steps, and whether the play
    lags are among its inputs (`lags`: the function that gives them for a dataset, or None)."""

    net: StateNet
    layout: FeatureLayout
    x_norm: MinMax
    y_norm: MinMax
    lags: Callable[[Dataset], np.ndarray] | None

    def inputs(self, ds: Dataset) -> np.ndarray:
        """(T, F) normalised inputs, Δα0 clipped to its training range."""
        feats = sequence_features(self.layout, ds.joints(), ds.sequence_bounds())
        if self.lags is not None:
            feats = np.concatenate([feats, self.lags(ds)], axis=1)
        X = self.x_norm.transform(feats).astype(np.float32)
        dcols = delta_columns(self.layout)
        X[:, dcols] = np.clip(X[:, dcols], 0.0, 1.0)
        return X

    def predict(self, ds: Dataset) -> np.ndarray:
        """(T, 6) poses in the tracker frame, each run streamed from its first row."""
        yn = predict_runs(self.net, self.inputs(ds), run_bounds(ds))
        return postprocess(self.layout, self.y_norm.inverse(yn))


def network_step_us(step: Callable[[], object], n: int = 300) -> float:
    """Median µs of one streaming step of a network alone (torch, no grad, the calling thread count;
    no features, normalisation or checks): `step` makes one prediction."""
    times = []
    with torch.inference_mode():
        for _ in range(n):
            t0 = time.perf_counter()
            step()
            times.append(time.perf_counter() - t0)
    return float(np.median(times) * 1e6)


def state_step_us(net: StateNet, n_inputs: int) -> float:
    """network_step_us of a state net: one LSTM update from the carried state, then the head."""
    x = torch.full((1, n_inputs), 0.5)
    carried: list[State | None] = [None]

    def step() -> None:
        _, carried[0] = net.step(x, carried[0])
    return network_step_us(step)


def _cuts(n: int, first: int) -> np.ndarray:
    """Piece edges (K + 1,) of n steps: the first piece `first` steps long, the rest CHUNK."""
    return np.unique(np.r_[0, np.arange(min(first, n), n, CHUNK), n])


def _stored_states(net: StateNet, Xp: torch.Tensor, edges: np.ndarray) -> tuple[torch.Tensor, State]:
    """Every run from its first step, no gradient: the outputs (R, L, O) and the state at the start of
    each piece, (h, c) each (K, R, HIDDEN) (zeros for the first)."""
    h = torch.zeros(len(edges) - 1, Xp.shape[0], net.lstm.hidden_size)
    c = torch.zeros_like(h)
    outs, state = [], None
    net.eval()
    with torch.no_grad():
        for k, (a, b) in enumerate(itertools.pairwise(edges)):
            if state is not None:
                h[k], c[k] = state[0][0], state[1][0]
            y, state = net(Xp[:, a:b], state)
            outs.append(y)
    return torch.cat(outs, 1), (h, c)


def train_state(ds: Dataset, cfg: TrainConfig, lags: Callable[[Dataset], np.ndarray] | None
                ) -> tuple[dict[str, Any], StateModel]:
    """Train one state arm (module docstring); its epochs, seconds and RMSE vs truth per part
    (as bench_memory.train_arm reports them), and the model."""
    torch.set_num_threads(cfg.threads)
    _, rows = split_rows(ds, cfg)
    n_train = len(rows["train"])
    cfg = replace(cfg, max_epochs=cfg.epoch_budget(n_train))
    assert cfg.max_epochs is not None and cfg.task == "fk" and cfg.target_frame == "tracker"
    layout = cfg.layout(ds.n_tubes)
    _, target = inputs_and_targets(ds, cfg.task, cfg.pose_source)
    feats = sequence_features(layout, ds.joints(), ds.sequence_bounds())
    if lags is not None:
        feats = np.concatenate([feats, lags(ds)], axis=1)
    x_norm, y_norm = MinMax.fit(feats[rows["train"]]), MinMax.fit(target[rows["train"]])
    torch.manual_seed(cfg.seed)
    model = StateModel(StateNet(feats.shape[1], target.shape[1], cfg.output_activation), layout, x_norm,
                       y_norm, lags)
    net = model.net
    runs = run_bounds(ds)
    X = model.inputs(ds)
    Y = y_norm.transform(target).astype(np.float32)
    masks = {}
    for part in ("train", "val"):
        used = np.zeros((len(ds.frame), 1), np.float32)
        used[rows[part]] = 1.0
        masks[part] = torch.from_numpy(padded(used, runs))[..., 0]    # (R, L)
    Xp, Yp = torch.from_numpy(padded(X, runs)), torch.from_numpy(padded(Y, runs))
    length = Xp.shape[1]
    opt, gen = _optimizer(net, cfg), torch.Generator().manual_seed(cfg.seed)
    patience = cfg.patience_epochs(n_train)
    st: dict[str, Any] = {"epoch": 0, "best_val": float("inf"), "best_epoch": 0, "since_best": 0}
    best = {k: v.clone() for k, v in net.state_dict().items()}
    mv = masks["val"]
    t0 = time.perf_counter()
    while True:
        edges = _cuts(length, int(torch.randint(1, CHUNK + 1, (1,), generator=gen)))
        yv, (h0, c0) = _stored_states(net, Xp, edges)       # this epoch's stored states
        if st["epoch"] > 0:                                 # the last epoch's validation
            val = float(((yv - Yp).abs().mean(-1) * mv).sum() / mv.sum())
            if _early_stopping(st, val, cfg):
                best = {k: v.detach().clone() for k, v in net.state_dict().items()}
        if st["epoch"] >= cfg.max_epochs or st["since_best"] >= patience:
            break
        for group in opt.param_groups:
            group["lr"] = _learning_rate(cfg, st["epoch"], cfg.max_epochs)
        net.train()
        mt = masks["train"]
        pieces = [(r, k) for k, (a, b) in enumerate(itertools.pairwise(edges))
                  for r in range(len(runs)) if mt[r, a:b].sum() > 0]
        order = torch.randperm(len(pieces), generator=gen).tolist()
        for g in range(0, len(order), PIECES_PER_BATCH):
            batch = [pieces[i] for i in order[g:g + PIECES_PER_BATCH]]
            x = torch.zeros(len(batch), CHUNK, Xp.shape[2])
            y = torch.zeros(len(batch), CHUNK, Yp.shape[2])
            m = torch.zeros(len(batch), CHUNK)
            for i, (r, k) in enumerate(batch):
                a, b = int(edges[k]), int(edges[k + 1])
                x[i, :b - a], y[i, :b - a], m[i, :b - a] = Xp[r, a:b], Yp[r, a:b], mt[r, a:b]
            rr = torch.tensor([r for r, _ in batch])
            kk = torch.tensor([k for _, k in batch])
            out, _ = net(x, (h0[kk, rr][None], c0[kk, rr][None]))
            err = (out - y).abs().mean(-1)                     # MAE (paper IV.A), per row
            loss = (err * m).sum() / m.sum()
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
        st["epoch"] += 1
    seconds = time.perf_counter() - t0
    net.load_state_dict(best)
    net.eval()
    pred = model.predict(ds)
    truth = recorded_tracker_view(ds) if cfg.pose_source == "measured" else None
    truth = ds.poses(true=True) if truth is None else truth
    result: dict[str, Any] = {"inputs": feats.shape[1], "epochs": st["epoch"], "best_epoch": st["best_epoch"],
                              "seconds": seconds, "load": os.getloadavg()[0],
                              "step_us": state_step_us(net, feats.shape[1])}
    for part in ("train", "val", "test"):
        if len(rows[part]):
            r = rows[part]
            result[part] = metrics_json_pose_errors(pred[r], truth[r])["position_mm_rmse"]
    return result, model
