"""A snap-aware LSTM-MLP: the paper's network with a learned hysteron
(docs/learned_kinematics.md: Snap-aware FK).

Why: near a fold the tip pose is a discontinuous function of the joints and of their history. A
regression net trained with an MAE loss on the few samples at a jump learns a ramp across it, and its
input buffer of IB steps cannot tell which of two stable branches the robot is on where the answer
depends on older history (a reversal inside the bistable band). So the state is made explicit:

    h_t   = trunk(window_t)                              LSTM -> flatten (paper eq. 3-5)
    s_t   = 1[ gate(h_t, s_{t-1}) > 0 ]                  branch state, a learned relay (hysteron)
    y_t   = head_{s_t}(h_t)                              Dense ReLU -> Dense (eq. 6-7), one per branch

The gate is trained as a classification (binary cross-entropy) against branch labels derived from the
data (ctrkin.families.snap_aware.labels), with the previous label as input (teacher forcing); each head is
trained with the MAE loss on the samples of its branch only, so neither blends the two branches and
the jump between them keeps its full size. At inference the state is carried from step to step,
so a jump happens in one step, at the joint values where the gate switches: a snap is sharp by
construction, and its timing is a classification boundary, not the midpoint of a ramp.

At a sequence start the previous state is unknown and fed as 0.5; training feeds 0.5 at random
(`unknown_prob`) so the gate also learns the history-free decision, and, where the label does not
depend on history (outside the bistable band), a flipped previous state, so a wrong state recovers.

Head forms (option `heads`): "separate" (the default) gives each branch its own head, trained on its
branch's rows only; "offset" writes both branches as one shared output and a jump d between them,

    y_t   = out(relu(head(h_t))) + (s_t − ½) · out1(relu(head1(h_t)))

trained with an L1 penalty on d outside the bistable band (ctrkin.families.snap_aware.recipe.
OFFSET_L1): there one branch alone exists, so d goes to 0, the shared head fits the rows of both
labels and a wrong state costs nothing; in the band the rows of both branches fit d, the jump. The
shared head learns from every row, as the plain LSTM-MLP does. The sum is one Dense ReLU head of
twice the width (hidden layers side by side, the output layers likewise), so `heads()` gives the
streaming engine and the fused step two ordinary heads (docs/learned_kinematics.md: The offset head
form).
"""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

from ctrkin.errors import ModelError
from ctrkin.models.seqnet import UNKNOWN_STATE, SeqNet


class BranchNet(SeqNet):
    """SeqNet trunk, two heads (branch 0: `head`, `out`; branch 1: `head1`, `out1`) and a gate MLP.

    x: (B, IB, F) normalised windows; states are floats in {0, 1} (0.5: unknown). gate_units: hidden
    width of the gate; heads: "separate" or "offset" (module docstring)."""

    def __init__(self, n_inputs: int, n_outputs: int, ib: int, structure: str = "paper",
                 output_activation: str = "linear", gate_units: int = 32, heads: str = "separate") -> None:
        super().__init__(n_inputs, n_outputs, ib, structure, "flatten", output_activation)
        if heads not in HEAD_FORMS:
            raise ModelError(f"heads must be one of {HEAD_FORMS}, got {heads!r}")
        self.head_form = heads
        self.gate = nn.ModuleList([nn.Linear(self.trunk_width + 1, gate_units), nn.Linear(gate_units, 1)])
        self.head1 = nn.ModuleList(nn.Linear(m.in_features, m.out_features)
                                   for m in self.head if isinstance(m, nn.Linear))
        self.out1 = nn.Linear(self.out.in_features, self.out.out_features)

    def init_output_bias(self) -> None:
        super().init_output_bias()
        with torch.no_grad():
            self.out1.bias.fill_(0.0 if self.head_form == "offset" else 0.5)   # an offset starts at 0

    def head_out(self, h: torch.Tensor, state: torch.Tensor | None = None) -> torch.Tensor:
        """h: (B, W), state: (B,) in {0, 1} -> (B, O) from the head of each row's branch."""
        if state is None:
            raise ModelError("a BranchNet needs its branch state (BranchNet.decode)")
        s = state.reshape(-1, 1) > 0.5
        if self.head_form == "offset":
            return self.offset_out(h, s)[0]
        y0 = self.finish(self.out(_hidden(self.head, h)))    # eq. (6), (7)
        y1 = self.finish(self.out1(_hidden(self.head1, h)))
        return torch.where(s, y1, y0)

    def offset_out(self, h: torch.Tensor, state: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """The offset form: h (B, W), state (B, 1) in {0, 1} -> the outputs z + (s − ½)·d (B, O) and
        the jump d (B, O) itself (before the output activation; its penalty is the recipe's)."""
        z, d = self.out(_hidden(self.head, h)), self.out1(_hidden(self.head1, h))
        return self.finish(z + (state.to(z.dtype) - 0.5) * d), d

    def heads(self) -> list[tuple[nn.ModuleList, nn.Linear]]:
        if self.head_form == "offset":
            return merged_offset_heads(self.head, self.out, self.head1, self.out1)
        return [(self.head, self.out), (self.head1, self.out1)]

    def gate_layers(self) -> nn.ModuleList | None:
        return self.gate

    def gate_logit(self, h: torch.Tensor, s_prev: torch.Tensor) -> torch.Tensor:
        """h: (B, W) trunk features, s_prev: (B,) previous state -> (B,) logit of s_t = 1."""
        z = torch.cat([h, s_prev.reshape(-1, 1).to(h.dtype)], dim=1)
        return self.gate[1](torch.relu(self.gate[0](z)))[:, 0]

    def forward_state(self, x: torch.Tensor, state: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """One step with the state carried outside (the ONNX graph, ctrkin.models.onnx_graph): x (B, IB,
        F), state (B,) the previous state -> (outputs (B, O), the new state (B,))."""
        h = self.trunk(x)
        new_state = (self.gate_logit(h, state) > 0).to(h.dtype)
        return self.head_out(h, new_state), new_state

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """History-free use (one window, unknown previous state): the gate decides the state."""
        h = self.trunk(x)
        s = (self.gate_logit(h, torch.full((len(h),), UNKNOWN_STATE)) > 0).to(h.dtype)
        return self.head_out(h, s)

    @torch.inference_mode()
    def decode(self, h: torch.Tensor, bounds: list[tuple[int, int]]) -> tuple[np.ndarray, np.ndarray]:
        """Carry the state through every sequence. h: (T, W) trunk features of consecutive rows;
        bounds: [(start, stop)) of the sequences. Returns y (T, O) normalised outputs and s (T,) states.

        The gate is evaluated for both previous states in one pass, then the relay is scanned."""
        n = len(h)
        logits = {v: self.gate_logit(h, torch.full((n,), v)).numpy() for v in (0.0, 1.0, UNKNOWN_STATE)}
        s = relay_scan(logits[0.0] > 0, logits[1.0] > 0, logits[UNKNOWN_STATE] > 0, bounds)
        y = self.head_out(h, torch.from_numpy(s.astype(np.float32))).numpy()
        return y, s


HEAD_FORMS = ("separate", "offset")


def _hidden(layers: nn.ModuleList, h: torch.Tensor) -> torch.Tensor:
    for layer in layers:
        h = torch.relu(layer(h))                             # eq. (6)
    return h


@torch.no_grad()
def merged_offset_heads(head: nn.ModuleList, out: nn.Linear, head1: nn.ModuleList, out1: nn.Linear
                        ) -> list[tuple[nn.ModuleList, nn.Linear]]:
    """The offset form as two ordinary heads of the summed width: the hidden layers of the shared
    head and the jump's side by side (block-diagonal after the first); branch s's output layer reads
    the shared half and ±½ the jump's half, biases likewise (without hidden layers, the weights add).
    Equal to head_out up to float round-off."""
    layers = nn.ModuleList()
    pairs = [(a, b) for a, b in zip(head, head1, strict=True)
             if isinstance(a, nn.Linear) and isinstance(b, nn.Linear)]
    for k, (a, b) in enumerate(pairs):
        lin = nn.Linear(a.in_features if k == 0 else a.in_features + b.in_features,
                        a.out_features + b.out_features)
        if k == 0:
            lin.weight.copy_(torch.cat([a.weight, b.weight]))
        else:
            lin.weight.copy_(torch.block_diag(a.weight, b.weight))
        lin.bias.copy_(torch.cat([a.bias, b.bias]))
        layers.append(lin)
    outs: list[tuple[nn.ModuleList, nn.Linear]] = []
    for sign in (-0.5, 0.5):
        if layers:
            lin = nn.Linear(out.in_features + out1.in_features, out.out_features)
            lin.weight.copy_(torch.cat([out.weight, sign * out1.weight], dim=1))
        else:                               # no hidden layer: both read the trunk, the weights add
            lin = nn.Linear(out.in_features, out.out_features)
            lin.weight.copy_(out.weight + sign * out1.weight)
        lin.bias.copy_(out.bias + sign * out1.bias)
        outs.append((layers, lin))
    return outs


def relay_scan(from0: np.ndarray, from1: np.ndarray, first: np.ndarray,
               bounds: list[tuple[int, int]]) -> np.ndarray:
    """States (T,) in {0, 1}: s_t = from1[t] if s_{t-1} else from0[t], s at a sequence start = first."""
    s = np.zeros(len(from0), dtype=np.int8)
    for a, b in bounds:
        if b <= a:
            continue
        cur = bool(first[a])
        s[a] = cur
        for t in range(a + 1, b):
            cur = bool(from1[t]) if cur else bool(from0[t])
            s[t] = cur
    return s
