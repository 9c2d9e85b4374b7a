"""The GRU family trains with `ctrkin.training.train`, opens with `Kinematics.load` and streams
equal to its batch prediction."""

from __future__ import annotations

import numpy as np

from ctrkin.inference import Kinematics
from ctrkin.training import TrainConfig, train


def test_gru_trains_and_streams(sweeps, tmp_path) -> None:
    train(sweeps, TrainConfig(task="fk", model="gru_mlp", options={"units": 8}, max_epochs=2, threads=1),
          tmp_path / "gru", progress=False)
    kin = Kinematics.load(tmp_path / "gru")
    a, b = sweeps.sequence_bounds()[0]
    batch = kin.predict(sweeps.joints()[a:b])
    kin.reset()
    stream = np.array([kin.step(q) for q in sweeps.joints()[a:b]])
    np.testing.assert_allclose(stream, batch, rtol=0, atol=1e-5)
