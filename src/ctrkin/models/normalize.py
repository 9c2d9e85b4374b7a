"""Min-max normalisation to [0, 1] (paper III.C), fit on the training split only and saved with a model.

A model's one pre/post step: inputs go through x_norm.transform before the network, outputs through
y_norm.inverse after it, in numpy (MinMax) or, inside an exported graph, in torch (TorchMinMax).
Nothing else restates the arithmetic.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from torch import nn

from ctrkin.errors import ModelError


@dataclass(frozen=True, eq=False)
class MinMax:
    """x_n = (x − lo) / span per column. A constant column (span 0) gets span 1, so it maps to 0.

    data_hi, where known (fitted since 0.2), is each column's training maximum: the range the data
    had, [lo, data_hi], which span cannot give for a constant column."""

    lo: np.ndarray
    span: np.ndarray
    data_hi: np.ndarray | None = None

    def __post_init__(self) -> None:
        lo = np.asarray(self.lo, dtype=np.float64).ravel()
        span = np.asarray(self.span, dtype=np.float64).ravel()
        if lo.shape != span.shape or not np.all(np.isfinite(lo)) or not np.all(span > 0):
            raise ModelError("MinMax needs finite lo and positive span of equal length")
        object.__setattr__(self, "lo", lo)
        object.__setattr__(self, "span", span)
        if self.data_hi is not None:
            hi = np.asarray(self.data_hi, dtype=np.float64).ravel()
            if hi.shape != lo.shape or not np.all(np.isfinite(hi)) or np.any(hi < lo):
                raise ModelError("MinMax data_hi must be finite, of lo's length and not below lo")
            object.__setattr__(self, "data_hi", hi)

    def trained_range(self) -> tuple[np.ndarray, np.ndarray]:
        """(lo, hi) of the training data per column; a folder from before 0.2 gives lo + span, which
        is one unit too wide for a column that was constant."""
        return self.lo, self.lo + self.span if self.data_hi is None else self.data_hi

    @classmethod
    def fit(cls, x: np.ndarray) -> MinMax:
        """x: (M, F) training rows."""
        x = np.asarray(x, dtype=np.float64)
        if x.ndim != 2 or len(x) == 0:
            raise ModelError(f"cannot fit a normaliser on an array of shape {x.shape}; the training "
                             f"split is empty?")
        lo, hi = x.min(axis=0), x.max(axis=0)
        span = hi - lo
        return cls(lo, np.where(span > 1e-12, span, 1.0), hi)

    @property
    def hi(self) -> np.ndarray:
        return self.lo + self.span

    def transform(self, x: np.ndarray) -> np.ndarray:
        """(..., F) -> (..., F) in [0, 1] on the training range."""
        return (np.asarray(x, dtype=np.float64) - self.lo) / self.span

    def inverse(self, x: np.ndarray) -> np.ndarray:
        """(..., F) normalised -> (..., F) in the original units (float64)."""
        return np.asarray(x, dtype=np.float64) * self.span + self.lo

    def subset(self, columns: slice | np.ndarray) -> MinMax:
        """The normaliser of some of the columns (e.g. the pose inputs of an IK model)."""
        return MinMax(self.lo[columns], self.span[columns],
                      None if self.data_hi is None else self.data_hi[columns])

    def torch(self) -> TorchMinMax:
        """The same step as a torch module (float32 buffers), for exported graphs."""
        return TorchMinMax(self)

    def to_dict(self) -> dict[str, list[float]]:
        d = {"lo": self.lo.tolist(), "span": self.span.tolist()}
        return d if self.data_hi is None else {**d, "data_hi": self.data_hi.tolist()}

    @classmethod
    def from_dict(cls, d: dict) -> MinMax:
        try:
            hi = d.get("data_hi")
            return cls(np.array(d["lo"], dtype=np.float64), np.array(d["span"], dtype=np.float64),
                       None if hi is None else np.array(hi, dtype=np.float64))
        except KeyError as e:
            raise ModelError(f"normalisation entry lacks {e}") from None


class TorchMinMax(nn.Module):
    """MinMax in torch, float32: transform (..., F) -> normalised, inverse (..., F) -> units."""

    lo: torch.Tensor
    span: torch.Tensor

    def __init__(self, norm: MinMax) -> None:
        super().__init__()
        self.register_buffer("lo", torch.tensor(norm.lo, dtype=torch.float32))
        self.register_buffer("span", torch.tensor(norm.span, dtype=torch.float32))

    def transform(self, x: torch.Tensor) -> torch.Tensor:
        return (x - self.lo) / self.span

    def inverse(self, x: torch.Tensor) -> torch.Tensor:
        return x * self.span + self.lo
