"""GAPS's canonical garment at rest: the template relaxed under GAPS's own loss on the canonical (rest-pose)
body, and how that relaxation changes with the body shape (``method.params.canonical: relaxed``).

The paper's templates are garments resting on the canonical body; this suite's parametric templates are cut
to the body with no gravity and no shape. For body shape beta the canonical garment before the network is
``template + transfer(beta)`` (the shape transfer); its relaxation d(beta) is the move that minimises GAPS's
training loss (k_ext at the end of the ramp, no inertia: the garment at rest) on the rest-pose body of that
shape. d is solved at the garment's own shape (d0) and at +-r_k on each of the first K shape components
(r = ``train.beta_range``) and taken piecewise linear in between: for b = beta - the garment's betas,
d(b) = d0 + sum_k max(b_k, 0) P_k + max(-b_k, 0) N_k, P_k = (d(+r_k e_k) - d0) / r_k and N_k = (d(-r_k e_k) - d0) / r_k.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass

import numpy as np
import torch

from drapebench.cache import Cache, body_key, content_hash
from drapebench.geometry.ops import vertex_normals
from drapebench.optimum import minimise

log = logging.getLogger("drapebench")
RELAXED = Cache("gaps_canonical", 1)  # bump when the solve or the stored arrays change


@dataclass
class Relaxation:
    """d0 (V, 3) m: the relaxation at the garment's own shape; pos, neg (V, 3, K) m per unit of the first K shape
    components above and below it; loss_start, loss_end (1 + 2K,): GAPS's loss at each solve's start and end."""

    d0: torch.Tensor
    pos: torch.Tensor
    neg: torch.Tensor
    loss_start: np.ndarray
    loss_end: np.ndarray

    def at(self, b: torch.Tensor) -> torch.Tensor:
        """(B, V, 3) m the relaxation for shape offsets b (B, S) from the garment's betas (components beyond K: none)."""
        k = self.pos.shape[-1]
        bk = b[:, :k].to(self.d0.dtype)
        return self.d0 + torch.einsum("vck,bk->bvc", self.pos, bk.clamp_min(0)) + torch.einsum("vck,bk->bvc", self.neg, (-bk).clamp_min(0))


def relax_at(m, b: torch.Tensor, iterations: int) -> tuple[torch.Tensor, float, float]:
    """GAPS ``m``'s canonical garment for shape offset b (S,) relaxed on the rest-pose body of that shape: its move
    (V, 3) m from ``template + transfer(b)`` minimising ``m._terms`` (at most ``iterations`` L-BFGS iterations),
    and the loss at the start and at the end."""
    body, W = m.body, m.p["train"]["window"]
    betas = (m.garment_betas + b)[None]
    with torch.no_grad():
        out = body.forward(betas, torch.zeros(1, body.n_joints, 3, dtype=body.dtype), torch.zeros(1, 3, dtype=body.dtype))
        bv = out.vertices.expand(W, -1, -1)
        bn = vertex_normals(out.vertices, body.faces).expand(W, -1, -1)
        start = m._canonical(torch.zeros(1, 1, 3 * len(m.template), dtype=body.dtype), betas, relaxed=False)[0, 0]  # rest pose: canonical = world
    epoch = m.p["train"]["kext_ramp_epochs"]

    def loss(x: torch.Tensor) -> torch.Tensor:
        return sum(m._terms(x[None].expand(W, -1, -1), bv, bn, epoch).values())

    x, _ = minimise(loss, start, "lbfgs", iterations)
    with torch.no_grad():
        return x - start, float(loss(start)), float(loss(x))


def relaxation(m, iterations: int) -> Relaxation:
    """The :class:`Relaxation` of GAPS ``m``'s garment (set up by ``m._setup``), cached by content (body, garment,
    GAPS's loss and skinning settings, material)."""
    r = [float(v) for v in m.p["train"]["beta_range"]]
    key = (body_key(m.body), m.garment_key, {k: v for k, v in m.p.items() if k != "train"}, m.p["train"]["kext_ramp_epochs"],
           m.p["train"]["window"], r, iterations, m.material, str(m.body.dtype))  # fmt: skip
    path = RELAXED.path(*key, prefix="relaxed", suffix=".pt")

    def build() -> Relaxation:
        t0 = time.perf_counter()
        S = m.body.n_betas
        offsets = [torch.zeros(S, dtype=m.body.dtype)]
        for k, rk in enumerate(r):
            for sign in (1.0, -1.0):
                b = torch.zeros(S, dtype=m.body.dtype)
                b[k] = sign * rk
                offsets.append(b)
        solves = [relax_at(m, b, iterations) for b in offsets]
        d = [s[0] for s in solves]
        pos = torch.stack([(d[1 + 2 * k] - d[0]) / rk for k, rk in enumerate(r)], -1)
        neg = torch.stack([(d[2 + 2 * k] - d[0]) / rk for k, rk in enumerate(r)], -1)
        rel = Relaxation(d[0], pos, neg, np.array([s[1] for s in solves]), np.array([s[2] for s in solves]))
        log.info("gaps: canonical garment relaxed at %d body shapes in %.0f s (loss %.4g -> %.4g at the garment's own shape, "
                 "mean move %.1f mm)", len(offsets), time.perf_counter() - t0, rel.loss_start[0], rel.loss_end[0],
                 1e3 * float(d[0].norm(dim=-1).mean()))  # fmt: skip
        return rel

    def write(rel: Relaxation, tmp) -> None:
        torch.save({"d0": rel.d0, "pos": rel.pos, "neg": rel.neg, "loss_start": rel.loss_start, "loss_end": rel.loss_end, "key": content_hash(*key)}, tmp)

    def read(p) -> Relaxation | None:
        s = torch.load(p, weights_only=False)
        return Relaxation(s["d0"], s["pos"], s["neg"], s["loss_start"], s["loss_end"]) if s.get("key") == content_hash(*key) else None

    return RELAXED.get_or_build(path, build, write, read)
