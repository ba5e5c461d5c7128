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
