"""Datasets: schema, parquet + meta.json folders, splits."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ctrkin.util.lazy import lazy_attributes

_WHERE = {
    "Dataset": "ctrkin.data.dataset", "validate_frame": "ctrkin.data.dataset",
    "Split": "ctrkin.data.splits", "random_split": "ctrkin.data.splits",
    "split_by_sequence": "ctrkin.data.splits",
}

__all__ = ["Dataset", "Split", "random_split", "split_by_sequence", "validate_frame"]

__getattr__, __dir__ = lazy_attributes(__name__, _WHERE)

if TYPE_CHECKING:
    from ctrkin.data.dataset import Dataset, validate_frame
    from ctrkin.data.splits import Split, random_split, split_by_sequence
