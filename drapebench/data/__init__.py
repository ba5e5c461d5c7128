"""Typed training data: garments x body sequences x (optional) reference drapes, lazy h5, windows, splits (each
export imported at first use: :mod:`drapebench.data.reference_spec` alone imports no torch)."""

from drapebench.lazy import exports

_EXPORTS = {
    "References": "references", "read_drape": "references", "H5Sequences": "sequences", "Split": "splits",
    "check_held_out": "splits", "split_sequences": "splits", "TrainData": "train_data", "Windows": "windows",
}  # fmt: skip
__getattr__ = exports(__name__, _EXPORTS)
__all__ = sorted(_EXPORTS)
