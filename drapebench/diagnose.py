"""What a loss sees: each weighted term of a loss that is a function of draped vertices, its value and the
size of its gradient on every vertex, so a term that dominates the others by orders of magnitude shows.

A term's gradient with respect to a vertex position is a force in N when the term is an energy in J and the
positions are in m; :func:`term_table` reports its per-vertex norm (mean, median, 99th percentile, max) next to the
value, one row per term and one for their sum.
"""

from __future__ import annotations

from typing import Callable

import pandas as pd
import torch


def term_table(terms_of: Callable[[torch.Tensor], dict[str, torch.Tensor]], x: torch.Tensor) -> pd.DataFrame:
    """One row per term of ``terms_of(x)`` (x (..., V, 3) m -> {name: scalar}) and a "total" row: the value,
    and the norm of d term / d x per vertex over all of x's vertices (mean, median, p99, max; N for a term in J).
    Raises ValueError naming a term that is not finite or has a non-finite gradient."""
    x = x.detach().clone().requires_grad_(True)
    terms = terms_of(x)
    rows = []
    for name, value in {**terms, "total": sum(terms.values())}.items():
        (grad,) = torch.autograd.grad(value, x, retain_graph=True, allow_unused=True)
        norm = torch.zeros(x.shape[:-1], dtype=x.dtype) if grad is None else grad.norm(dim=-1).flatten()
        if not torch.isfinite(value) or not torch.isfinite(norm).all():
            raise ValueError(f"loss term {name!r} is not finite at this drape (value {float(value.detach()):.4g})")
        norm = norm.flatten().double()
        rows.append({"term": name, "value": float(value.detach()), "grad_mean": float(norm.mean()), "grad_median": float(norm.median()),
                     "grad_p99": float(torch.quantile(norm, 0.99)), "grad_max": float(norm.max())})  # fmt: skip
    return pd.DataFrame(rows)
