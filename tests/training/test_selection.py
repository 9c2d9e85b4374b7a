"""Selecting an FK's play lags and joint field by validation (ctrkin.training.selection)."""

from __future__ import annotations

import json

import pytest

from ctrkin.errors import ModelError
from ctrkin.inference import Kinematics
from ctrkin.training import TrainConfig, train
from ctrkin.training.selection import candidate_configs, candidate_folder, choose, selects_inputs


def _cfg(**kw):
    return TrainConfig(task="fk", model="lstm_mlp_branch", max_epochs=2, patience=2, threads=1,
                       options={"structure": "L8|D8"}, batch_size=256, **{"select_inputs": True, **kw})


def test_choose_keeps_the_lower_validation_error_and_the_requested_one_on_a_tie_or_without_figures():
    assert choose({"requested": 1.2, "plain": 0.9}) == "plain"
    assert choose({"requested": 0.9, "plain": 1.2}) == "requested"
    assert choose({"requested": 1.0, "plain": 1.0}) == "requested"
    assert choose({"requested": None, "plain": 0.5}) == "requested"
    assert choose({"requested": 0.5, "plain": None}) == "requested"


def test_what_a_selection_trains():
    cfg = _cfg(play_lags=True, joint_field=True)
    cands = candidate_configs(cfg)
    assert (cands["requested"].play_lags, cands["requested"].joint_field) == (True, True)
    assert (cands["plain"].play_lags, cands["plain"].joint_field) == (False, False)
    assert cands["plain"].seed == cfg.seed and cands["plain"].split == cfg.split
    assert selects_inputs(cfg) and not selects_inputs(cands["plain"])
    assert not selects_inputs(_cfg(play_lags=False, joint_field=False))   # nothing to select
    with pytest.raises(ModelError, match="select_inputs"):
        TrainConfig(task="ik", select_inputs=True)


def test_the_model_validation_prefers_is_kept_whole_and_the_other_removed(sweeps, tmp_path):
    out = tmp_path / "fk"
    said: list[str] = []
    res = train(sweeps, _cfg(play_lags=True, joint_field=True), out, progress=False, log=said.append)
    sel = res.metrics["input_selection"]
    val = sel["val_position_rmse_mm"]
    assert sel["kept"] == choose(val) and set(val) == {"requested", "plain"}
    assert all(v is not None and v > 0 for v in val.values())
    saved = json.loads((out / "metrics.json").read_text())
    assert saved["input_selection"] == sel
    assert saved["val"]["vs_measured"]["position_mm_rmse"] == pytest.approx(val[sel["kept"]])
    trained = json.loads((out / "config.json").read_text())["train"]
    assert (trained["play_lags"], trained["joint_field"]) == tuple(sel["candidates"][sel["kept"]].values())
    assert any("keeping the" in m for m in said)
    # the hidden candidates are gone: the kept one moved into out, the other removed
    assert not any(candidate_folder(out, n).exists() for n in ("requested", "plain"))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fk"]
    kin = Kinematics.load(out)                       # a complete model folder (manifest included)
    assert kin.predict(sweeps.joints()[:5]).shape == (5, 6)
    # a second selection into a folder that holds a model needs overwrite; nothing is touched before
    before = (out / "weights.pt").read_bytes()
    with pytest.raises(ModelError, match="overwrite"):
        train(sweeps, _cfg(play_lags=True, joint_field=True), out, progress=False)
    assert (out / "weights.pt").read_bytes() == before
    res2 = train(sweeps, _cfg(play_lags=True, joint_field=True, seed=1), out, overwrite=True, progress=False)
    assert res2.metrics["input_selection"]["kept"] in ("requested", "plain")


def test_without_selection_one_model_is_trained(sweeps, tmp_path):
    res = train(sweeps, _cfg(play_lags=True, joint_field=False, select_inputs=False), tmp_path / "fk",
                progress=False)
    assert "input_selection" not in res.metrics
