"""Benchmark: does the FK network see the robot's torsional hysteresis through generic memory
features? (issue 21, goal 1's FK; docs/learned_kinematics.md: What the learned models assume about
the robot).

    python benchmarks/bench_memory.py --data out/reproduce/data/paper
    python benchmarks/bench_memory.py --data ... --arms ib2,ib2+play --max-epochs 20
    python benchmarks/bench_memory.py --data ... --arms state,state+play,ib2,ib2+play,ib8 --seed 0,1

With friction between the tubes at the top of its range the tip's state after a reversal depends on
how far each tube has turned since (hysteresis loops tens of degrees of base rotation wide), which a
window of IB = 2 steps cannot see. The arms, trained with one recipe on one split and compared on
the held-out (test) sequences against the virtual robot's true pose:

  ib2        the paper's features (α1..αN, β1..βN, α0, Δα0; ctrkin.models.features) in windows of 2
  ib2+play   the same plus, appended to every step, the play-operator lags (a Prandtl–Ishlinskii
             basis; ctrkin.families.snap_aware.play) of α1 and αN (half widths ANGLE_WIDTHS deg) and
             of the relative translation d = βN − β1 (SLIDE_WIDTHS mm), carried along each run (the
             `run` column) from the commanded joints only: no friction law or simulator parameter
             enters them, so a robot computes them the same way
  ib8        the paper's features in windows of 8 (a longer memory without a model of it)
  ib8+play   both
  state      an LSTM whose state is carried over each whole recorded run from its first step, the
             paper's per-step features as inputs, trained by stateful truncated backpropagation
             through time (benchmarks/memory_state.py): a memory that does not depend on a window
  state+play the same with the play lags among its inputs
  ib2+tcm    ib2 with a physics prior among its inputs: the tip pose (6 columns, tracker frame) of the
             TCM calibrated on the training rows (`ctrkin calibrate` as `reproduce` runs it: every
             group and μ, ctrkin.calibration) and followed along each whole run with its friction
             state (CalibratedTCM.predict_continued over the `run` column's runs)
  ib2+play+tcm, ib8+tcm   the same prior as inputs with the play lags / windows of 8
  ib2+tcmres ib2 learning the residual of that prior: the position target is the recorded position
             less the prior's (the orientation is learned as in ib2) and the prior is added back
  ib2+play+tcmres, ib8+tcmres   the same residual with the play lags / windows of 8
  ib2+play+tcmboth   the residual, and the prior's poses also among the inputs: what the prior misses
             that depends on where the tip is (the tracker's field) becomes a function of the prior's
             position, not of the joints
  tcm        the prior alone (no network): what the residual arms start from

Every arm is also scored where the paper protocol never records: on the held-out sweeps (the
dataset folder `sweeps` beside --data, the inner tube slid between levels) and along the mid-turn
reversals of bench_generalisation.py, recorded here on the virtual robot the data was recorded on
(rebuilt from its meta.json); position RMSE (and max) against the noise-free truth. A memory that
wins on the held-out paper rows but loses along the reversals is not a win (IB 8, bench_fk_memory.py).

The recipe is the paper's LSTM-MLP (ctrkin.models.recipe.WindowRecipe; structure "paper"): Adam,
MAE, min-max on the training rows, early stopping on the validation loss, with the settings of
`--recipe` (a model folder's config.json, e.g. the reproduction's fk_lstm_mlp; default: the quick
reproduction's: lr 1e-3, batch 64, at most 150 epochs, patience 15). Only the input columns and IB
differ between arms; each arm starts from the same seed. Training runs here (not through
ctrkin.training.train, whose layouts have no extra columns) with the engine's own epoch,
learning-rate and early-stopping functions.

Prints a table (arm, seed, epochs, train / val / test position RMSE vs truth in mm, sweeps RMSE,
reversals RMSE / max, training seconds, the network's streaming step in µs (torch, one thread, the
network alone: a window arm runs IB LSTM updates from zero per prediction, a state arm one update from
its carried state), load) and ends with one JSON line of the figures.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import torch

from ctrkin.data.dataset import Dataset
from ctrkin.data.tracker_view import recorded_tracker_view
from ctrkin.evaluation.datasets import registered_truth, with_training_runs
from ctrkin.families.registry import build_model
from ctrkin.families.snap_aware.play import dataset_lags
from ctrkin.metrics import position_error
from ctrkin.models.features import delta_columns, postprocess, sequence_features, windows
from ctrkin.models.normalize import MinMax
from ctrkin.models.recipe import Prepared, TrainingData, WindowRecipe, predict_windows
from ctrkin.models.store import ModelBundle
from ctrkin.training.config import TrainConfig
from ctrkin.training.data import split_rows
from ctrkin.training.engine import _early_stopping, _epoch_gathered, _learning_rate, _optimizer
from ctrkin.virtual.truth import virtual_from_meta

sys.path.insert(0, str(Path(__file__).resolve().parent))   # the benchmarks beside this one
from memory_state import network_step_us, train_state

ANGLE_WIDTHS = (2.0, 5.0, 15.0, 45.0, 90.0)     # deg: half widths of the α1, αN play operators
SLIDE_WIDTHS = (0.05, 0.2, 1.0)                 # mm: of d = βN − β1
# arm -> (IB, play lags, the calibrated TCM prior: None, "input" or "residual"); IB 0: the state
# carried over the run
ARMS: dict[str, tuple[int, bool, str | None]] = {
    "ib2": (2, False, None), "ib2+play": (2, True, None), "ib8": (8, False, None),
    "ib8+play": (8, True, None), "state": (0, False, None), "state+play": (0, True, None),
    "ib2+tcm": (2, False, "input"), "ib2+play+tcm": (2, True, "input"), "ib8+tcm": (8, False, "input"),
    "ib2+tcmres": (2, False, "residual"),
    "ib2+play+tcmres": (2, True, "residual"), "ib8+tcmres": (8, False, "residual"),
    "ib2+play+tcmboth": (2, True, "both"),
    "tcm": (0, False, "alone")}
# the quick reproduction's paper LSTM-MLP (its models/fk_lstm_mlp/config.json)
QUICK_RECIPE = {"model": "lstm_mlp", "options": {"structure": "paper"}, "lr": 1e-3, "batch_size": 64,
                "max_epochs": 150, "patience": 15, "min_steps": 10000, "patience_steps": 1000,
                "threads": 1, "loop": "epoch", "lr_schedule": "constant", "target_frame": "tracker"}


def play_columns(ds: Dataset) -> np.ndarray:
    """(T, 2K + J) play lags of α1 (K), αN (K) and d (J) along each run (fractions of each width)."""
    lg = dataset_lags(ds, ANGLE_WIDTHS, SLIDE_WIDTHS)
    return np.concatenate([lg.inner, lg.outer, lg.slide], axis=1)


class MemoryRecipe(WindowRecipe):
    """The paper's recipe with extra per-step input columns `extra` (T, E) appended after the
    paper's features (so that Δα0 keeps its index and its clipping at evaluation), min-max fitted
    on the training rows with them; with `prior` (T, 6) tracker-frame poses the network learns the
    position's residual from the prior's (target x, y, z less the prior's, min-max refitted; the
    orientation as without it) and `to_world` adds the prior back."""

    def __init__(self, cfg: TrainConfig, extra: np.ndarray | None, prior: np.ndarray | None = None) -> None:
        super().__init__(cfg)
        self.extra = extra
        self.prior = prior

    def prepare(self, data: TrainingData) -> Prepared:
        prepared = super().prepare(data)
        if self.prior is not None:
            if self.frame is not None:
                raise ValueError("a residual arm needs the tracker frame as its target frame")
            self.target = self.target.copy()
            self.target[:, :3] -= self.prior[:, :3]
            self.y_norm = MinMax.fit(self.target[self.rows["train"]])
            self.Y = self.y_norm.transform(self.target).astype(np.float32)
            self.Yt = torch.from_numpy(self.Y[self.rows["train"]])
            prepared = replace(prepared, y_norm=self.y_norm)
        if self.extra is None:
            return prepared
        net_in = self.raw_in if self.frame is None else self.frame.network_joints(self.raw_in, self.outer_deg)
        feats = np.concatenate([sequence_features(self.layout, net_in, self.bounds), self.extra], axis=1)
        self.x_norm = MinMax.fit(feats[self.rows["train"]])
        self.X = windows(self.x_norm.transform(feats), self.bounds, self.layout.ib).astype(np.float32)
        self.Xt = torch.from_numpy(self.X[self.rows["train"]])
        return replace(prepared, x_norm=self.x_norm)

    def to_world(self, pred: np.ndarray, rows: np.ndarray) -> np.ndarray:
        out = super().to_world(pred, rows)
        if self.prior is None:
            return out
        out = np.array(out, dtype=np.float64, copy=True)
        out[:, :3] += self.prior[rows, :3]
        return out


Prior = Callable[[Dataset], np.ndarray]     # a dataset -> (T, 6) tracker-frame poses of a physics model


def tcm_prior(paper: Dataset) -> tuple[Prior, dict[str, Any]]:
    """The calibrated TCM as a prior, as `ctrkin train --tcm-prior` makes it (ctrkin.models.tcm_prior:
    `calibrate_prior` on the paper data's training rows, reproduce's quick budget, every group and μ),
    then a dataset -> its poses followed along each whole run with the friction state (`dataset_prior`:
    runs from rest, as recorded; a row where no equilibrium converged takes the row before it).
    Returns the prior and the calibration's figures."""
    from ctrkin.models.tcm_prior import calibrate_prior, dataset_prior

    t0 = time.perf_counter()
    cal = calibrate_prior(paper, paper.get_split().train)
    info = {"seconds": time.perf_counter() - t0, "friction": cal.robot.friction}
    done: dict[int, np.ndarray] = {}      # by dataset: each is followed once however many arms use it

    def prior(ds: Dataset) -> np.ndarray:
        if id(ds) not in done:
            done[id(ds)] = dataset_prior(cal, ds)
        return done[id(ds)]

    return prior, info


Predict = Callable[[Dataset], np.ndarray]      # a trained arm: a dataset -> (T, 6) poses, tracker frame


def train_arm(ds: Dataset, cfg: TrainConfig, extra: np.ndarray | None) -> dict[str, Any]:
    """Train one window arm (module docstring) and return its epochs, seconds and RMSE vs truth per part."""
    return train_window(ds, cfg, extra)[0]


def window_predict(rec: MemoryRecipe, net: torch.nn.Module, play: bool, prior: Prior | None = None,
                   prior_input: bool = False, prior_residual: bool | None = None) -> Predict:
    """A trained window arm on another dataset: its features (and play lags, and the prior's poses
    where they are inputs), the training's min-max, Δα0 clipped to its training range (as `evaluate`
    and `Kinematics.predict` clip it), windows of IB steps within each sequence; a residual arm adds
    the prior's position (prior_residual; default: a prior that is not an input)."""
    residual = prior is not None and (not prior_input if prior_residual is None else prior_residual)

    def predict(ds: Dataset) -> np.ndarray:
        bounds = ds.sequence_bounds()
        feats = sequence_features(rec.layout, ds.joints(), bounds)
        base = None if prior is None else prior(ds)
        if play:
            feats = np.concatenate([feats, play_columns(ds)], axis=1)
        if prior_input:
            assert base is not None
            feats = np.concatenate([feats, base], axis=1)
        x = rec.x_norm.transform(feats)
        dcols = delta_columns(rec.layout)
        x[:, dcols] = np.clip(x[:, dcols], 0.0, 1.0)
        X = windows(x, bounds, rec.layout.ib).astype(np.float32)
        yn = predict_windows(net, X, np.arange(len(X)))
        out = postprocess(rec.layout, rec.y_norm.inverse(yn))
        if residual:
            assert base is not None
            out[:, :3] += base[:, :3]
        return out
    return predict


def prior_alone(ds: Dataset, cfg: TrainConfig, prior: Prior) -> tuple[dict[str, Any], Predict]:
    """The `tcm` arm: the prior's position RMSE vs truth on the split's rows, as train_window reports
    an arm's (the noise-free tracker view, `recorded_tracker_view`, else the true pose columns, as
    WindowRecipe.evaluate), and the prior as its Predict."""
    _, rows = split_rows(ds, cfg)
    truth = recorded_tracker_view(ds)
    if truth is None:
        truth = ds.poses(true=True)
    poses = prior(ds)
    out: dict[str, Any] = {"inputs": 0, "epochs": 0, "best_epoch": 0, "seconds": 0.0,
                           "load": os.getloadavg()[0], "step_us": math.nan}
    for part in ("train", "val", "test"):
        if len(rows[part]):
            e = position_error(poses[rows[part]], truth[rows[part]])
            out[part] = float(np.sqrt(np.mean(e ** 2)))
    return out, prior


def train_window(ds: Dataset, cfg: TrainConfig, extra: np.ndarray | None, prior: Prior | None = None,
                 prior_mode: str | None = None, play: bool | None = None) -> tuple[dict[str, Any], Predict]:
    """train_arm's figures and the trained arm as a Predict. prior, prior_mode: the physics prior and
    how the arm uses it ("input": its poses are extra columns, after `extra`; "residual": the network
    learns the position's residual); play: the arm's extra columns hold the play lags (default:
    `extra` is given)."""
    play = extra is not None if play is None else play
    base = None if prior is None else prior(ds)
    if prior_mode in ("input", "both"):
        assert base is not None
        extra = base if extra is None else np.concatenate([extra, base], axis=1)
    torch.set_num_threads(cfg.threads)
    split, rows = split_rows(ds, cfg)
    n_train = len(rows["train"])
    cfg = replace(cfg, max_epochs=cfg.epoch_budget(n_train))
    assert cfg.max_epochs is not None
    rec = MemoryRecipe(cfg, extra, base if prior_mode in ("residual", "both") else None)
    prep = rec.prepare(TrainingData(ds, cfg, split, rows))
    n_in = rec.X.shape[2]
    torch.manual_seed(cfg.seed)
    bundle = ModelBundle.create(cfg.to_dict(), prep.layout, prep.x_norm, prep.y_norm, ds.robot,
                                build=lambda c, lay: build_model(c.model, n_in, lay.n_outputs, lay.ib,
                                                                 c.output_activation, c.options))
    net = bundle.net
    opt, gen = _optimizer(net, cfg), torch.Generator().manual_seed(cfg.seed)
    patience = cfg.patience_epochs(n_train)
    state: dict[str, Any] = {"epoch": 0, "best_val": float("inf"), "best_epoch": 0, "since_best": 0}
    best = {k: v.clone() for k, v in net.state_dict().items()}
    t0 = time.perf_counter()
    while state["epoch"] < cfg.max_epochs and state["since_best"] < patience:
        for group in opt.param_groups:
            group["lr"] = _learning_rate(cfg, state["epoch"], cfg.max_epochs)
        X, Y = rec.epoch_tensors(state["epoch"], bundle)
        _epoch_gathered(net, opt, X, Y, cfg.batch_size, gen, rec.loss)
        val = rec.val_loss(net)
        state["epoch"] += 1
        if _early_stopping(state, val, cfg):
            best = {k: v.detach().clone() for k, v in net.state_dict().items()}
    seconds = time.perf_counter() - t0
    net.load_state_dict(best)
    net.eval()
    metrics = rec.evaluate(bundle)
    window = torch.from_numpy(rec.X[:1])
    return ({"inputs": n_in, "epochs": state["epoch"], "best_epoch": state["best_epoch"], "seconds": seconds,
             "load": os.getloadavg()[0], "step_us": network_step_us(lambda: net(window)),
             # against the truth where the data has it (a virtual robot's), else the measured poses
             **{part: metrics[part].get("vs_true", metrics[part]["vs_measured"])["position_mm_rmse"]
                for part in ("train", "val", "test") if part in metrics}},
            window_predict(rec, net, play, prior if prior_mode else None, prior_mode in ("input", "both"),
                           prior_mode in ("residual", "both")))


@dataclass(frozen=True)
class HeldOut:
    """Recorded data outside the paper protocol: the dataset, its noise-free tracker view of the
    truth (T, 6), the rows scored (not glitches)."""

    name: str
    ds: Dataset
    truth: np.ndarray
    keep: np.ndarray


def held_out_sets(data: Path, ds: Dataset, reversals: bool) -> list[HeldOut]:
    """The sweeps beside `data` (if recorded) and, with `reversals`, the mid-turn reversals recorded
    on the virtual robot `ds` was recorded on."""
    sets = []
    sweeps = data.parent / "sweeps"
    if (sweeps / "meta.json").is_file():
        sw = Dataset.load(sweeps)
        sets.append(HeldOut("sweeps", sw, registered_truth(sw), ~sw.frame["outlier"].to_numpy()))
    if reversals:
        from bench_generalisation import reversal_data

        rev, truth, keep = reversal_data(ds.robot, virtual_from_meta(ds))
        sets.append(HeldOut("reversals", rev, truth, keep))
    return sets


def score(predict: Predict, sets: list[HeldOut]) -> dict[str, float]:
    """Position RMSE and max (mm) vs truth of a trained arm on each held-out set."""
    out = {}
    for h in sets:
        e = position_error(np.asarray(predict(h.ds), float)[h.keep], h.truth[h.keep])
        out[f"{h.name}_rmse"], out[f"{h.name}_max"] = float(np.sqrt(np.mean(e ** 2))), float(e.max())
    return out


def recipe_config(path: Path | None, max_epochs: int | None) -> TrainConfig:
    """The arms' common recipe: a model folder's config.json (`train`), else QUICK_RECIPE."""
    d = dict(QUICK_RECIPE)
    if path is not None:
        d = json.loads(path.read_text())["train"]
    cfg = TrainConfig.from_dict(d)
    cfg = replace(cfg, task="fk", split="dataset", device="cpu")
    return cfg if max_epochs is None else replace(cfg, max_epochs=max_epochs)


def main(argv: list[str] | None = None) -> dict[str, Any]:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, required=True, help="a paper-protocol dataset folder (its "
                    "split.json is the split), e.g. a reproduction's data/paper")
    ap.add_argument("--recipe", type=Path, default=None, help="a model folder's config.json whose training "
                    "settings every arm uses (default: the quick reproduction's paper LSTM-MLP)")
    ap.add_argument("--arms", default="ib2,ib2+play,ib8", help=f"comma-separated, of {sorted(ARMS)}")
    ap.add_argument("--max-epochs", type=int, default=None, help="cap every arm's epochs (a smoke run)")
    ap.add_argument("--seed", default=None, help="the arms' training seeds, comma-separated, each arm "
                    "trained once per seed (default: the recipe's)")
    ap.add_argument("--extra", type=Path, default=None, help="a dataset folder recorded on the same "
                    "virtual robot whose rows every arm also trains on, as training rows only (e.g. the "
                    "reproduction's data/excitation; ctrkin.evaluation.datasets.with_training_runs)")
    ap.add_argument("--no-reversals", action="store_true", help="do not record and score the mid-turn "
                    "reversals (the sweeps beside --data are still scored)")
    args = ap.parse_args(argv)
    arms = [a.strip() for a in args.arms.split(",") if a.strip()]
    unknown = sorted(set(arms) - set(ARMS))
    if unknown:
        ap.error(f"unknown arms {unknown}; choose from {sorted(ARMS)}")
    ds = Dataset.load(args.data)
    if ds.split is None:
        ap.error(f"{args.data} has no split.json: the arms must be compared on a saved split")
    if not ds.has_truth:
        ap.error(f"{args.data} has no true pose columns (a virtual robot's data is needed)")
    if args.extra is not None:
        ds = with_training_runs(ds, Dataset.load(args.extra))
    base = recipe_config(args.recipe, args.max_epochs)
    seeds = [base.seed] if args.seed is None else [int(s) for s in str(args.seed).split(",") if s.strip()]
    lags = play_columns(ds)
    prior: Prior | None = None
    if any(ARMS[a][2] for a in arms):
        prior, cal_info = tcm_prior(Dataset.load(args.data))
        print(f"calibrated TCM prior: μ {cal_info['friction']:.3f}, {cal_info['seconds']:.0f} s", flush=True)
    t0 = time.perf_counter()
    sets = held_out_sets(args.data, ds, not args.no_reversals)
    print(f"memory features on {args.data}{f' + {args.extra} (training rows)' if args.extra else ''}: "
          f"{len(ds.frame)} rows, recipe {base.model} {base.options} "
          f"lr {base.lr} batch {base.batch_size} max_epochs {base.max_epochs} patience {base.patience} "
          f"seeds {seeds}; play widths {ANGLE_WIDTHS} deg, {SLIDE_WIDTHS} mm; held out beyond the protocol: "
          f"{[f'{h.name} ({int(h.keep.sum())} rows)' for h in sets]} ({time.perf_counter() - t0:.0f} s)",
          flush=True)
    print(f"{'arm':10s} {'seed':>4s} {'inputs':>6s} {'epochs':>6s} {'best':>5s} {'train':>7s} {'val':>7s} "
          f"{'test':>7s} {'sweeps':>7s} {'rev':>6s} {'revmax':>6s} {'s':>6s} {'µs':>5s} {'load':>5s}   "
          f"(position RMSE vs truth, mm; s: training; µs: the network's streaming step)", flush=True)
    out: dict[str, list[dict[str, Any]]] = {}
    for seed in seeds:
        for arm in arms:
            ib, play, prior_mode = ARMS[arm]
            cfg = replace(base, seed=seed, ib=max(ib, 1))
            if arm.startswith("state"):
                r, model = train_state(ds, cfg, play_columns if play else None)
                predict: Predict = model.predict
            elif prior_mode == "alone":
                assert prior is not None
                r, predict = prior_alone(ds, cfg, prior)
            else:
                r, predict = train_window(ds, cfg, lags if play else None, prior, prior_mode, play)
            r = {"seed": seed, **r, **score(predict, sets)}
            out.setdefault(arm, []).append(r)
            print(f"{arm:10s} {seed:4d} {r['inputs']:6d} {r['epochs']:6d} {r['best_epoch']:5d} "
                  + " ".join(f"{r.get(k, math.nan):7.3f}" for k in ("train", "val", "test", "sweeps_rmse"))
                  + f" {r.get('reversals_rmse', math.nan):6.2f} {r.get('reversals_max', math.nan):6.2f}"
                  f" {r['seconds']:6.0f} {r['step_us']:5.0f} {r['load']:5.1f}", flush=True)
    report = {"data": str(args.data), "extra": None if args.extra is None else str(args.extra),
              "recipe": {"model": base.model, "options": base.options, "lr": base.lr,
                         "batch_size": base.batch_size, "max_epochs": base.max_epochs,
                         "patience": base.patience, "seeds": seeds},
              "angle_widths_deg": ANGLE_WIDTHS, "slide_widths_mm": SLIDE_WIDTHS,
              "held_out": {h.name: int(h.keep.sum()) for h in sets}, "arms": out}
    print(json.dumps(report, default=float))
    return report


if __name__ == "__main__":
    main()
