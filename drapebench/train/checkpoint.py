"""Training state on disk: atomic, resumable checkpoints and the per-step loss log ``losses.csv``."""

from __future__ import annotations

import csv
import io
import logging
from pathlib import Path

import torch

from drapebench.cache import Cache, atomic_write

log = logging.getLogger("drapebench")


PARTIAL = Cache("checkpoints", "partial")  # the resumable training state: sealed like every cached file


def save_state(path: Path, state: dict) -> None:
    """Write a training state dict (tensors, optimizer state, RNG states, history) to ``path`` atomically,
    sealed with a SHA-256 sidecar (:class:`drapebench.cache.Cache`); the previous state stays valid until then."""
    PARTIAL.store(path, lambda tmp: torch.save(state, tmp))


def load_state(path: Path, key: str) -> dict | None:
    """The training state saved at ``path`` for run ``key``, or None: there is none, the run is forced
    (``force=true``, :func:`drapebench.cache.forcing`), or the file fails its checksum, cannot be read or
    belongs to another run (a warning names the file; training starts over and replaces it)."""

    def read(p: Path) -> dict:
        state = torch.load(p, map_location="cpu", weights_only=False)
        if not isinstance(state, dict) or state.get("key") != key:
            raise ValueError("it belongs to another run")
        return state

    return PARTIAL.load(path, read)


def remove_state(path: Path) -> None:
    """Delete the training state at ``path`` and its seal (training ended)."""
    PARTIAL.remove(path)


def write_losses(path: Path, history: list[dict]) -> None:
    """Write ``losses.csv`` atomically: one row per step with the columns of the history records
    (step, epoch, lr, loss, each loss term, grad_norm); a term missing from a row is left empty."""
    columns = list(dict.fromkeys(k for row in history for k in row))
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=columns, lineterminator="\n")
    writer.writeheader()
    writer.writerows(history)
    with atomic_write(path, "w") as f:
        f.write(buf.getvalue())
