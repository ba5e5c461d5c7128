"""The drape that minimises a method's own loss directly over the garment vertices, with no network.

For a self-supervised method whose loss is a function of the drape, this is the best any network trained on
that loss could do frame by frame: the gap between it and the trained model is what training leaves, the gap
between it and the reference what the loss itself costs.

The method supplies its loss as a callable ``loss(t, window) -> (scalar, {term: scalar})``: ``window``
(W, V, 3) m holds the drapes of frames t-W+1..t, the last one free. :func:`optimise_sequence` solves the
frames in sequence order, each from its start drape, with the W-1 frames before it fixed at their optimised
values (so a loss with an inertia term sees the two previous optimised frames, as in training). Frames
before the first repeat the first frame, the garment at rest: its start drape while the first frame is
solved, its optimum afterwards.
"""

from __future__ import annotations

import logging
import math
import time
import typing
from dataclasses import dataclass, field
from typing import Callable, Literal

import torch

from drapebench.progress import progress

log = logging.getLogger("drapebench")
WindowLoss = Callable[[int, torch.Tensor], tuple[torch.Tensor, dict[str, torch.Tensor]]]


@dataclass(frozen=True)
class SolverSettings:
    """A method's ``method.params.optimum``: the solver settings of :func:`minimise`."""

    solver: Literal["lbfgs", "adam"] = "lbfgs"
    iterations: int = 50  # per frame: L-BFGS iterations (each one or more loss evaluations) or Adam steps
    lr: float = 1.0  # L-BFGS step (1: the quasi-Newton step) or Adam's rate (m per step)
    history: int = 20  # L-BFGS correction pairs


SOLVERS = typing.get_args(typing.get_type_hints(SolverSettings)["solver"])


@dataclass
class Optimum:
    """vertices: (T, V, 3) optimised drape, m. start_terms / final_terms: per frame, the loss terms (the
    loss's units) of the window at the frame's start drape and at its optimum. evaluations: loss
    evaluations per frame."""

    vertices: torch.Tensor
    start_terms: list[dict[str, float]] = field(default_factory=list)
    final_terms: list[dict[str, float]] = field(default_factory=list)
    evaluations: list[int] = field(default_factory=list)


def minimise(f: Callable[[torch.Tensor], torch.Tensor], x0: torch.Tensor, solver: str = "lbfgs", iterations: int = 50,
             lr: float = 1.0, history: int = 20) -> tuple[torch.Tensor, int]:  # fmt: skip
    """Minimise the scalar ``f`` over x, from x0 (any shape; m for a drape). "lbfgs": at most ``iterations``
    L-BFGS iterations with a strong-Wolfe line search, step ``lr`` (1: the quasi-Newton step) and ``history``
    correction pairs; "adam": ``iterations`` Adam steps of rate ``lr`` (about lr per coordinate per step, m).
    Returns the evaluated point of lowest f (no gradient; Adam's steps need not descend) and the number of
    evaluations of f."""
    if solver not in SOLVERS:
        raise ValueError(f"optimum solver must be one of {', '.join(SOLVERS)}, not {solver!r}")
    x = x0.detach().clone().requires_grad_(True)
    n, best, best_x = 0, math.inf, x0.detach()

    def closure():
        nonlocal n, best, best_x
        n += 1
        opt.zero_grad()
        value = f(x)
        if value.item() < best:
            best, best_x = value.item(), x.detach().clone()
        value.backward()
        return value

    if solver == "lbfgs":
        opt = torch.optim.LBFGS([x], lr=lr, max_iter=iterations, history_size=history, line_search_fn="strong_wolfe")
        opt.step(closure)
    else:
        opt = torch.optim.Adam([x], lr=lr)
        for _ in range(iterations):
            opt.step(closure)
    return best_x, n


def optimise_sequence(loss: WindowLoss, start: torch.Tensor, window: int, solver: str = "lbfgs", iterations: int = 50,
                      lr: float = 1.0, history: int = 20) -> Optimum:  # fmt: skip
    """The optimum of ``loss`` (module docstring) over a sequence: frame t minimised from start[t] with the
    ``window`` - 1 frames before it fixed; ``start`` (T, V, 3) m; the solver settings as :func:`minimise`.
    Raises ValueError on a non-finite loss at a frame's start or optimum. Progress: a bar on a terminal, and
    a log line at every tenth of the frames."""
    done: list[torch.Tensor] = []
    result = Optimum(vertices=start.new_empty(start.shape))
    T, t0 = start.shape[0], time.perf_counter()
    for t in progress(range(T), desc="optimum", unit="frame"):
        before = [done[max(i, 0)] if done else start[0] for i in range(t - window + 1, t)]

        def of(x: torch.Tensor, before=before, t=t) -> torch.Tensor:
            return loss(t, torch.stack([*before, x]))[0]

        with torch.no_grad():
            start_terms = _floats(loss(t, torch.stack([*before, start[t]]))[1], t, "start")
        x, n = minimise(of, start[t], solver, iterations, lr, history)
        with torch.no_grad():
            final_terms = _floats(loss(t, torch.stack([*before, x]))[1], t, "optimum")
        done.append(x)
        result.vertices[t] = x
        result.start_terms.append(start_terms)
        result.final_terms.append(final_terms)
        result.evaluations.append(n)
        if (t + 1) % max(1, T // 10) == 0 and t + 1 < T:
            log.info("optimum: frame %d of %d, loss %.4g -> %.4g, %.0f s", t + 1, T, sum(start_terms.values()),
                     sum(final_terms.values()), time.perf_counter() - t0)  # fmt: skip
    return result


def sequence_terms(loss: WindowLoss, drape: torch.Tensor, window: int) -> list[dict[str, float]]:
    """Per frame t, the terms of ``loss`` (module docstring) on the window of ``drape`` (T, V, 3) m ending at t
    (frames before the first repeat the first): how a method's own loss scores a whole drape, trained or not."""
    with torch.no_grad():
        return [_floats(loss(t, drape[[max(i, 0) for i in range(t - window + 1, t + 1)]])[1], t, "drape") for t in range(len(drape))]


def _floats(terms: dict[str, torch.Tensor], t: int, where: str) -> dict[str, float]:
    """The terms as floats; ValueError naming the non-finite ones."""
    out = {k: float(v) for k, v in terms.items()}
    bad = [k for k, v in out.items() if not math.isfinite(v)]
    if bad:
        raise ValueError(f"optimum: non-finite loss term(s) {bad} at frame {t} ({where})")
    return out
