"""When a training run converged, read from its per-step loss (``losses.csv``): the first step after which
the loss, smoothed by a running mean, stays within ``tolerance`` of its total drop above its final value.
Step times are near uniform within a run, so the training time to convergence is ``train_s`` x that step's
share of the steps."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

SMOOTHING_SHARE = 0.05  # running-mean window: this share of the steps (at least MIN_WINDOW)
MIN_WINDOW = 10
TOLERANCE = 0.05  # converged: the smoothed loss within this share of its total drop above its final value


def converged_step(loss: np.ndarray, tolerance: float = TOLERANCE, smoothing_share: float = SMOOTHING_SHARE) -> int:
    """The 1-based step (of len(loss)) from which the running mean of ``loss`` (window: ``smoothing_share`` of
    the steps, at least 10) stays at or below final + ``tolerance`` x (start - final), start and final its
    first and last smoothed values; len(loss) when it never drops (nothing to converge to). Raises ValueError
    on an empty or non-finite loss."""
    loss = np.asarray(loss, dtype=np.float64)
    if len(loss) == 0 or not np.isfinite(loss).all():
        raise ValueError("converged_step needs a non-empty, finite loss history")
    window = max(MIN_WINDOW, int(round(smoothing_share * len(loss))))
    smooth = pd.Series(loss).rolling(window, min_periods=1).mean().to_numpy()
    start, final = smooth[min(window, len(smooth)) - 1], smooth[-1]
    if not start > final:
        return len(loss)
    above = np.nonzero(smooth > final + tolerance * (start - final))[0]
    return int(above[-1]) + 2 if len(above) else 1


def converged_seconds(losses_csv: str | Path, train_s: float) -> float | None:
    """Training time (s) to :func:`converged_step` of the ``loss`` column of a run's ``losses.csv``, for a run
    that trained ``train_s`` seconds in all; None when the file holds no steps (a run with zero epochs)."""
    try:
        loss = pd.read_csv(losses_csv)["loss"].to_numpy()
    except pd.errors.EmptyDataError:
        return None
    if len(loss) == 0:
        return None
    return float(train_s) * min(converged_step(loss), len(loss)) / len(loss)
