"""Keeping the snap-aware FK or the paper's LSTM-MLP, as validation says (ctrkin.training.selection)."""

from __future__ import annotations

import json

import pytest

from ctrkin.errors import ModelError
from ctrkin.inference import Kinematics
from ctrkin.training import TrainConfig, train
from ctrkin.training.selection import candidate_configs, candidate_folder, choose, selects


def _cfg(**kw):
    return TrainConfig(task="fk", model="lstm_mlp_branch", max_epochs=2, patience=2, threads=1,
                       options={"structure": "L8|D8"}, batch_size=256, **{"select_by_validation": True, **kw})


def test_choose_keeps_the_lower_validation_error_and_the_requested_one_on_a_tie_or_without_figures():
    assert choose({"requested": 1.2, "paper": 0.9}) == "paper"
    assert choose({"requested": 0.9, "paper": 1.2}) == "requested"
    assert choose({"requested": 1.0, "paper": 1.0}) == "requested"
    assert choose({"requested": None, "paper": 0.5}) == "requested"
    assert choose({"requested": 0.5, "paper": None}) == "requested"


def test_what_a_selection_trains():
    cfg = _cfg(play_lags=True, joint_field=True, seed=3, lr=3e-3)
    cands = candidate_configs(cfg)
    assert cands["requested"] is cfg
    paper = cands["paper"]
    assert (paper.model, paper.angle_encoding, paper.target_frame, paper.output_activation) == \
        ("lstm_mlp", "sincos", "tracker", "relu")
    assert not (paper.play_lags or paper.joint_field or paper.tcm_prior)
    assert paper.options == TrainConfig(task="fk", model="lstm_mlp").options       # the paper's network
    assert (paper.seed, paper.split, paper.lr, paper.batch_size, paper.max_epochs, paper.ib) == \
        (3, cfg.split, 3e-3, 256, 2, cfg.ib)                                       # the same budget
    assert selects(cfg) and not selects(paper)
    assert not selects(_cfg(select_by_validation=False))
    with pytest.raises(ModelError, match="select_by_validation"):
        TrainConfig(task="ik", select_by_validation=True)


def test_the_model_validation_prefers_is_kept_whole_and_the_other_removed(sweeps, tmp_path):
    out = tmp_path / "fk"
    said: list[str] = []
    res = train(sweeps, _cfg(play_lags=True, joint_field=True), out, progress=False, log=said.append)
    sel = res.metrics["model_selection"]
    val = sel["val_position_rmse_mm"]
    assert sel["kept"] == choose(val) and set(val) == {"requested", "paper"}
    assert all(v is not None and v > 0 for v in val.values())
    saved = json.loads((out / "metrics.json").read_text())
    assert saved["model_selection"] == sel
    assert saved["val"]["vs_measured"]["position_mm_rmse"] == pytest.approx(val[sel["kept"]])
    trained = json.loads((out / "config.json").read_text())["train"]
    assert [trained[k] for k in ("model", "play_lags", "joint_field")] == \
        list(sel["candidates"][sel["kept"]].values())
    assert any("keeping the" in m for m in said)
    # the hidden candidates are gone: the kept one moved into out, the other removed
    assert not any(candidate_folder(out, n).exists() for n in ("requested", "paper"))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fk"]
    kin = Kinematics.load(out)                       # a complete model folder (manifest included)
    assert kin.predict(sweeps.joints()[:5]).shape == (5, 6)
    # the same selection again reuses the folder; another one needs overwrite, nothing touched before
    before = (out / "weights.pt").read_bytes()
    said.clear()
    again = train(sweeps, _cfg(play_lags=True, joint_field=True), out, progress=False, log=said.append)
    assert again.metrics == saved and any("reusing it" in m for m in said)
    for other in (_cfg(play_lags=True, joint_field=True, lr=5e-3), _cfg(play_lags=True, joint_field=True,
                                                                         seed=7)):
        with pytest.raises(ModelError, match="overwrite"):
            train(sweeps, other, out, progress=False)
    assert (out / "weights.pt").read_bytes() == before
    res2 = train(sweeps, _cfg(play_lags=True, joint_field=True, seed=1), out, overwrite=True, progress=False)
    assert res2.metrics["model_selection"]["kept"] in ("requested", "paper")


def test_without_selection_one_model_is_trained(sweeps, tmp_path):
    res = train(sweeps, _cfg(play_lags=True, select_by_validation=False), tmp_path / "fk", progress=False)
    assert "model_selection" not in res.metrics
