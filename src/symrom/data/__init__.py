"""Datasets: the file contract, validation, import and preprocessing."""

from symrom.data.dataset import Dataset, DatasetError, validate
from symrom.data.io import read_dataset, write_dataset

__all__ = ["Dataset", "DatasetError", "read_dataset", "validate", "write_dataset"]
