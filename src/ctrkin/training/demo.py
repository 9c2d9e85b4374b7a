"""The old import path of ctrkin.acquisition.demo (a data maker, not training; kept for users' code)."""

from ctrkin.acquisition.demo import sweep_dataset

__all__ = ["sweep_dataset"]
