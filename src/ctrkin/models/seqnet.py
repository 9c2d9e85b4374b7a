"""The LSTM-MLP family (paper Fig. 4, eq. 3-7; Table III), and the LSTM and MLP baselines, as one
layer-list network that the numpy streaming engine (ctrkin.models.engine) can run step by step.

A structure is written "SEQ|HEAD": SEQ are per-step layers applied along the input buffer
(Lh: LSTM with h units, Dh: Dense(h) + ReLU on each step), then the buffer is flattened (or, with
pooling "last", only the last step is kept), then HEAD are Dense + ReLU layers, then Dense(O) with the
output activation (ReLU in the paper, eq. 7).

Named structures:
  paper  L128|D64            the final model of III.C ("an LSTM layer with 128 hidden nodes and an MLP
                             layer with 64 ReLU units"), the default
  S1     L64,L64|D32         Table III. The extracted table lists S1 and S2 with the same layers; we read
  S2     L128,L64|D32        the merged "LSTM 128" cell as covering S2-S5, so S1 is the smaller one.
  S3     L128,L128|D64       eq. (3)-(7) taken literally (two LSTM layers)
  S4     L128,D128,L64|      Table III lists "Flatten" before the second LSTM; a Keras LSTM needs a
  S5     L128,D64,L32|       sequence, so we apply the Dense per step and flatten after the LSTM.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import torch
from torch import nn

from ctrkin.errors import ModelError
from ctrkin.models.base import KinematicsNet

STRUCTURES = {
    "paper": "L128|D64",
    "S1": "L64,L64|D32",
    "S2": "L128,L64|D32",
    "S3": "L128,L128|D64",
    "S4": "L128,D128,L64|",
    "S5": "L128,D64,L32|",
}
_LAYER = re.compile(r"^([LD])(\d+)$")
UNKNOWN_STATE = 0.5     # the previous state of a net that carries one, at a sequence start


@dataclass(frozen=True)
class Structure:
    """seq: per-step layers (("lstm"|"dense", units), ...); head: Dense units after pooling."""

    seq: tuple[tuple[str, int], ...]
    head: tuple[int, ...]

    @classmethod
    def parse(cls, text: str) -> Structure:
        """A name from STRUCTURES or a spec like "L128,D64|D32"."""
        spec = STRUCTURES.get(text, text)
        if spec.count("|") != 1:
            raise ModelError(f"structure {text!r} is neither a name {sorted(STRUCTURES)} nor a spec "
                             f"'SEQ|HEAD' such as 'L128|D64' (L: LSTM, D: Dense+ReLU, units after)")
        seq_txt, head_txt = spec.split("|")
        seq: list[tuple[str, int]] = []
        head: list[int] = []
        for part, out_seq in ((seq_txt, True), (head_txt, False)):
            for tok in filter(None, (t.strip() for t in part.split(","))):
                m = _LAYER.match(tok)
                if not m or int(m.group(2)) < 1:
                    raise ModelError(f"bad layer {tok!r} in structure {text!r}: use Lh or Dh, h >= 1")
                if out_seq:
                    seq.append(("lstm" if m.group(1) == "L" else "dense", int(m.group(2))))
                elif m.group(1) == "D":
                    head.append(int(m.group(2)))
                else:
                    raise ModelError(f"structure {text!r}: only Dense layers (Dh) may follow '|'")
        return cls(tuple(seq), tuple(head))


class SeqNet(KinematicsNet):
    """Per-step layers -> flatten (or last step) -> Dense ReLU head -> Dense(O) -> output activation.

    x: (B, IB, F) normalised features -> (B, O) normalised outputs. Each LSTM starts from zero state
    on every window (the buffer is the model's only memory, as in the paper).

    fused_lstm: where gradients are recorded (training steps), a one-layer LSTM on float32 CPU windows
    runs as ctrkin.models.window_lstm (the same values within float32 round-off, a fused backward);
    the training engine sets it from TrainConfig.fused_lstm for its epochs and unsets it after. Off,
    and without gradients (validation: nn.LSTM's forward alone was faster, 55 vs 75 ms on 7,800
    windows): torch's nn.LSTM.
    """

    fused_lstm: bool = False

    def __init__(self, n_inputs: int, n_outputs: int, ib: int, structure: str = "paper",
                 pooling: str = "flatten", output_activation: str = "relu") -> None:
        super().__init__(n_inputs, n_outputs, ib, output_activation)
        if pooling not in ("flatten", "last"):
            raise ModelError(f"pooling must be 'flatten' or 'last', got {pooling!r}")
        self.structure = Structure.parse(structure)
        self.pooling = pooling
        self.seq = nn.ModuleList()
        width = n_inputs
        for kind, units in self.structure.seq:
            if kind == "lstm":
                self.seq.append(nn.LSTM(width, units, batch_first=True))
            else:
                self.seq.append(nn.Linear(width, units))
            width = units
        width = width * ib if pooling == "flatten" else width
        self.trunk_width: int = width
        self.head = nn.ModuleList()
        for units in self.structure.head:
            self.head.append(nn.Linear(width, units))
            width = units
        self.out = nn.Linear(width, n_outputs)

    def trunk(self, x: torch.Tensor) -> torch.Tensor:
        """x: (B, IB, F) -> (B, trunk_width): the per-step layers, flattened (or the last step)."""
        h = x
        for layer in self.seq:
            if isinstance(layer, nn.LSTM):
                h = self._lstm(layer, h)                     # eq. (3), (4)
            else:
                h = torch.relu(layer(h))
        return h.flatten(1) if self.pooling == "flatten" else h[:, -1]   # eq. (5)

    def _lstm(self, layer: nn.LSTM, h: torch.Tensor) -> torch.Tensor:
        """layer(h)[0]: the fused window LSTM where `fused_lstm` applies, else torch's."""
        if self.fused_lstm and torch.is_grad_enabled():
            # imported here: window_lstm imports numba, which training alone needs
            from ctrkin.models.window_lstm import fits, window_lstm

            if fits(layer, h):
                return window_lstm(layer, h)
        return layer(h)[0]

    def head_out(self, h: torch.Tensor, state: torch.Tensor | None = None) -> torch.Tensor:
        """h: (B, trunk_width) -> (B, O): Dense ReLU layers and the output (state: BranchNet only)."""
        for layer in self.head:
            h = torch.relu(layer(h))                         # eq. (6)
        return self.finish(self.out(h))                      # eq. (7)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.head_out(self.trunk(x))

    def heads(self) -> list[tuple[nn.ModuleList, nn.Linear]]:
        """The heads after the trunk, each its Dense ReLU layers and output layer: one here; a net
        that carries a state has one per state (the streaming engine runs each, ctrkin.models.engine)."""
        return [(self.head, self.out)]

    def gate_layers(self) -> nn.ModuleList | None:
        """The gate MLP of a net that carries a state: (trunk features, previous state) -> logit of
        state 1; None here."""
        return None
