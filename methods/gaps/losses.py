"""GAPS's loss terms: each is a :mod:`drapebench.physics` energy times its weight, summed over the
batch's frames and divided by a count ``n``: :func:`loss_terms` divides per ``normalisation`` (the GAPS
code's "code": strain, bending, gravity and inextensibility by the B x W frames, collision and inertia by
the B windows; "batch": every term by B).

Shapes: x (B*W, V, 3) draped vertices of B windows of W frames (m); ``nn`` where each vertex meets
the body: ``.point`` (B*W, V, 3), unit ``.normal`` (B*W, V, 3) and signed ``.distance`` (B*W, V) m
(:class:`drapebench.geometry.sdf.SurfacePoint` or :class:`drapebench.geometry.proximity.NearestVertex`). Every function returns
a scalar tensor (J, or the energy's unit times its weight).
"""

from __future__ import annotations

import torch

from drapebench.physics import (
    bending_energy,
    collision_aware_kext,
    collision_energy,
    gravity_energy,
    inertia_energy,
    inextensibility_energy,
    stvk_energy,
)


def strain(x: torch.Tensor, topo, material, n: int) -> torch.Tensor:
    """StVK membrane energy (J) summed over x's frames, divided by ``n``."""
    return stvk_energy(x, topo, material).sum() / n


def bending(x: torch.Tensor, topo, material, n: int, mode: str = "blend", blend: torch.Tensor | None = None, scale: str = "edge") -> torch.Tensor:
    """Bending energy (J) summed over x's frames, divided by ``n``, against flat (``mode`` "flat"), template ("template") or, for "blend",
    rest angles blended per hinge edge by ``blend`` (E,) in [0, 1] (GAPS Eq. 12); each hinge scaled per ``scale``
    (:func:`drapebench.physics.bending_energy`: "edge", the deformed edge length over the rest areas, as the code; "rest")."""
    rest_angle = "template" if mode == "template" else "flat"
    return bending_energy(x, topo, material, rest_angle=rest_angle, blend=blend if mode == "blend" else None, scale=scale).sum() / n


def blend_weights(template: torch.Tensor, body_vertices: torch.Tensor, body_normals: torch.Tensor, nearest: torch.Tensor,
                  hinge_edges: torch.Tensor, mode: str = "normal") -> torch.Tensor:
    """GAPS Eq. 12's per-hinge weight alpha (H,) in [0, 1] of the template angle: each template vertex's (V, 3) m
    distance to its ``nearest`` (V,) vertex of the rest body (body_vertices, unit body_normals (Vb, 3)), averaged over
    the hinge edge's two ends (hinge_edges (H, 2)) and min-max normalised over the hinges. ``mode`` "normal": the
    signed distance along that body vertex's normal (the code's ``compute_bending_coeff``); "distance": the
    Euclidean distance (this suite's earlier reading)."""
    offset = template - body_vertices[nearest]
    d = (offset * body_normals[nearest]).sum(-1) if mode == "normal" else offset.norm(dim=-1)
    edge_d = d[hinge_edges].mean(-1)
    return (edge_d - edge_d.min()) / (edge_d.max() - edge_d.min()).clamp_min(1e-9)


def gravity(x: torch.Tensor, topo, material, n: int) -> torch.Tensor:
    """Gravitational potential energy (J) summed over x's frames, divided by ``n``."""
    return gravity_energy(x, topo, material).sum() / n


def collision(x: torch.Tensor, nn, n: int, weight: float, eps: float) -> torch.Tensor:
    """weight x cubic collision penalty (m^3) per window against the body point ``nn.point`` along ``nn.normal``, margin ``eps`` m."""
    return weight * collision_energy(x, nn.point, nn.normal, eps).sum() / n


def inertia(xw: torch.Tensor, topo, material) -> torch.Tensor:
    """Inertia (J) of the last frame of each window xw (B, W, V, 3) against stop_gradient(2 x1 - x0) of
    the two frames before it (no gradient reaches the earlier frames), per window."""
    x1, x0 = xw[:, -2].detach(), xw[:, -3].detach()
    return inertia_energy(xw[:, -1], x1, (x1 - x0) / material.dt, topo, material).sum() / xw.shape[0]


PAPER_KEXT_EPOCHS = 100  # GAPS Eq. 16: k_ext = 1 + min(10 d_c, 0.03) min(epoch, 100), at most 4


def contact_distance(x: torch.Tensor, nn) -> torch.Tensor:
    """(B*W, V) m: each vertex of x (B*W, V, 3) m along the body normal from its body point, n . (x - p), with
    ``nn.point`` and ``nn.normal`` held constant: ``nn.distance``'s value, with the gradient n in x (the GAPS
    code's distance, which k_ext is differentiated through)."""
    return ((x - nn.point.detach()) * nn.normal.detach()).sum(-1)


def extension_factor(distance: torch.Tensor, epoch: int, mode: str, eps: float, ramp_epochs: int) -> torch.Tensor:
    """k_ext per vertex (B*W, V) from the signed body distance (m): GAPS Eq. 16 for ``mode`` "collision"
    with the paper's 100-epoch ramp compressed into ``ramp_epochs`` (the same cap, 4, reached at
    ``ramp_epochs``), 1 everywhere for "one" (a (1,) tensor). Differentiable in ``distance`` (detach it for a
    constant factor)."""
    if mode == "collision":
        paper_epoch = PAPER_KEXT_EPOCHS * min(epoch, ramp_epochs) / ramp_epochs
        return collision_aware_kext(distance, paper_epoch, eps, ramp_epochs=PAPER_KEXT_EPOCHS)
    return torch.ones(1, dtype=distance.dtype, device=distance.device)


def inextensibility(x: torch.Tensor, topo, k_ext: torch.Tensor, n: int, weight: float) -> torch.Tensor:
    """weight x collision-aware inextensibility energy (m^6) summed over x's frames, divided by ``n``,
    with extension factor ``k_ext``."""
    return weight * inextensibility_energy(x, topo, k_ext).sum() / n


def loss_terms(x: torch.Tensor, window: int, nn, topo, material, p: dict, epoch: int, blend: torch.Tensor) -> tuple[dict, torch.Tensor | None]:
    """GAPS's named, weighted loss terms of one batch x (B*W, V, 3) under parameters ``p``
    (:func:`methods.gaps.config.gaps_params`) at ``epoch``; also k_ext (None without inextensibility), differentiated
    through the body distance with ``kext_gradient`` (the code), else held constant.
    ``p["normalisation"]`` "code" divides the per-frame terms by the B x W frames and collision and inertia by
    the B windows (the public code); "batch" divides every term by B."""
    B = x.shape[0] // window
    frames = B * window if p["normalisation"] == "code" else B
    terms = {
        "strain": strain(x, topo, material, frames),
        "bending": bending(x, topo, material, frames, p["bending"], blend, p["bending_scale"]),
        "gravity": gravity(x, topo, material, frames),
        "collision": collision(x, nn, B, p["collision_weight"], p["collision_eps"]),
        "inertia": inertia(x.reshape(B, window, *x.shape[1:]), topo, material),
    }
    k_ext = None
    if p["inextensibility_weight"] > 0:
        distance = contact_distance(x, nn) if p["kext_gradient"] else nn.distance.detach()
        k_ext = extension_factor(distance, epoch, p["kext"], p["collision_eps"], p["train"]["kext_ramp_epochs"])
        terms["inext"] = inextensibility(x, topo, k_ext, frames, p["inextensibility_weight"])
    return terms, k_ext
