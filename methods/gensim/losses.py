"""GenSim's unsupervised losses (paper Eq. 2-9), each a :mod:`drapebench.physics` energy times its weight.

Every function takes the predicted garment x (B, V, 3) m of B frames of one garment and returns a scalar:
the frames' mean of the weighted term. The readings the paper leaves open are in ``methods/gensim/README.md``.
"""

from __future__ import annotations

import torch

from drapebench.geometry.ops import edge_lengths
from drapebench.geometry.proximity import nearest_body_vertex
from drapebench.geometry.sdf import closest_body_point
from drapebench.physics import (
    bending_energy,
    gravity_energy,
    hinge_collision_energy,
    laplacian_smoothness,
    pin_energy,
)

WEIGHTS = {"restrain": 1e2, "bending": 1.0, "pin": 1e2, "potential": 1e2, "smoothness": 1.0, "collision": 1e2, "l2": 1e2}
UNSUPERVISED = ("restrain", "bending", "pin", "potential", "smoothness", "collision")  # Eq. 9
SUPERVISED = ("l2", "smoothness", "collision")  # the paper's Table 2 baseline


def restrain(x, topo, fabric_mean: float, fabric_std: float, weight: float, reduction: str = "mean", offset: str = "dead_zone",
             huber: float | None = 5.0) -> torch.Tensor:
    """Eq. 2-3 per edge with phi = | |l| - |l0| | (m): z = |phi - mu_fabric| / sigma_fabric (``offset`` "printed"),
    max(phi - mu_fabric, 0) / sigma_fabric ("dead_zone": zero for phi <= mu, the rest length a minimum) or
    phi / sigma_fabric ("none"); the penalty is z^2, or beyond ``huber`` (in sigmas) its linear continuation
    2 h z - h^2; ``reduction`` "mean" or "sum" over the edges. As printed: "sum", "printed", huber None."""
    phi = (edge_lengths(x if x.dim() == 3 else x[None], topo.edges) - topo.rest_edge_lengths).abs()
    shifted = {"printed": lambda: (phi - fabric_mean).abs(), "dead_zone": lambda: torch.relu(phi - fabric_mean), "none": lambda: phi}
    if offset not in shifted:
        raise ValueError(f"gensim restrain offset must be one of {sorted(shifted)}, not {offset!r}")
    z = shifted[offset]() / fabric_std
    per_edge = z * z if huber is None else torch.where(z <= huber, z * z, 2.0 * huber * z - huber * huber)
    if reduction not in ("mean", "sum"):
        raise ValueError(f"gensim restrain reduction must be 'mean' or 'sum', not {reduction!r}")
    return weight * (per_edge.mean(-1) if reduction == "mean" else per_edge.sum(-1)).mean()


def bending(x, topo, material, weight: float, rest_angle: str = "flat") -> torch.Tensor:
    """Eq. 4: sum over hinges of |E|^2 / (4 (A1 + A2)) theta^2 / 2 with the deformed edge and faces (no
    stiffness factor: the physics energy divided by the material's bending stiffness)."""
    return weight * bending_energy(x, topo, material, rest_angle=rest_angle, scale="current").mean() / material.bending


def pin(x, arap, pins: torch.Tensor, weight: float) -> torch.Tensor:
    """Eq. 5: sum over pins of |G_i - x_i|^2 with G the ARAP-deformed garment (B, V, 3)."""
    return weight * pin_energy(x, arap[:, pins], pins).mean()


def potential(x, topo, material, free: torch.Tensor, weight: float) -> torch.Tensor:
    """Eq. 6: sum over the non-pin vertices (``free`` (V,) bool) of m g z (J)."""
    return weight * (gravity_energy(x, topo, material, per_element=True) * free).sum(-1).mean()


def smoothness(x, topo, weight: float) -> torch.Tensor:
    """Eq. 7: sum over vertices of |L x| with the cotangent Laplacian L."""
    return weight * laplacian_smoothness(x, topo).mean()


def l2(x, reference, weight: float) -> torch.Tensor:
    """The supervised baseline's data term: sum over vertices of |x - x_ref|^2 (m^2) to reference drapes (B, V, 3)."""
    return weight * ((x - reference) ** 2).sum(-1).sum(-1).mean()


def collision(x, body_vertices, body_normals, eps: float, weight: float, candidates=None, contact: str = "vertex", body_faces=None,
              outer_faces=None) -> torch.Tensor:  # fmt: skip
    """Eq. 8 (hinge reading): sum over vertices of max(eps - d, 0) with d the signed distance of each predicted
    vertex to the body (B, Vb, 3): ``contact`` "surface" the exact one to the closest point of the body's outer
    surface (``body_faces`` (Fb, 3), ``outer_faces`` (Fb,) bool; negative inside the whole body, as eps_c
    counts it; gradient along the closest point's direction), "vertex" n . (x - B_nu) with B_nu the nearest
    body vertex (among ``candidates``) and n its unit normal (``body_normals`` (B, Vb, 3))."""
    if contact == "surface":
        sp = closest_body_point(x.detach(), body_vertices.detach(), body_faces, outer_faces=outer_faces)
        point, normal = sp.point, sp.normal
    elif contact == "vertex":
        nn = nearest_body_vertex(x, body_vertices, body_normals, candidates)
        point, normal = nn.point, nn.normal
    else:
        raise ValueError(f"gensim contact must be 'surface' or 'vertex', not {contact!r}")
    return weight * hinge_collision_energy(x, point, normal, eps).mean()
