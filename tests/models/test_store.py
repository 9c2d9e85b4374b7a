"""The model folder: typed configuration with unchanged JSON keys, the MinMax pre/post step."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from ctrkin.errors import ModelError
from ctrkin.families.registry import build_net
from ctrkin.models.normalize import MinMax
from ctrkin.models.store import ModelBundle, ModelConfig
from ctrkin.training.config import TrainConfig


def _bundle(robot, cfg: TrainConfig) -> ModelBundle:
    layout = cfg.layout(robot.n_tubes)
    rng = np.random.default_rng(0)
    x_norm = MinMax.fit(rng.normal(size=(20, layout.n_inputs)))
    y_norm = MinMax.fit(rng.normal(size=(20, layout.n_outputs)))
    torch.manual_seed(0)
    return ModelBundle.create(cfg.to_dict(), layout, x_norm, y_norm, robot, {"data": {"samples": 20}},
                              build=build_net)


def test_config_json_keeps_the_training_keys_in_order(robot, tmp_path) -> None:
    cfg = TrainConfig(model="lstm_mlp", options={"structure": "S2"}, pose_source="true", max_epochs=3)
    _bundle(robot, cfg).save(tmp_path / "m")
    written = json.loads((tmp_path / "m" / "config.json").read_text())
    assert list(written) == ["train", "ctrkin_version", "data"]
    assert written["train"] == cfg.to_dict()
    assert list(written["train"]) == list(cfg.to_dict())         # same keys, same order
    loaded = ModelBundle.load(tmp_path / "m", build_net)
    assert isinstance(loaded.config, ModelConfig)
    assert (loaded.config.model, loaded.config.pose_source, loaded.config.target_frame) == \
        ("lstm_mlp", "true", "tracker")
    assert loaded.config.options == cfg.options
    assert loaded.config.to_dict() == cfg.to_dict()
    assert TrainConfig.from_dict(loaded.config.training) == cfg   # resume reads it back whole
    assert loaded.config["model"] == "lstm_mlp" and loaded.config.get("max_epochs") == 3
    assert loaded.extra == {"data": {"samples": 20}}


def test_older_config_without_the_frame_keys_loads_with_defaults() -> None:
    old = {"task": "fk", "model": "mlp", "options": {}, "output_activation": "relu"}
    cfg = ModelConfig.from_dict(old)
    assert (cfg.pose_source, cfg.target_frame) == ("measured", "tracker")
    assert cfg.training == old


def test_a_mangled_config_is_refused_with_the_file_named() -> None:
    with pytest.raises(ModelError, match=r"m/config\.json.*lacks.*'model'"):
        ModelConfig.from_dict({"options": {}, "output_activation": "relu"}, "m/config.json")
    with pytest.raises(ModelError, match="not a table"):
        ModelConfig.from_dict([1, 2], "m/config.json")   # type: ignore[arg-type]


def test_torch_min_max_is_the_same_step_in_float32() -> None:
    rng = np.random.default_rng(1)
    x = rng.normal(scale=50.0, size=(40, 5))
    norm = MinMax.fit(x)
    step = norm.torch()
    xt = torch.tensor(x, dtype=torch.float32)
    np.testing.assert_allclose(step.transform(xt).numpy(), norm.transform(x), atol=1e-6)   # float32 on [0, 1]
    z = norm.transform(x)
    np.testing.assert_allclose(step.inverse(torch.tensor(z, dtype=torch.float32)).numpy(), x, rtol=1e-5,
                               atol=1e-4)
    np.testing.assert_allclose(norm.inverse(z), x, atol=1e-12)
    sub = norm.subset(slice(1, 3))
    np.testing.assert_array_equal(sub.transform(x[:, 1:3]), z[:, 1:3])
