"""TrainData: what a learned method trains on."""

from __future__ import annotations

from typing import Callable

from drapebench.data.references import References
from drapebench.data.splits import check_held_out
from drapebench.data.windows import Windows


class _Once:
    """A value computed by ``load()`` on first use and kept (shared by the views of one TrainData)."""

    def __init__(self, load: Callable[[], object]):
        self._load, self._value, self.loaded = load, None, False

    def get(self):
        if not self.loaded:
            self._value, self.loaded = self._load(), True
        return self._value


class TrainData:
    """The body, material, garment(s), training/validation/test body sequences and optional reference drapes.

    Args:
        body, material: the :class:`~drapebench.body.BodyModel` and :class:`~drapebench.physics.Material`.
        garment: the one garment of a per-garment method (shorthand for ``garments=[garment]``).
        load_train: returns the training sequences (a list, or a lazy
            :class:`~drapebench.data.sequences.H5Sequences`); called the first time they are asked for.
        test_sequences: the sequences the method is evaluated on.
        garments: several garments (a generic method trains one model on all of them).
        load_val: returns the validation sequences, like ``load_train``.
        references: reference drapes per (garment, sequence), see :meth:`reference`.
        held_out_motions: motion kinds that must never appear in training; loading training sequences
            with one of them raises ValueError naming it.
    """

    def __init__(self, body, material, garment=None, load_train: Callable[[], object] | None = None, test_sequences=(),
                 *, garments=None, load_val: Callable[[], object] | None = None, references: References | None = None,
                 held_out_motions=()):  # fmt: skip
        if garment is not None and garments is not None:
            raise ValueError("give garment (one) or garments (several), not both")
        self.body, self.material = body, material
        self.garments = list(garments) if garments is not None else ([] if garment is None else [garment])
        self.test_sequences = list(test_sequences)
        self.references = references
        self.held_out_motions = tuple(held_out_motions)
        self._train = _Once(lambda: self._checked(load_train() if load_train is not None else []))
        self._val = _Once(lambda: list(load_val()) if load_val is not None else [])

    def _checked(self, seqs):
        motions = seqs.motions if hasattr(seqs, "motions") else [s.motion for s in seqs]
        check_held_out(motions, self.held_out_motions)
        return seqs

    @property
    def garment(self):
        """The single garment; ValueError when there are none or several (a per-garment method needs one)."""
        if len(self.garments) != 1:
            names = ", ".join(g.name for g in self.garments) or "none"
            raise ValueError(f"this method trains one model per garment but the training data holds {len(self.garments)} "
                             f"garments ({names}); train once per garment with TrainData.for_garment(g)")  # fmt: skip
        return self.garments[0]

    def for_garment(self, garment) -> TrainData:
        """A view with the one garment ``garment`` that shares the sequences (loaded once) and references."""
        view = TrainData(self.body, self.material, garment, test_sequences=self.test_sequences, references=self.references,
                         held_out_motions=self.held_out_motions)  # fmt: skip
        view._train, view._val = self._train, self._val
        return view

    def read_train(self) -> None:
        """Read the training sequences now (for reference drapes: simulate those the cache lacks), so that a
        fit's training time does not include making its data."""
        self._train.get()

    @property
    def train_source(self):
        """The training sequences as given by ``load_train`` (a lazy H5Sequences keeps poses on disk until read)."""
        return self._train.get()

    @property
    def train_sequences(self) -> list:
        """The training sequences as a list (all read on first use)."""
        return list(self.train_source)

    @property
    def val_sequences(self) -> list:
        """The validation sequences (read on first use)."""
        return self._val.get()

    def windows(self, length: int, stride: int = 1, first: int = 0) -> Windows:
        """Windows of ``length`` frames over the training sequences (rows: position in train_source, start frame)."""
        src = self.train_source
        return Windows.over(src.n_frames if hasattr(src, "n_frames") else [s.n_frames for s in src], length, stride, first)

    def reference(self, garment, seq):
        """Reference drape (T, V, 3) of ``garment`` over ``seq``, or None (no references, or none for that pair)."""
        return None if self.references is None else self.references.get(garment, seq)
