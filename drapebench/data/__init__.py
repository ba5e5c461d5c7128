"""Typed training data: garments x body sequences x (optional) reference drapes, lazy h5, windows, splits."""

from drapebench.data.references import References, read_drape
from drapebench.data.sequences import H5Sequences
from drapebench.data.splits import Split, check_held_out, split_sequences
from drapebench.data.train_data import TrainData
from drapebench.data.windows import Windows

__all__ = ["H5Sequences", "References", "Split", "TrainData", "Windows", "check_held_out", "read_drape", "split_sequences"]
