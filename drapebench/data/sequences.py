"""Body sequences of a dataset h5 file (``drapebench.body.dataset``), read on demand."""

from __future__ import annotations

from pathlib import Path
from typing import Callable

import h5py

from drapebench.body.dataset import check_complete
from drapebench.body.sequence import BodySequence


class H5Sequences:
    """The sequences of one dataset h5 file, in name order, read lazily.

    ``source`` is the file's path or a callable returning it (e.g. one that builds the dataset), called
    the first time anything is asked for. Names, motions and frame counts come from the file's index
    (attributes and shapes) without reading poses; a sequence is read on first access and kept. A
    :meth:`subset` shares the file and the sequences already read.
    """

    def __init__(self, source: str | Path | Callable[[], str | Path], names: list[str] | None = None, _shared=None):
        self._source = source
        self._names = names
        self._shared = _shared if _shared is not None else {"path": None, "index": None, "loaded": {}}

    @property
    def path(self) -> Path:
        """The h5 file (calls ``source`` once if it is a callable)."""
        if self._shared["path"] is None:
            self._shared["path"] = Path(self._source() if callable(self._source) else self._source)
        return self._shared["path"]

    def _index(self) -> dict[str, tuple[str, int]]:
        """name -> (motion, n_frames) of every sequence in the file (read once)."""
        if self._shared["index"] is None:
            with h5py.File(self.path, "r") as f:
                check_complete(f)
                self._shared["index"] = {k: (str(f[k].attrs["motion"]), int(f[k]["poses"].shape[0])) for k in sorted(f.keys())}
        return self._shared["index"]

    @property
    def names(self) -> list[str]:
        """Sequence names, sorted (the order of :func:`drapebench.body.dataset.load_dataset`)."""
        return list(self._names) if self._names is not None else list(self._index())

    @property
    def motions(self) -> list[str]:
        """Motion kind of each sequence (e.g. "walk", "random"), without reading poses."""
        index = self._index()
        return [index[n][0] for n in self.names]

    @property
    def n_frames(self) -> list[int]:
        """Frame count of each sequence, without reading poses."""
        index = self._index()
        return [index[n][1] for n in self.names]

    def __len__(self) -> int:
        return len(self.names)

    def __getitem__(self, i: int) -> BodySequence:
        name = self.names[i]
        loaded = self._shared["loaded"]
        if name not in loaded:
            with h5py.File(self.path, "r") as f:
                loaded[name] = BodySequence.read_h5(f[name])
        return loaded[name]

    def __iter__(self):
        return (self[i] for i in range(len(self)))

    def subset(self, indices) -> H5Sequences:
        """The sequences at ``indices`` (positions in this set), sharing the file and what was read."""
        names = self.names
        return H5Sequences(self._source, [names[int(i)] for i in indices], self._shared)
