"""GAPS's canonical garment at rest: the template relaxed under GAPS's own loss on the canonical (rest-pose)
body, and how that relaxation changes with the body shape (``method.params.canonical: relaxed``).

The paper's templates are garments resting on the canonical body; this suite's parametric templates are cut
to the body with no gravity and no shape. For body shape beta the canonical garment before the network is
``template + transfer(beta)`` (the shape transfer); its relaxation d(beta) is the move that minimises GAPS's
training loss (k_ext at the end of the ramp, no inertia: the garment at rest) on the rest-pose body of that
shape, with the collision margin ``relax_clearance`` (larger than training's, so that the skinned garment keeps
clear of the body in motion) and, for ablations of L_inext, GAPS's own L_inext weight
(``relax_inextensibility_weight``: the same canonical garment, another training loss). d is solved on a grid
of shape offsets b = beta - the garment's betas: every combination of the values ``relax_grid`` on the first
``relax_components`` components (the others 0), and interpolated multilinearly between the grid points
(clamped to the grid's range outside it): a grid, because the relaxations of two components do not add.
"""

from __future__ import annotations

import itertools
import logging
import math
import time
from dataclasses import dataclass

import numpy as np
import torch

from drapebench.cache import Cache, body_key, content_hash
from drapebench.geometry.ops import vertex_normals
from drapebench.optimum import minimise
from methods.gaps.basis import KEYS as BASIS_KEYS

log = logging.getLogger("drapebench")
RELAXED = Cache("gaps_canonical", 3)  # bump when the solve or the stored arrays change


@dataclass
class Relaxation:
    """grid (G,) shape-offset values on each of the first K components; d (G^K, V, 3) m (float64): the relaxation at each grid
    point (itertools.product order, the last component fastest); loss_start, loss_end (G^K,): GAPS's loss at each
    solve's start and end."""

    grid: torch.Tensor
    d: torch.Tensor
    loss_start: np.ndarray
    loss_end: np.ndarray

    def to(self, device) -> Relaxation:
        """This relaxation with its grid and moves on ``device`` (a cached one is read onto the CPU)."""
        return Relaxation(self.grid.to(device), self.d.to(device), self.loss_start, self.loss_end)

    def at(self, b: torch.Tensor) -> torch.Tensor:
        """(B, V, 3) m the relaxation for shape offsets b (B, S) from the garment's betas: multilinear in the first K
        components between the grid points, clamped to the grid's range; the other components do not enter."""
        g, G = self.grid.to(self.d.dtype), len(self.grid)
        K = round(math.log(len(self.d), G))
        x = b[:, :K].to(g.dtype).clamp(g[0], g[-1])
        cell = (torch.searchsorted(g, x.contiguous(), right=True) - 1).clamp(0, G - 2)  # (B, K) lower grid index
        t = (x - g[cell]) / (g[cell + 1] - g[cell])  # (B, K) position in the cell, 0..1
        out = torch.zeros(len(b), *self.d.shape[1:], dtype=self.d.dtype, device=self.d.device)
        for corner in itertools.product((0, 1), repeat=K):
            c = torch.tensor(corner, device=cell.device)
            index = ((cell + c) * G ** torch.arange(K - 1, -1, -1, device=cell.device)).sum(-1)  # (B,) flat grid index
            weight = torch.where(c.bool(), t, 1 - t).prod(-1)  # (B,)
            out = out + weight[:, None, None] * self.d[index]
        return out


def relax_at(m, b: torch.Tensor, iterations: int) -> tuple[torch.Tensor, float, float]:
    """GAPS ``m``'s canonical garment for shape offset b (S,) relaxed on the rest-pose body of that shape: its move
    (V, 3) m (float64) from ``template + transfer(b)`` minimising ``m._terms`` with the collision margin
    ``relax_clearance`` and L_inext's weight ``relax_inextensibility_weight`` (None: the model's) (at most
    ``iterations`` L-BFGS iterations), and the loss at the start and at the end."""
    body, W = m.body, m.p["train"]["window"]
    betas = (m.garment_betas + b)[None]
    with torch.no_grad():  # solved in float64 whatever the body's dtype: float32 and float64 runs share one relaxation
        out = body.forward(betas, torch.zeros(1, body.n_joints, 3, dtype=body.dtype, device=body.device),
                           torch.zeros(1, 3, dtype=body.dtype, device=body.device))
        bv = out.vertices.double().expand(W, -1, -1)
        bn = vertex_normals(out.vertices, body.faces).double().expand(W, -1, -1)
        start = m._canonical(torch.zeros(1, 1, 3 * len(m.template), dtype=body.dtype, device=body.device), betas, relaxed=False)[0, 0].double()  # rest pose: canonical = world
    epoch = m.p["train"]["kext_ramp_epochs"]
    inext = m.p["relax_inextensibility_weight"]
    p = {**m.p, "collision_eps": m.p["relax_clearance"], "inextensibility_weight": m.p["inextensibility_weight"] if inext is None else inext}

    def loss(x: torch.Tensor) -> torch.Tensor:
        return sum(m._terms(x[None].expand(W, -1, -1), bv, bn, epoch, p).values())

    x, _ = minimise(loss, start, "lbfgs", iterations)
    with torch.no_grad():
        return x - start, float(loss(start)), float(loss(x))


def relaxation(m) -> Relaxation:
    """The :class:`Relaxation` of GAPS ``m``'s garment (set up by ``m._setup``) on the grid of ``relax_grid`` x
    ``relax_components``, each solve at most ``relax_iterations`` L-BFGS iterations; cached by content (body,
    garment, GAPS's loss, skinning and relaxation settings, material)."""
    p = m.p
    grid = sorted(float(v) for v in p["relax_grid"])
    K = int(p["relax_components"])
    if len(grid) < 2 or not 1 <= K <= m.body.n_betas:
        raise ValueError(f"canonical: relaxed needs relax_grid of at least 2 values (got {grid}) and relax_components "
                         f"between 1 and the body's {m.body.n_betas} betas (got {K})")  # fmt: skip
    key = (body_key(m.body), m.garment_key, {k: v for k, v in p.items() if k not in ("train", *BASIS_KEYS)}, p["train"]["kext_ramp_epochs"],
           p["train"]["window"], m.material)  # fmt: skip
    path = RELAXED.path(*key, prefix="relaxed", suffix=".pt")

    def build() -> Relaxation:
        t0 = time.perf_counter()
        points = list(itertools.product(grid, repeat=K))
        solves = []
        for n, point in enumerate(points):
            b = torch.zeros(m.body.n_betas, dtype=m.body.dtype, device=m.body.device)
            b[:K] = torch.tensor(point, dtype=m.body.dtype, device=m.body.device)
            solves.append(relax_at(m, b, int(p["relax_iterations"])))
            log.info("gaps: canonical garment relaxed at body shape %d of %d (offset %s): loss %.4g -> %.4g, %.0f s", n + 1,
                     len(points), list(point), solves[-1][1], solves[-1][2], time.perf_counter() - t0)  # fmt: skip
        return Relaxation(torch.tensor(grid, device="cpu"), torch.stack([d for d, _, _ in solves]).cpu(), np.array([s[1] for s in solves]),
                          np.array([s[2] for s in solves]))  # fmt: skip

    def write(rel: Relaxation, tmp) -> None:
        torch.save({"grid": rel.grid, "d": rel.d, "loss_start": rel.loss_start, "loss_end": rel.loss_end, "key": content_hash(*key)}, tmp)

    def read(path_) -> Relaxation | None:
        s = torch.load(path_, weights_only=False)
        return Relaxation(s["grid"], s["d"], s["loss_start"], s["loss_end"]) if s.get("key") == content_hash(*key) else None

    return RELAXED.get_or_build(path, build, write, read)
