"""Per-element mesh quantities, batched over leading dimensions, differentiable."""

from __future__ import annotations

import torch


def face_cross(x: torch.Tensor, faces: torch.Tensor) -> torch.Tensor:
    """Un-normalised face normals (e1 x e2), length = 2 x face area. x (..., V, 3), faces (F, 3) -> (..., F, 3)."""
    v0, v1, v2 = x[..., faces[:, 0], :], x[..., faces[:, 1], :], x[..., faces[:, 2], :]
    return torch.cross(v1 - v0, v2 - v0, dim=-1)


def face_areas(x: torch.Tensor, faces: torch.Tensor) -> torch.Tensor:
    """Triangle areas (m^2). x (..., V, 3), faces (F, 3) -> (..., F)."""
    c = face_cross(x, faces)
    return 0.5 * torch.sqrt((c * c).sum(-1) + torch.finfo(x.dtype).tiny)


def face_normals(x: torch.Tensor, faces: torch.Tensor, eps: float = 1e-12) -> torch.Tensor:
    """Unit face normals (zero for degenerate faces). x (..., V, 3) -> (..., F, 3)."""
    c = face_cross(x, faces)
    return c / c.norm(dim=-1, keepdim=True).clamp_min(eps)


def vertex_normals(x: torch.Tensor, faces: torch.Tensor, eps: float = 1e-12) -> torch.Tensor:
    """Area-weighted unit vertex normals. x (..., V, 3), faces (F, 3) -> (..., V, 3)."""
    c = face_cross(x, faces)  # area-weighted (x2)
    n = torch.zeros_like(x)
    idx = faces.reshape(-1)
    contrib = c.unsqueeze(-2).expand(*c.shape[:-1], 3, 3).reshape(*c.shape[:-2], -1, 3)
    n = n.index_add(-2, idx, contrib)
    return n / n.norm(dim=-1, keepdim=True).clamp_min(eps)


def edge_lengths(x: torch.Tensor, edges: torch.Tensor) -> torch.Tensor:
    """Edge lengths (m). x (..., V, 3), edges (E, 2) -> (..., E); finite gradient for collapsed edges."""
    d = x[..., edges[:, 1], :] - x[..., edges[:, 0], :]
    return torch.sqrt((d * d).sum(-1) + torch.finfo(x.dtype).tiny)


def dihedral_angles(x: torch.Tensor, hinge_edges: torch.Tensor, hinge_opposite: torch.Tensor) -> torch.Tensor:
    """Signed dihedral angles (rad, 0 = flat) of hinges: atan2(e_hat . (n0 x n1), n0 . n1).

    x (..., V, 3); hinge_edges (H, 2) oriented as in the first face; hinge_opposite (H, 2).
    Finite (with finite gradients) for degenerate hinges: the atan2 arguments are guarded.
    """
    x0, x1 = x[..., hinge_edges[:, 0], :], x[..., hinge_edges[:, 1], :]
    p0, p1 = x[..., hinge_opposite[:, 0], :], x[..., hinge_opposite[:, 1], :]
    e = x1 - x0
    n0 = torch.cross(e, p0 - x0, dim=-1)
    n1 = torch.cross(p1 - x0, e, dim=-1)
    tiny = torch.finfo(x.dtype).eps
    e_hat = e / torch.sqrt((e * e).sum(-1, keepdim=True) + tiny**2)
    sin = (torch.cross(n0, n1, dim=-1) * e_hat).sum(-1)
    cos = (n0 * n1).sum(-1)
    # atan2(0, 0) has an undefined gradient: nudge cos away from exactly zero when both vanish.
    degenerate = (sin.abs() < tiny**2) & (cos.abs() < tiny**2)
    cos = torch.where(degenerate, torch.full_like(cos, tiny), cos)
    return torch.atan2(sin, cos)
