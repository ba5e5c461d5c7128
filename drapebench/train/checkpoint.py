"""Training state on disk: atomic, resumable checkpoints and the per-step loss log ``losses.csv``."""

from __future__ import annotations

import csv
import io
import logging
from pathlib import Path

import torch

from drapebench.cache import atomic_write

log = logging.getLogger("drapebench")


def save_state(path: Path, state: dict) -> None:
    """Write a training state dict (tensors, optimizer state, RNG states, history) to ``path`` atomically."""
    with atomic_write(path, mode=None) as tmp:
        torch.save(state, tmp)


def load_state(path: Path, key: str) -> dict | None:
    """The training state saved at ``path`` for run ``key``, or None when there is none. A file that
    cannot be read or belongs to another run is reported with a warning, removed and not used."""
    if not path.exists():
        return None
    try:
        state = torch.load(path, map_location="cpu", weights_only=False)
    except Exception as err:  # a truncated or foreign file: any unpickling error
        log.warning("training checkpoint %s is unreadable (%s: %s); removing it and starting over", path, type(err).__name__, err)
        path.unlink(missing_ok=True)
        return None
    if not isinstance(state, dict) or state.get("key") != key:
        log.warning("training checkpoint %s belongs to another run; removing it and starting over", path)
        path.unlink(missing_ok=True)
        return None
    return state


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
