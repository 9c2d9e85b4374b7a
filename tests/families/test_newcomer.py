"""A newcomer's family (issue 25's test of the interface): a GRU variant of the paper's model, written
as a family folder would be (a network, an entry, a load function; the shared FK predictor and the
paper's recipe), registered for the test alone, trains through `ctrkin.training.train`, opens
through `Kinematics.load`, streams equal to its batch prediction and exports to ONNX, with nothing
else in ctrkin changed."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from torch import nn

import ctrkin.families.registry as registry
from ctrkin.inference import Kinematics, export_onnx
from ctrkin.models.base import KinematicsNet
from ctrkin.models.fk_predictor import FKPredictor
from ctrkin.models.predictor import Family, ModelEntry, Opened, Predictor
from ctrkin.models.recipe import WindowRecipe
from ctrkin.training import TrainConfig, train


class GRUNet(KinematicsNet):
    """x: (B, IB, F) -> GRU(units) on the window -> flatten -> Dense(units, ReLU) -> (B, O)."""

    def __init__(self, n_inputs: int, n_outputs: int, ib: int, output_activation: str,
                 units: int = 16) -> None:
        super().__init__(n_inputs, n_outputs, ib, output_activation)
        self.gru = nn.GRU(n_inputs, int(units), batch_first=True)
        self.hidden = nn.Linear(int(units) * ib, int(units))
        self.out = nn.Linear(int(units), n_outputs)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        h, _ = self.gru(x)
        return self.finish(self.out(torch.relu(self.hidden(h.flatten(1)))))


def _load(opened: Opened) -> Predictor:
    return FKPredictor(opened.bundle, None, opened.fused)        # no numba engine: torch on windows


GRU = Family(name="gru", title="GRU sequence model",
             entries=(ModelEntry("gru_mlp", "GRU -> flatten -> Dense ReLU -> out", GRUNet, {"units": 16},
                                 {"task": "fk"}),),
             load=_load, recipe=WindowRecipe, predictors=(FKPredictor,))


@pytest.fixture
def with_gru(monkeypatch):
    """The registry with the GRU family's line added, for this test only."""
    monkeypatch.setattr(registry, "FAMILIES", (*registry.FAMILIES, GRU))
    monkeypatch.setitem(registry.MODELS, "gru_mlp", GRU.entries[0])
    monkeypatch.setitem(registry._FAMILY_OF, "gru_mlp", GRU)


def test_a_new_family_trains_streams_and_exports(with_gru, sweeps, tmp_path) -> None:
    ort = pytest.importorskip("onnxruntime")
    cfg = TrainConfig(task="fk", model="gru_mlp", options={"units": 8}, max_epochs=2, threads=1)
    res = train(sweeps, cfg, tmp_path / "gru", progress=False)
    assert res.metrics["training"]["epochs"] == 2 and "vs_measured" in res.metrics["test"]
    kin = Kinematics.load(tmp_path / "gru")
    assert isinstance(kin.predictor, FKPredictor) and isinstance(kin.net, GRUNet)
    a, b = sweeps.sequence_bounds()[1]
    batch = kin.predict(sweeps.joints()[a:b])
    kin.reset()
    stream = np.array([kin.step(q) for q in sweeps.joints()[a:b]])
    np.testing.assert_allclose(stream, batch, rtol=0, atol=1e-5)     # batch == streaming (mm, quaternion)
    onnx_file = export_onnx(kin, tmp_path / "gru.onnx")
    sess = ort.InferenceSession(str(onnx_file), providers=["CPUExecutionProvider"])
    windows = kin.feature_windows(sweeps.joints()[a:b]).astype(np.float32)
    np.testing.assert_allclose(sess.run(None, {"window": windows})[0], batch, rtol=0, atol=1e-4)
