"""Training data records."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable


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
