"""Datasets: schema, parquet + meta.json folders, splits."""

from ctrkin.data.dataset import Dataset, validate_frame
from ctrkin.data.splits import Split, random_split, split_by_sequence

__all__ = ["Dataset", "Split", "random_split", "split_by_sequence", "validate_frame"]
