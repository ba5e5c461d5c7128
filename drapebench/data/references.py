"""Physics-based reference drapes per (garment, sequence), loaded or simulated on first use."""

from __future__ import annotations

from pathlib import Path
from typing import Callable

import numpy as np
import torch

from drapebench.results import read_prediction


def read_drape(path: str | Path) -> torch.Tensor:
    """Vertices (T, V, 3) of a drape file: a prediction/reference ``.h5`` (dataset ``vertices``, as
    :func:`drapebench.results.write_prediction` writes) or an ``.npz`` with a ``vertices`` array (the
    reference cache's format)."""
    path = Path(path)
    if path.suffix == ".h5":
        return torch.from_numpy(read_prediction(path)[0])
    if path.suffix == ".npz":
        with np.load(path) as z:
            return torch.from_numpy(z["vertices"])
    raise ValueError(f"{path}: a reference drape is an .h5 or .npz file with a 'vertices' array")


class References:
    """Reference drapes keyed by (garment name, sequence name), each read once on first use and kept.

    ``load(garment, seq)`` returns the drape (T, V, 3) or None when there is none; see
    :meth:`from_simulator` and :meth:`from_files`. Every drape is checked against the sequence's frame
    count and the garment's vertex count.
    """

    def __init__(self, load: Callable[[object, object], torch.Tensor | None]):
        self._load = load
        self._drapes: dict[tuple[str, str], torch.Tensor | None] = {}

    @classmethod
    def from_simulator(cls, body, material, solver: str = "vbd", **settings) -> References:
        """Drapes of :func:`drapebench.reference.simulate_record` (read from its cache when there, simulated otherwise)."""

        def load(garment, seq):
            from drapebench.reference import simulate_record

            return simulate_record(garment, seq, body, material, solver, progress=False, **settings).vertices

        return cls(load)

    @classmethod
    def from_files(cls, paths: dict[tuple[str, str], str | Path]) -> References:
        """Drapes from files (see :func:`read_drape`) keyed by (garment name, sequence name); other pairs have none."""
        return cls(lambda garment, seq: read_drape(paths[key]) if (key := (garment.name, seq.name)) in paths else None)

    def get(self, garment, seq) -> torch.Tensor | None:
        """The reference drape (T, V, 3) of ``garment`` over ``seq``, or None."""
        key = (garment.name, seq.name)
        if key not in self._drapes:
            drape = self._load(garment, seq)
            if drape is not None:
                expected = (seq.n_frames, garment.n_vertices, 3)
                if tuple(drape.shape) != expected:
                    raise ValueError(f"reference drape of {garment.name} over {seq.name} has shape {tuple(drape.shape)}, "
                                     f"expected {expected}; rebuild it for this garment and sequence")  # fmt: skip
                if not torch.isfinite(drape).all():
                    raise ValueError(f"reference drape of {garment.name} over {seq.name} contains NaN or Inf")
            self._drapes[key] = drape
        return self._drapes[key]
