"""The fused window LSTM (ctrkin.models.window_lstm, issue 26 goal 3) against torch's nn.LSTM: the
same outputs and the same gradients (weights, biases, inputs) within float32 round-off, at every
input buffer the paper uses; the pool of buffers does not mix one forward with another; SeqNet uses
it only where it may (gradients recorded, CPU float32, fused_lstm on)."""

from __future__ import annotations

import pytest
import torch
from torch import nn

from ctrkin.families.registry import build_model
from ctrkin.models.window_lstm import fits, use_window_lstm, window_lstm

# float32 round-off of a 128-unit LSTM and its gradients (the polynomial σ: relative error < 1e-7)
RTOL, ATOL = 1e-5, 1e-6


def _grads(layer: nn.LSTM, x: torch.Tensor, weight: torch.Tensor, fused: bool
           ) -> tuple[torch.Tensor, list[torch.Tensor]]:
    for p in layer.parameters():
        p.grad = None
    x = x.detach().clone().requires_grad_(True)
    out = window_lstm(layer, x) if fused else layer(x)[0]
    (out * weight).sum().backward()
    assert x.grad is not None
    return out.detach(), [p.grad.clone() for p in layer.parameters() if p.grad is not None] + [x.grad]


@pytest.mark.parametrize("ib", [1, 2, 3, 5])
def test_outputs_and_gradients_equal_nn_lstm(ib):
    torch.manual_seed(ib)
    layer = nn.LSTM(7, 128, batch_first=True)
    x = torch.rand(257, ib, 7) * 2 - 0.5           # beyond the [0, 1] of normalised features
    weight = torch.randn(257, ib, 128)
    ref, ref_grads = _grads(layer, x, weight, fused=False)
    out, grads = _grads(layer, x, weight, fused=True)
    torch.testing.assert_close(out, ref, rtol=RTOL, atol=ATOL)
    assert len(grads) == len(ref_grads) == 5
    for got, want in zip(grads, ref_grads, strict=True):
        torch.testing.assert_close(got, want, rtol=RTOL, atol=ATOL * max(1.0, float(want.abs().max())))
    assert layer.bias_ih_l0.grad is not layer.bias_hh_l0.grad     # equal values, two tensors


def test_pooled_buffers_do_not_mix_forwards():
    """Two forwards before either backward (the second cannot take the first's buffers), then the
    backwards in either order: each gradient equals its own nn.LSTM gradient."""
    torch.manual_seed(1)
    layer = nn.LSTM(7, 32, batch_first=True)
    xs = [torch.rand(64, 2, 7) for _ in range(3)]
    want = []
    for x in xs:
        layer.zero_grad()
        layer(x)[0].square().sum().backward()
        want.append(layer.weight_hh_l0.grad.clone())
    for order in ((0, 1), (1, 0)):
        outs = [window_lstm(layer, xs[i]) for i in (0, 1)]
        for i in order:
            layer.zero_grad()
            outs[i].square().sum().backward()
            torch.testing.assert_close(layer.weight_hh_l0.grad, want[i], rtol=RTOL, atol=ATOL)
        layer.zero_grad()                       # a pooled buffer after both: the third still right
        window_lstm(layer, xs[2]).square().sum().backward()
        torch.testing.assert_close(layer.weight_hh_l0.grad, want[2], rtol=RTOL, atol=ATOL)


def test_buffers_made_in_inference_mode_serve_a_training_step():
    torch.manual_seed(3)
    layer = nn.LSTM(7, 16, batch_first=True)
    x = torch.rand(32, 2, 7)
    with torch.inference_mode():
        window_lstm(layer, x)                           # pools its buffers
    window_lstm(layer, x).sum().backward()
    assert layer.weight_hh_l0.grad is not None


def test_a_second_backward_through_the_same_graph_is_refused():
    layer = nn.LSTM(7, 16, batch_first=True)
    out = window_lstm(layer, torch.rand(8, 2, 7)).sum()
    out.backward(retain_graph=True)
    with pytest.raises(RuntimeError, match="twice"):
        out.backward()


def test_seqnet_uses_it_only_where_it_may(monkeypatch):
    torch.manual_seed(2)
    net = build_model("lstm_mlp", 7, 6, 2)
    x = torch.rand(40, 2, 7)
    calls = []
    import ctrkin.models.window_lstm as module

    real = module.window_lstm
    monkeypatch.setattr(module, "window_lstm", lambda layer, h: calls.append(1) or real(layer, h))
    ref = net(x)
    assert calls == []                                   # off by default
    use_window_lstm(net, True)
    with torch.inference_mode():                         # validation: torch's forward
        torch.testing.assert_close(net(x), ref)
    assert calls == []
    out = net(x)
    assert calls == [1]
    torch.testing.assert_close(out, ref, rtol=RTOL, atol=ATOL)
    with torch.inference_mode():                         # called directly without gradients
        torch.testing.assert_close(window_lstm(net.seq[0], x), net.seq[0](x)[0], rtol=RTOL, atol=ATOL)
    assert not fits(net.seq[0], x.double())              # float64, CUDA, stacked layers: nn.LSTM
    assert not fits(nn.LSTM(7, 8, num_layers=2, batch_first=True), x)
    use_window_lstm(net, False)
    net(x)
    assert calls == [1]
