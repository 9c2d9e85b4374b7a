"""Datasets: schema, parquet + meta.json folders, splits."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ctrkin.util.lazy import lazy_attributes

__all__ = ["Dataset", "Split", "random_split", "split_by_sequence", "validate_frame"]

if TYPE_CHECKING:   # imported on first use instead (ctrkin.util.lazy)
    from ctrkin.data.dataset import Dataset, validate_frame
    from ctrkin.data.splits import Split, random_split, split_by_sequence

__getattr__, __dir__ = lazy_attributes(__name__, __file__)
