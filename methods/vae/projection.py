"""Projection of simulated garment frames to the canonical space by optimisation (Eq. 9-12).

For every frame: min_X E_rec + w1 E_strain + w2 E_collision, with E_rec the squared distance (mm^2, mean
over vertices) between the garment model M_G(X) and the simulated frame, E_strain the squared Frobenius
norm of the Green-Lagrange strain of T_G(X) (in %^2, mean over faces) and E_collision the hinge
max(eps - SDF(X), 0) (mm, mean over vertices) against the learned SDF of the canonical body. Frames are
solved in order, each warm-started from the previous one (the first from the template); sequences of
equal length are solved together, frame by frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from drapebench.body.lbs import inverse_lbs
from drapebench.physics.energies import green_strain
from drapebench.progress import progress
from methods.vae.garment_model import garment_model, unposed


@dataclass
class Projection:
    """X (N, T, V, 3) canonical vertices (m); residual_mm (N, T) mean distance between M_G(X) and the
    simulated frame (mm); colliding (N, T) fraction of vertices with SDF(X) < 0 (canonical collisions)."""

    X: torch.Tensor
    residual_mm: torch.Tensor
    colliding: torch.Tensor


def projection_terms(diffused, sdf, topology, X, target, betas, transforms, cfg: dict) -> dict:
    """Eq. 9's weighted terms for canonical X (B, V, 3) against simulated frames target (B, V, 3), body
    shapes betas (B, S) and transforms (B, J, 4, 4): {"data": mm^2, "strain": %^2, "collision": mm}."""
    rest = unposed(diffused, X, betas)
    data = ((garment_model(diffused, X, betas, transforms, rest) - target) * 1e3).square().sum(-1).mean(-1)
    strain = (green_strain(rest, topology) * 1e2).square().sum((-1, -2)).mean(-1)
    hinge = (cfg["eps"] - sdf(X)).clamp_min(0) * 1e3
    return {"data": data, "strain": cfg["strain_weight"] * strain, "collision": cfg["collision_weight"] * hinge.mean(-1)}


def inverse_skinning(diffused, X, target, betas, transforms, iterations: int = 2) -> torch.Tensor:
    """Fixed-point inversion of the garment model: X <- LBS^-1(target; W(X)) - B_s(X, betas), from X (B, V, 3)."""
    with torch.no_grad():
        for _ in range(iterations):
            rest = inverse_lbs(target, diffused.weights(X), transforms)
            X = rest - (unposed(diffused, X, betas) - X)  # minus the shape offsets at X
    return X


def project_sequences(diffused, sdf, topology, template, frames, betas, transforms, cfg: dict, desc: str = "vae projection") -> Projection:
    """Canonical X of simulated frames (N, T, V, 3) m of N sequences with body shapes betas (N, S) and
    skinning transforms (N, T, J, 4, 4); template (V, 3) is the canonical garment the first frame starts from."""
    N, T, V, _ = frames.shape
    X = template[None].expand(N, V, 3).clone()
    out, residual, colliding = [], [], []
    for t in progress(range(T), desc=desc, unit="frame"):
        target, A = frames[:, t], transforms[:, t]
        if cfg["init"] == "inverse_skinning":
            X = inverse_skinning(diffused, X, target, betas, A)
        X = X.detach().requires_grad_(True)
        opt = torch.optim.Adam([X], lr=cfg["lr"])
        for _ in range(cfg["steps"] * (4 if t == 0 else 1)):
            loss = sum(v.sum() for v in projection_terms(diffused, sdf, topology, X, target, betas, A, cfg).values())
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
        X = X.detach()
        if not torch.isfinite(X).all():
            raise FloatingPointError(f"vae projection produced NaN/Inf at frame {t}; lower method.params.projection.lr")
        with torch.no_grad():
            residual.append((garment_model(diffused, X, betas, A) - target).norm(dim=-1).mean(-1) * 1e3)
            colliding.append((sdf(X) < 0).to(X.dtype).mean(-1))
        out.append(X)
    return Projection(torch.stack(out, 1), torch.stack(residual, 1), torch.stack(colliding, 1))
