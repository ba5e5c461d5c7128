"""Seeded train/validation/test splits of sequences in which the test motions never appear in training."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Split:
    """Positions (sorted int64 arrays) of the training, validation and test sequences in the split list."""

    train: np.ndarray
    val: np.ndarray
    test: np.ndarray


def check_held_out(train_motions, test_motions) -> None:
    """Raise ValueError naming every motion of ``test_motions`` found among ``train_motions`` (one per sequence)."""
    train_motions = list(train_motions)
    leaked = sorted(set(test_motions) & set(train_motions))
    if leaked:
        counts = ", ".join(f"{m} ({train_motions.count(m)} sequences)" for m in leaked)
        raise ValueError(f"test motion(s) {counts} appear in the training set; train on a dataset without them "
                         "or choose other test motions")  # fmt: skip


def split_sequences(motions, seed: int, val_fraction: float = 0.1, test_fraction: float = 0.0, test_motions=()) -> Split:
    """Split sequences with the given ``motions`` (one kind per sequence) into train/val/test.

    Every sequence of a motion in ``test_motions`` goes to test; the others are shuffled with ``seed``
    and ``round(fraction x count)`` of them go to val and to test, the rest to train. Raises ValueError
    for fractions outside [0, 1) or summing to 1 or more, or when nothing is left for training.
    """
    if not (0 <= val_fraction < 1 and 0 <= test_fraction < 1 and val_fraction + test_fraction < 1):
        raise ValueError(f"val_fraction and test_fraction must be in [0, 1) with a sum < 1, got {val_fraction}, {test_fraction}")
    motions = np.asarray(list(motions), dtype=object)
    held = np.isin(motions, list(test_motions)) if len(motions) else np.zeros(0, bool)
    pool = np.random.default_rng(seed).permutation(np.flatnonzero(~held))
    n_val, n_test = round(val_fraction * len(pool)), round(test_fraction * len(pool))
    train = np.sort(pool[n_val + n_test :])
    if not len(train):
        raise ValueError(f"no sequence left for training out of {len(motions)} (test motions {list(test_motions)}, "
                         f"val_fraction {val_fraction}, test_fraction {test_fraction})")  # fmt: skip
    split = Split(train, np.sort(pool[:n_val]), np.sort(np.concatenate([np.flatnonzero(held), pool[n_val : n_val + n_test]])))
    check_held_out(motions[split.train], test_motions)
    return split
