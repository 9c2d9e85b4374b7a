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
    """x_n = (x − lo) / span per column. A constant column (span 0) gets span 1, so it maps to 0."""

    lo: np.ndarray
    span: np.ndarray

    def __post_init__(self) -> None:
        lo = np.asarray(self.lo, dtype=np.float64).ravel()
        span = np.asarray(self.span, dtype=np.float64).ravel()
        if lo.shape != span.shape or not np.all(np.isfinite(lo)) or not np.all(span > 0):
            raise ModelError("MinMax needs finite lo and positive span of equal length")
        object.__setattr__(self, "lo", lo)
        object.__setattr__(self, "span", span)

    @classmethod
    def fit(cls, x: np.ndarray) -> MinMax:
        """x: (M, F) training rows."""
        x = np.asarray(x, dtype=np.float64)
        if x.ndim != 2 or len(x) == 0:
            raise ModelError(f"cannot fit a normaliser on an array of shape {x.shape}; the training "
                             f"split is empty?")
        lo, hi = x.min(axis=0), x.max(axis=0)
        span = hi - lo
        return cls(lo, np.where(span > 1e-12, span, 1.0))

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
        return MinMax(self.lo[columns], self.span[columns])

    def torch(self) -> TorchMinMax:
        """The same step as a torch module (float32 buffers), for exported graphs."""
        return TorchMinMax(self)

    def to_dict(self) -> dict[str, list[float]]:
        return {"lo": self.lo.tolist(), "span": self.span.tolist()}

    @classmethod
    def from_dict(cls, d: dict) -> MinMax:
        try:
            return cls(np.array(d["lo"], dtype=np.float64), np.array(d["span"], dtype=np.float64))
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
