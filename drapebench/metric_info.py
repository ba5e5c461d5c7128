"""What a metric column means (:class:`MetricInfo`): the record the library's metrics (:data:`drapebench.results.METRICS`)
and each method's declared diagnostics (``methods/<name>/metrics.py``, :mod:`drapebench.plugins`) are described by."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class MetricInfo:
    """What a metric column means: table label, unit, which direction is better, one-line meaning, the
    decimals a table prints it with, and whether it is the method's own training loss on its drape (``own_loss``:
    with ``<name>@untrained``, the loss on its untrained start, and runs of ``<method>_optimum``, the report's
    ``loss_gap_closed``)."""

    label: str
    unit: str
    better: str
    meaning: str
    decimals: int = 3
    own_loss: bool = False
