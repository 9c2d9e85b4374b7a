"""Where a training runs: `--device auto|cpu|cuda` (issue 26, goal 4; the paper trained on a GPU).

auto takes CUDA where torch sees a CUDA device, else the CPU, and says which; cuda without one is an
error that names what to pass instead. The model folder a run writes is the same either way: the
network the recipe, validation and the saved weights see stays on the CPU (ctrkin.training.engine
trains a copy on the device and copies its weights back after every epoch), so a CUDA run differs
from a CPU run only by the device's float rounding.
"""

from __future__ import annotations

import torch

from ctrkin.errors import ModelError
from ctrkin.training.config import DEVICES


def resolve_device(requested: str) -> tuple[torch.device, str | None]:
    """The torch device for `requested` (auto | cpu | cuda) and a note to show the user (None: nothing
    to say). ModelError for cuda where torch sees no CUDA device, or an unknown name."""
    if requested not in DEVICES:
        raise ModelError(f"device must be one of {DEVICES}, got {requested!r}")
    available = torch.cuda.is_available()
    if requested == "cuda" and not available:
        why = ("this torch build has no CUDA support" if torch.version.cuda is None
               else f"torch (CUDA {torch.version.cuda}) sees no CUDA device")
        raise ModelError(f"--device cuda: {why}; pass --device cpu, or --device auto to use a GPU "
                         "where there is one")
    if requested == "cpu" or not available:
        return torch.device("cpu"), ("--device auto: no CUDA device found, training on the CPU"
                                     if requested == "auto" else None)
    name = torch.cuda.get_device_name(0)
    return torch.device("cuda"), f"training on CUDA ({name})" if requested == "auto" else None
