"""benchmarks/bench_memory.py: the play-lag columns fed beside the paper's FK features."""

from __future__ import annotations

import numpy as np
import pytest

from tests.benchmark_scripts import load_benchmark


@pytest.fixture(scope="module")
def bench():
    return load_benchmark("bench_memory")


def test_play_columns_follow_the_commanded_joints_only(bench, sweeps) -> None:
    cols = bench.play_columns(sweeps)
    k, j = len(bench.ANGLE_WIDTHS), len(bench.SLIDE_WIDTHS)
    assert cols.shape == (len(sweeps.frame), 2 * k + j)
    assert np.all(np.abs(cols) <= 1.0 + 1e-12)
    # the sweeps turn the inner tube: its narrowest play is taken up, the widest not always
    assert np.abs(cols[:, 0]).max() == pytest.approx(1.0)
    moved = sweeps.frame.copy()
    for c in ("x", "y", "z"):
        moved[c] = moved[c] + 5.0          # the tip's poses do not enter the features
    assert np.array_equal(bench.play_columns(type(sweeps)(moved, sweeps.robot, sweeps.meta)), cols)


def test_the_extra_columns_follow_the_paper_features_in_every_window(bench, sweeps) -> None:
    from ctrkin.models.recipe import TrainingData
    from ctrkin.training.data import split_rows

    cfg = bench.recipe_config(None, 1)
    cfg = type(cfg).from_dict({**cfg.to_dict(), "ib": 3})
    split, rows = split_rows(sweeps, cfg)
    extra = bench.play_columns(sweeps)
    plain = bench.MemoryRecipe(cfg, None)
    plain.prepare(TrainingData(sweeps, cfg, split, rows))
    rec = bench.MemoryRecipe(cfg, extra)
    rec.prepare(TrainingData(sweeps, cfg, split, rows))
    f = plain.X.shape[2]
    assert rec.X.shape == (*plain.X.shape[:2], f + extra.shape[1])
    np.testing.assert_allclose(rec.X[..., :f], plain.X[..., :f])      # Δα0 keeps its index
    lo, hi = extra[rows["train"]].min(axis=0), extra[rows["train"]].max(axis=0)
    want = (extra - lo) / np.where(hi > lo, hi - lo, 1.0)
    np.testing.assert_allclose(rec.X[:, -1, f:][:, hi > lo], want[:, hi > lo], atol=1e-5)   # min-max on train


def test_one_arm_trains_and_reports_rmse_vs_truth(bench, sweeps) -> None:
    cfg = bench.recipe_config(None, 1)
    cfg = type(cfg).from_dict({**cfg.to_dict(), "options": {"structure": "L16|D16"}})
    r = bench.train_arm(sweeps, cfg, bench.play_columns(sweeps))
    assert r["inputs"] == 6 + 13 and r["epochs"] == 1
    assert all(np.isfinite(r[p]) and r[p] > 0 for p in ("train", "val", "test"))


@pytest.fixture(scope="module")
def state_mod(bench):
    import sys

    return sys.modules["memory_state"]      # imported by bench_memory from beside it


def test_the_state_is_carried_along_a_run_and_reset_at_the_next(state_mod) -> None:
    import torch

    torch.manual_seed(0)
    net = state_mod.StateNet(5, 3, hidden=8, head=4)
    X = np.random.default_rng(0).uniform(0, 1, (23, 5)).astype(np.float32)
    runs = [(0, 9), (9, 23)]
    whole = state_mod.predict_runs(net, X, runs)
    # streaming one step at a time, the state from zero at each run's first step, gives the same poses
    stream = []
    with torch.inference_mode():
        for a, b in runs:
            state = None
            for t in range(a, b):
                y, state = net.step(torch.from_numpy(X[t:t + 1]), state)
                stream.append(y.numpy()[0])
    np.testing.assert_allclose(np.array(stream), whole, atol=1e-6)
    # a run's poses do not depend on the run before it; within a run the state carries the past
    Y = X.copy()
    Y[:3] += 0.5
    changed = state_mod.predict_runs(net, Y, runs)
    np.testing.assert_allclose(changed[9:], whole[9:], atol=1e-6)
    assert np.abs(changed[5:9] - whole[5:9]).max() > 1e-6


def test_one_state_arm_trains_and_predicts_as_it_scores(bench, state_mod, sweeps) -> None:
    cfg = bench.recipe_config(None, 1)
    r, model = state_mod.train_state(sweeps, cfg, bench.play_columns)
    assert r["inputs"] == 6 + 13 and r["epochs"] == 1
    assert all(np.isfinite(r[p]) and r[p] > 0 for p in ("train", "val", "test"))
    assert state_mod.run_bounds(sweeps) == sweeps.sequence_bounds()     # no `run` column: each sequence
    pred = model.predict(sweeps)
    assert pred.shape == (len(sweeps.frame), 6) and np.all(np.isfinite(pred))


def test_extra_rows_join_the_training_rows_only(bench, sweeps, tmp_path, capsys) -> None:
    """--extra DIR: every arm trains on the data's training rows plus DIR's rows; the validation and
    test rows are the data's (datasets.with_training_runs)."""
    import dataclasses

    data, extra = tmp_path / "paper", tmp_path / "excitation"
    ds = dataclasses.replace(sweeps, split=sweeps.get_split(seed=0))
    ds.save(data)
    sweeps.save(extra)
    report = bench.main(["--data", str(data), "--extra", str(extra), "--arms", "ib2", "--max-epochs", "1",
                         "--no-reversals"])
    out = capsys.readouterr().out
    assert report["extra"] == str(extra)
    assert f"{2 * len(sweeps.frame)} rows" in out and "(training rows)" in out
    assert report["arms"]["ib2"][0]["epochs"] == 1


def test_a_residual_arm_learns_the_position_less_the_prior_and_adds_it_back(bench, sweeps) -> None:
    from ctrkin.models.recipe import TrainingData
    from ctrkin.training.data import split_rows

    poses = sweeps.poses()
    shift = np.array([3.0, -1.0, 0.5, 0.0, 0.0, 0.0])

    def prior(ds):
        return ds.poses() + shift          # a prior off by a constant: the residual is that constant

    cfg = bench.recipe_config(None, 1)
    split, rows = split_rows(sweeps, cfg)
    rec = bench.MemoryRecipe(cfg, None, prior(sweeps))
    rec.prepare(TrainingData(sweeps, cfg, split, rows))
    np.testing.assert_allclose(rec.target[:, :3], -np.broadcast_to(shift[:3], (len(poses), 3)), atol=1e-9)
    np.testing.assert_array_equal(rec.target[:, 3:], poses[:, 3:])     # the orientation as without a prior
    train = rows["train"]
    back = rec.to_world(rec.y_norm.inverse(rec.Y[train].astype(float)), train)
    np.testing.assert_allclose(back[:, :3], poses[train, :3], atol=1e-3)

    cfg = type(cfg).from_dict({**cfg.to_dict(), "options": {"structure": "L16|D16"}})
    r, predict = bench.train_window(sweeps, cfg, None, prior, "residual")
    assert r["inputs"] == 6 and r["epochs"] == 1
    pred = predict(sweeps)
    # the network learns a near-constant residual: its predictions sit about the prior less the shift
    err = np.linalg.norm(pred[:, :3] - poses[:, :3], axis=1)
    assert np.all(np.isfinite(pred)) and np.median(err) < np.linalg.norm(shift[:3])


def test_a_prior_as_input_adds_its_pose_columns(bench, sweeps) -> None:
    cfg = bench.recipe_config(None, 1)
    cfg = type(cfg).from_dict({**cfg.to_dict(), "options": {"structure": "L16|D16"}})
    r, predict = bench.train_window(sweeps, cfg, None, lambda ds: ds.poses(), "input")
    assert r["inputs"] == 6 + 6
    assert predict(sweeps).shape == (len(sweeps.frame), 6)


def test_a_prior_as_input_and_residual_adds_its_columns_and_its_position(bench, sweeps) -> None:
    """`both` (ib2+play+tcmboth): the prior's poses among the inputs and its position added back."""
    shift = np.array([40.0, -30.0, 20.0, 0.0, 0.0, 0.0])
    wobble = np.random.default_rng(0).normal(0.0, 1.0, (len(sweeps.frame), 6)) * [1, 1, 1, 0, 0, 0]

    def prior(ds):
        return ds.poses() + shift + wobble     # the residual is -shift - wobble, a few mm wide

    cfg = bench.recipe_config(None, 1)
    cfg = type(cfg).from_dict({**cfg.to_dict(), "options": {"structure": "L16|D16"}})
    r, predict = bench.train_window(sweeps, cfg, None, prior, "both")
    assert r["inputs"] == 6 + 6
    err = np.linalg.norm(predict(sweeps)[:, :3] - sweeps.poses()[:, :3], axis=1)
    # the residual's range is about -shift: only with the prior's position added back are the
    # predictions near the poses (54 mm off without it)
    assert np.median(err) < 10.0 < np.linalg.norm(shift[:3])


def test_the_prior_alone_is_scored_against_the_noise_free_view(bench, sweeps) -> None:
    from ctrkin.data.tracker_view import recorded_tracker_view

    cfg = bench.recipe_config(None, 1)
    truth = recorded_tracker_view(sweeps)
    truth = sweeps.poses(true=True) if truth is None else truth
    exact, _ = bench.prior_alone(sweeps, cfg, lambda ds: truth)
    assert exact["val"] == pytest.approx(0.0, abs=1e-12) and exact["test"] == pytest.approx(0.0, abs=1e-12)
    off, _ = bench.prior_alone(sweeps, cfg, lambda ds: truth + np.array([0.0, 2.0, 0.0, 0.0, 0.0, 0.0]))
    assert off["val"] == pytest.approx(2.0) and off["epochs"] == 0
