"""Windows of consecutive frames over a set of sequences, for recurrent models, with seeded shuffling."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Windows:
    """Every window of ``length`` consecutive frames: ``index`` (N, 2) int64 rows (sequence, start frame).

    A window covers frames [start, start + length) of its sequence.
    """

    index: np.ndarray
    length: int

    @classmethod
    def over(cls, n_frames, length: int, stride: int = 1, first: int = 0) -> Windows:
        """Windows over sequences of ``n_frames`` (one count per sequence), starting at frames
        ``first, first + stride, ...`` while the window fits; a sequence shorter than ``first + length``
        contributes none. Raises ValueError for a bad length/stride/first or when no window fits anywhere."""
        if length < 1 or stride < 1 or first < 0:
            raise ValueError(f"windows need length >= 1, stride >= 1 and first >= 0, got {length}, {stride}, {first}")
        n_frames = np.asarray(list(n_frames), dtype=np.int64)
        counts = np.maximum(0, (n_frames - first - length) // stride + 1)
        if counts.sum() == 0:
            longest = int(n_frames.max()) if len(n_frames) else 0
            raise ValueError(f"no window of {length} frames (from frame {first}) fits: the longest of {len(n_frames)} "
                             f"sequences has {longest} frames; use shorter windows or longer sequences")  # fmt: skip
        seq = np.repeat(np.arange(len(n_frames)), counts)
        offset = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
        return cls(np.stack([seq, first + stride * offset], 1), length)

    def __len__(self) -> int:
        return len(self.index)

    def order(self, seed: int, epoch: int = 0) -> np.ndarray:
        """A permutation (N,) of the windows, fixed by (seed, epoch) and different across epochs."""
        return np.random.default_rng([seed, epoch]).permutation(len(self))

    def batches(self, batch_size: int, seed: int, epoch: int = 0, drop_last: bool = False):
        """Rows of ``index`` in batches (B, 2), in the order :meth:`order` gives; the last batch may be
        smaller unless ``drop_last``."""
        if batch_size < 1:
            raise ValueError(f"batch_size must be >= 1, got {batch_size}")
        order = self.order(seed, epoch)
        stop = len(order) - len(order) % batch_size if drop_last else len(order)
        for k in range(0, stop, batch_size):
            yield self.index[order[k : k + batch_size]]
