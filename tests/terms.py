"""Checks for a loss term a learned method registers with the trainer, reusable by every method.

A term is a function of draped vertices x (..., V, 3) returning a scalar tensor; the checks take
that function (close any other arguments over with a lambda) and compare its value, the direction
of its descent and where its gradient reaches.
"""

from __future__ import annotations

import torch


def descent(term, x: torch.Tensor) -> torch.Tensor:
    """-d term / d x, same shape as x (the direction a gradient step moves each vertex)."""
    x = x.detach().clone().requires_grad_(True)
    term(x).backward()
    return -x.grad


def assert_weighted(term, x: torch.Tensor, energy, weight: float, batch_size: int = 1) -> None:
    """The term's value is ``weight`` x ``energy(x)`` (the physics function, summed) / batch_size."""
    with torch.no_grad():
        got, want = term(x), weight * energy(x).sum() / batch_size
    assert torch.isfinite(got) and float(want) != 0.0, (float(got), float(want))
    assert torch.allclose(got, want, rtol=1e-6, atol=0.0), (float(got), float(want))


def assert_moves_along(term, x: torch.Tensor, moved: torch.Tensor, direction: torch.Tensor, min_cos: float = 0.99) -> None:
    """A descent step moves the vertices ``moved`` (a boolean mask over x's vertex axes) along ``direction``
    (broadcast to x; cosine >= min_cos each) and leaves every other vertex where it is."""
    d = descent(term, x)
    along = torch.nn.functional.cosine_similarity(d[moved], direction.expand_as(x)[moved].to(d.dtype), dim=-1)
    assert (along >= min_cos).all(), along
    assert torch.count_nonzero(d[~moved]) == 0


def assert_no_gradient_to(term, x: torch.Tensor, frozen: torch.Tensor) -> None:
    """No gradient of the term reaches the entries ``frozen`` (a mask over x's leading axes), and some
    gradient reaches the others."""
    d = descent(term, x)
    assert torch.count_nonzero(d[frozen]) == 0
    assert torch.count_nonzero(d[~frozen]) > 0
