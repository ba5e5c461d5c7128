"""Training data records and h5 files of draped predictions."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import h5py
import numpy as np
import torch

from drapebench.cache import atomic_write


@dataclass
class TrainData:
    """What a method trains on: the body, material and garment, training/test sequences, and
    (optionally) physics-based reference drapes keyed by sequence name. Sequences are loaded
    lazily from the dataset h5 the first time they are asked for."""

    body: object
    material: object
    garment: object
    load_train: Callable[[], list] = field(default=lambda: [])
    test_sequences: list = field(default_factory=list)
    references: dict = field(default_factory=dict)
    _train: list | None = field(default=None, repr=False)

    @property
    def train_sequences(self) -> list:
        if self._train is None:
            self._train = list(self.load_train())
        return self._train


def write_prediction(path: str | Path, vertices: torch.Tensor, faces: torch.Tensor, **attrs) -> None:
    """Write draped vertices (T, V, 3) and faces (F, 3) with scalar/string attributes to h5, atomically."""
    with atomic_write(path, mode=None) as tmp, h5py.File(tmp, "w") as f:
        f.create_dataset("vertices", data=np.asarray(vertices, dtype=np.float32), compression="gzip", compression_opts=1)
        f.create_dataset("faces", data=np.asarray(faces, dtype=np.int32))
        for k, v in attrs.items():
            f.attrs[k] = v


def read_prediction(path: str | Path) -> tuple[np.ndarray, np.ndarray, dict]:
    """Vertices (T, V, 3), faces (F, 3) and attributes of a prediction file."""
    with h5py.File(path, "r") as f:
        return f["vertices"][()], f["faces"][()], dict(f.attrs)
