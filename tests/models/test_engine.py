"""The numba streaming engine equals the torch batch path (windows from zero LSTM state)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from ctrkin.errors import ModelError
from ctrkin.families.registry import build_model
from ctrkin.models import windows
from ctrkin.models.batch import padded_rows, seqnet_predict
from ctrkin.models.engine import StreamingEngine


@pytest.mark.parametrize(("name", "structure", "ib"), [
    ("lstm_mlp", "paper", 2), ("lstm_mlp", "S3", 3), ("lstm_mlp", "S4", 4), ("lstm_mlp", "S5", 1),
    ("lstm_mlp", "D8,L8|D8", 5), ("mlp", "|D128,D64", 3), ("lstm", "L128|", 2)])
def test_engine_equals_batch(name, structure, ib, rng):
    torch.manual_seed(3)
    net = build_model(name, 6, 6, ib, "linear", {"structure": structure}).eval()
    feats = rng.random((40, 6))
    bounds = [(0, 15), (15, 40)]
    with torch.no_grad():
        batch = net(torch.tensor(windows(feats, bounds, ib), dtype=torch.float32)).numpy()
    eng = StreamingEngine(net)
    stream = []
    for t in range(40):
        if t in (0, 15):
            eng.reset()
        stream.append(eng.step(feats[t]))
    assert np.abs(np.array(stream) - batch).max() < 1e-6


def test_engine_refuses_conv_models():
    with pytest.raises(ModelError, match="SeqNet"):
        StreamingEngine(build_model("cnn", 6, 6, 2))


@pytest.mark.parametrize(("name", "structure", "ib"), [
    ("lstm_mlp", "paper", 2), ("lstm_mlp", "S3", 3), ("lstm_mlp", "S4", 4), ("lstm_mlp", "D8,L8|D8", 5),
    ("mlp", "|D128,D64", 3), ("lstm", "L128|", 1)])
def test_chain_batch_path_equals_windows(name, structure, ib, rng):
    torch.manual_seed(4)
    net = build_model(name, 6, 6, ib, "linear", {"structure": structure}).eval()
    feats = rng.random((700, 6))
    bounds = [(0, 2), (2, 300), (300, 700)]            # includes a sequence shorter than the buffer
    with torch.no_grad():
        ref = net(torch.tensor(windows(feats, bounds, ib), dtype=torch.float32)).numpy()
    out = seqnet_predict(net, *padded_rows(feats, bounds, ib), chunk=64)   # several chunks
    assert np.abs(out - ref).max() < 1e-6
