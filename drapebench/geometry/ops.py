"""Per-element mesh quantities, batched over leading dimensions, differentiable, finite on degenerate input.

Every function takes positions ``x`` (..., V, 3) (any number of leading batch dimensions, float32 or
float64) and returns values of the same dtype. Norms are guarded (``sqrt(. + tiny)``, clamped
denominators) so degenerate triangles and collapsed edges give finite values *and* gradients.
"""

from __future__ import annotations

import torch


def corners(x: torch.Tensor, index: torch.Tensor) -> torch.Tensor:
    """Positions of the vertices ``index`` (K, n) of x (..., V, 3), component-major: (n, 3, ..., K) (m).

    ``corners(x, faces)[j]`` holds the j-th corner of every face, its x, y, z in ``[0]``, ``[1]``, ``[2]``.
    One index_select on a (3 x batch, V) copy of x: on the CPU several times faster than n gathers
    ``x[..., index[:, j], :]``, and each component is contiguous over K. Differentiable w.r.t. x.
    """
    lead, n_vertices = x.shape[:-2], x.shape[-2]
    rows = x.movedim(-1, 0).reshape(-1, n_vertices)
    picked = rows.index_select(1, index.t().reshape(-1))
    return picked.view(3, *lead, index.shape[1], index.shape[0]).movedim(-2, 0)


def _cross_xyz(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Cross product of component-major vectors a, b (3, ...) -> (3, ...)."""
    return torch.stack((a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]))


def _face_cross_xyz(x: torch.Tensor, faces: torch.Tensor) -> torch.Tensor:
    v0, v1, v2 = corners(x, faces)
    return _cross_xyz(v1 - v0, v2 - v0)


def face_cross(x: torch.Tensor, faces: torch.Tensor) -> torch.Tensor:
    """Un-normalised face normals (x1 - x0) x (x2 - x0), length = 2 x face area (m^2). x (..., V, 3), faces (F, 3) -> (..., F, 3)."""
    return _face_cross_xyz(x, faces).movedim(0, -1)


def face_areas(x: torch.Tensor, faces: torch.Tensor) -> torch.Tensor:
    """Triangle areas (m^2). x (..., V, 3), faces (F, 3) -> (..., F)."""
    c = _face_cross_xyz(x, faces)
    return 0.5 * torch.sqrt((c * c).sum(0) + torch.finfo(x.dtype).tiny)


def face_normals(x: torch.Tensor, faces: torch.Tensor, eps: float = 1e-12) -> torch.Tensor:
    """Unit face normals, right-handed in the face's vertex order (zero for degenerate faces). x (..., V, 3) -> (..., F, 3)."""
    c = face_cross(x, faces)
    return c / c.norm(dim=-1, keepdim=True).clamp_min(eps)


def vertex_normals(x: torch.Tensor, faces: torch.Tensor, eps: float = 1e-12) -> torch.Tensor:
    """Area-weighted unit vertex normals: normalise(sum over incident faces of A_f n_f). x (..., V, 3), faces (F, 3) -> (..., V, 3).

    Vertices without faces (or whose weighted sum vanishes) get a zero normal.
    """
    c = _face_cross_xyz(x, faces)  # 2 A_f n_f, (3, ..., F)
    n = x.new_zeros((3, *x.shape[:-2], x.shape[-2]))
    n = n.index_add(-1, faces.t().reshape(-1), c.repeat(*(1,) * (c.dim() - 1), 3))
    return (n / torch.sqrt((n * n).sum(0)).clamp_min(eps)).movedim(0, -1).contiguous()


def edge_lengths(x: torch.Tensor, edges) -> torch.Tensor:
    """Edge lengths (m). x (..., V, 3); ``edges`` an (E, 2) index tensor or a Topology (its ``edges``) -> (..., E).

    The gradient of a collapsed (zero-length) edge is zero rather than NaN.
    """
    e = edges.edges if hasattr(edges, "edges") else edges
    x0, x1 = corners(x, e)
    d = x1 - x0
    return torch.sqrt((d * d).sum(0) + torch.finfo(x.dtype).tiny)


def dihedral_angles(x: torch.Tensor, hinges, hinge_opposite: torch.Tensor | None = None) -> torch.Tensor:
    """Signed dihedral angles (rad, 0 = flat, in (-pi, pi]) of interior edges: atan2(e_hat . (n0 x n1), n0 . n1).

    x (..., V, 3); ``hinges`` a Topology, or its ``hinge_edges`` (H, 2) (oriented as in the first face)
    followed by ``hinge_opposite`` (H, 2). n0 = e x (p0 - x0), n1 = (p1 - x0) x e are the (unnormalised)
    normals of the two faces (the SNUG code's convention); the angle is positive when the second face's
    opposite vertex p1 lies behind the first face's plane (n0 . (p1 - x0) < 0). Returns (..., H). Finite with finite gradients for degenerate hinges: when both
    atan2 arguments vanish the cosine is nudged to eps (atan2(0, 0) has no gradient).
    """
    if hasattr(hinges, "hinge_edges"):
        hinge_edges, hinge_opposite = hinges.hinge_edges, hinges.hinge_opposite
    else:
        hinge_edges = hinges
        if hinge_opposite is None:
            raise ValueError("dihedral_angles needs a Topology, or hinge_edges and hinge_opposite")
    x0, x1, p0, p1 = corners(x, torch.cat((hinge_edges, hinge_opposite), 1))
    e, b = x1 - x0, p1 - x0
    n0 = _cross_xyz(e, p0 - x0)
    n1 = _cross_xyz(b, e)
    eps = torch.finfo(x.dtype).eps
    # (n0 x n1) = -e (n0 . b), so (n0 x n1) . e_hat = -(n0 . b) |e|^2 / sqrt(|e|^2 + eps^2)
    e2 = (e * e).sum(0)
    sin = -(n0 * b).sum(0) * e2 / torch.sqrt(e2 + eps**2)
    cos = (n0 * n1).sum(0)
    degenerate = (sin.abs() < eps**2) & (cos.abs() < eps**2)
    cos = torch.where(degenerate, torch.full_like(cos, eps), cos)
    return torch.atan2(sin, cos)


def ring_smooth(x: torch.Tensor, topology, rounds: int) -> torch.Tensor:
    """(V, C): ``rounds`` rounds of replacing each vertex's values x (V, C) by their mean over its 1-ring with
    the vertex itself, over a :class:`~drapebench.geometry.topology.Topology`'s rings (a low-pass filter)."""
    owner, idx = topology.ring_owner, topology.ring_idx
    deg = topology.ring_sizes.to(x.dtype)[:, None] + 1
    for _ in range(rounds):
        x = x.index_add(0, owner, x[idx]) / deg
    return x


def ring_mean(x: torch.Tensor, topology) -> torch.Tensor:
    """(B, V, C): the mean of each vertex's 1-ring neighbours' values x (B, V, C) (a vertex without
    neighbours gets 0) over a :class:`~drapebench.geometry.topology.Topology`'s rings."""
    owner, idx = topology.ring_owner, topology.ring_idx
    total = torch.zeros_like(x).index_add_(1, owner, x[:, idx])
    return total / topology.ring_sizes.clamp_min(1).to(x.dtype)[None, :, None]
