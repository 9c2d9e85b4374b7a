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


def test_float32_sigmoid_pass():
    """The batch path's float32 sigmoid (issue 26): within 2e-7 of the float64 value over the whole
    range, 0 and 1 at the saturated ends, no NaN or inf."""
    from scipy.special import expit

    from ctrkin.models.batch import _sigmoid32

    x = np.r_[np.linspace(-120.0, 120.0, 24001), -1e30, 1e30, 0.0].astype(np.float32)
    y = x.copy()
    bits = np.empty(x.size, np.int32)
    _sigmoid32(y, bits, bits.view(np.float32))
    ref = expit(x.astype(np.float64))
    assert np.isfinite(y).all()
    assert np.abs(y - ref).max() < 2e-7


def test_one_lstm_batch_pass_with_saturated_gates(rng):
    """A one-LSTM network's batch path (gates and cells in one numba pass) equals net(windows) within
    float32 round-off where the gates saturate too (inputs far outside the normalised range)."""
    torch.manual_seed(5)
    net = build_model("lstm_mlp", 6, 6, 2, "linear", {"structure": "paper"}).eval()
    feats = rng.normal(0.0, 30.0, (300, 6))
    bounds = [(0, 1), (1, 300)]
    with torch.no_grad():
        ref = net(torch.tensor(windows(feats, bounds, 2), dtype=torch.float32)).numpy()
    out = seqnet_predict(net, *padded_rows(feats, bounds, 2), chunk=128)
    assert np.abs(out - ref).max() < 1e-5 * max(1.0, np.abs(ref).max())
