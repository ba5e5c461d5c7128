"""Per-element mesh quantities, batched over leading dimensions, differentiable, finite on degenerate input.

Every function takes positions ``x`` (..., V, 3) (any number of leading batch dimensions, float32 or
float64) and returns values of the same dtype. Norms are guarded (``sqrt(. + tiny)``, clamped
denominators) so degenerate triangles and collapsed edges give finite values *and* gradients.
"""

from __future__ import annotations

import torch


def face_cross(x: torch.Tensor, faces: torch.Tensor) -> torch.Tensor:
    """Un-normalised face normals (x1 - x0) x (x2 - x0), length = 2 x face area (m^2). x (..., V, 3), faces (F, 3) -> (..., F, 3)."""
    v0, v1, v2 = x[..., faces[:, 0], :], x[..., faces[:, 1], :], x[..., faces[:, 2], :]
    return torch.cross(v1 - v0, v2 - v0, dim=-1)


def face_areas(x: torch.Tensor, faces: torch.Tensor) -> torch.Tensor:
    """Triangle areas (m^2). x (..., V, 3), faces (F, 3) -> (..., F)."""
    c = face_cross(x, faces)
    return 0.5 * torch.sqrt((c * c).sum(-1) + torch.finfo(x.dtype).tiny)


def face_normals(x: torch.Tensor, faces: torch.Tensor, eps: float = 1e-12) -> torch.Tensor:
    """Unit face normals, right-handed in the face's vertex order (zero for degenerate faces). x (..., V, 3) -> (..., F, 3)."""
    c = face_cross(x, faces)
    return c / c.norm(dim=-1, keepdim=True).clamp_min(eps)


def vertex_normals(x: torch.Tensor, faces: torch.Tensor, eps: float = 1e-12) -> torch.Tensor:
    """Area-weighted unit vertex normals: normalise(sum over incident faces of A_f n_f). x (..., V, 3), faces (F, 3) -> (..., V, 3).

    Vertices without faces (or whose weighted sum vanishes) get a zero normal.
    """
    c = face_cross(x, faces)  # 2 A_f n_f
    idx = faces.reshape(-1)
    contrib = c.unsqueeze(-2).expand(*c.shape[:-1], 3, 3).reshape(*c.shape[:-2], -1, 3)
    n = torch.zeros_like(x).index_add(-2, idx, contrib)
    return n / n.norm(dim=-1, keepdim=True).clamp_min(eps)


def edge_lengths(x: torch.Tensor, edges) -> torch.Tensor:
    """Edge lengths (m). x (..., V, 3); ``edges`` an (E, 2) index tensor or a Topology (its ``edges``) -> (..., E).

    The gradient of a collapsed (zero-length) edge is zero rather than NaN.
    """
    e = edges.edges if hasattr(edges, "edges") else edges
    d = x[..., e[:, 1], :] - x[..., e[:, 0], :]
    return torch.sqrt((d * d).sum(-1) + torch.finfo(x.dtype).tiny)


def dihedral_angles(x: torch.Tensor, hinges, hinge_opposite: torch.Tensor | None = None) -> torch.Tensor:
    """Signed dihedral angles (rad, 0 = flat, in (-pi, pi]) of interior edges: atan2(e_hat . (n0 x n1), n0 . n1).

    x (..., V, 3); ``hinges`` a Topology, or its ``hinge_edges`` (H, 2) (oriented as in the first face)
    followed by ``hinge_opposite`` (H, 2). n0 = e x (p0 - x0), n1 = (p1 - x0) x e are the (unnormalised)
    normals of the two faces (GAPS/SNUG code convention); the angle is positive when the second face's
    opposite vertex p1 lies behind the first face's plane (n0 . (p1 - x0) < 0). Returns (..., H). Finite with finite gradients for degenerate hinges: when both
    atan2 arguments vanish the cosine is nudged to eps (atan2(0, 0) has no gradient).
    """
    if hasattr(hinges, "hinge_edges"):
        hinge_edges, hinge_opposite = hinges.hinge_edges, hinges.hinge_opposite
    else:
        hinge_edges = hinges
        if hinge_opposite is None:
            raise ValueError("dihedral_angles needs a Topology, or hinge_edges and hinge_opposite")
    x0, x1 = x[..., hinge_edges[:, 0], :], x[..., hinge_edges[:, 1], :]
    p0, p1 = x[..., hinge_opposite[:, 0], :], x[..., hinge_opposite[:, 1], :]
    e = x1 - x0
    n0 = torch.cross(e, p0 - x0, dim=-1)
    n1 = torch.cross(p1 - x0, e, dim=-1)
    eps = torch.finfo(x.dtype).eps
    e_hat = e / torch.sqrt((e * e).sum(-1, keepdim=True) + eps**2)
    sin = (torch.cross(n0, n1, dim=-1) * e_hat).sum(-1)
    cos = (n0 * n1).sum(-1)
    degenerate = (sin.abs() < eps**2) & (cos.abs() < eps**2)
    cos = torch.where(degenerate, torch.full_like(cos, eps), cos)
    return torch.atan2(sin, cos)
