"""The VAE's loss (Eq. 13-16) and the regressor's (Eq. 18), each term weighted, in mm where a length."""

from __future__ import annotations

import torch

from drapebench.physics.energies import laplacian


def collision(sdf, X: torch.Tensor, eps: float) -> torch.Tensor:
    """Mean over vertices and garments of max(eps - SDF(X), 0) in mm for canonical garments X (B, V, 3) m."""
    return ((eps - sdf(X)).clamp_min(0) * 1e3).mean()


def normal_noise(shape: tuple, like: torch.Tensor, generator: torch.Generator | None = None) -> torch.Tensor:
    """Standard normal draws of ``shape`` in the dtype and on the device of ``like``: drawn on the CPU by
    ``generator`` (a CPU generator; None: torch's global one) and moved, so a seed gives the same draws on any device."""
    return torch.randn(shape, generator=generator, dtype=like.dtype, device="cpu").to(like.device)


def latent_samples(n: int, mu: torch.Tensor, scale, generator: torch.Generator | None = None) -> torch.Tensor:
    """``n`` latent codes (n, latent) for the self-supervised term of Eq. 16: ``scale`` "prior" draws z ~ N(0, I)
    (the paper); "codes" draws z ~ N(m, diag(s^2)) with m, s the per-dimension mean and std of the posterior
    means mu (B, latent) of a batch (detached: where the data's codes live); a number s draws z ~ N(0, s^2 I)."""
    noise = normal_noise((n, mu.shape[-1]), mu, generator)
    if scale == "prior":
        return noise
    if scale == "codes":
        m = mu.detach()
        return m.mean(0) + (m.std(0) if len(m) > 1 else torch.ones_like(m[0])) * noise
    return float(scale) * noise


def kl_divergence(mu: torch.Tensor, logvar: torch.Tensor) -> torch.Tensor:
    """KL(N(mu, diag(exp(logvar))) || N(0, I)) in nats per code (B,), summed over latent dimensions."""
    return -0.5 * (1 + logvar - mu.square() - logvar.exp()).sum(-1)


def vae_terms(vae, sdf, topology, X: torch.Tensor, p: dict, eps: float, generator: torch.Generator | None = None,
              kl_factor: float = 1.0) -> dict:  # fmt: skip
    """Eq. 13's weighted terms for a batch of canonical garments X (B, V, 3) m: reconstruction (Eq. 14, L1,
    mm), Laplacian (Eq. 15, L1 of the cotangent Laplacians, mm), collision on the reconstructions and, with
    ``selfsup``, on decodings of ``samples`` latent codes drawn per ``sample_scale`` (:func:`latent_samples`;
    Eq. 16, mm), KL (nats per garment, weighted ``kl`` x ``kl_factor``, the annealing ramp); a term of weight 0
    is left out."""
    mu, logvar = vae.encode(X)
    z = mu + normal_noise(mu.shape, mu, generator) * torch.exp(0.5 * logvar)
    Y = vae.decode(z)
    terms = {"reconstruction": ((Y - X).abs() * 1e3).sum(-1).mean()}
    if p["laplacian"]:
        terms["laplacian"] = p["laplacian"] * ((laplacian(Y, topology) - laplacian(X, topology)).abs() * 1e3).sum(-1).mean()
    if p["kl"]:
        terms["kl"] = p["kl"] * kl_factor * kl_divergence(mu, logvar).mean()
    if p["collision"]:
        terms["collision"] = p["collision"] * collision(sdf, Y, eps)
        if p["selfsup"]:
            z_rand = latent_samples(int(p["samples"]), mu, p["sample_scale"], generator)
            terms["collision_sampled"] = p["collision"] * collision(sdf, vae.decode(z_rand), eps)
    return terms


def regressor_terms(pred: torch.Tensor, target: torch.Tensor, p: dict) -> dict:
    """Eq. 18 for latent codes pred and target (B, T, latent): L1 of positions, and (weighted rho_1, rho_2)
    of velocities and accelerations (finite differences per frame), means over codes and frames."""
    terms = {"position": (pred - target).abs().mean()}
    dp, dt = torch.diff(pred, dim=1), torch.diff(target, dim=1)
    if p["velocity"]:
        terms["velocity"] = p["velocity"] * (dp - dt).abs().mean()
    if p["acceleration"]:
        terms["acceleration"] = p["acceleration"] * (torch.diff(dp, dim=1) - torch.diff(dt, dim=1)).abs().mean()
    return terms
