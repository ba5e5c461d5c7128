"""Garment skinning weights from the body: GAPS's RBF body participation, SNUG's nearest vertex,
NCS's smoothed nearest vertex."""

from __future__ import annotations

import torch
from scipy.spatial import cKDTree


def rbf_weights(garment_rest: torch.Tensor, body_rest: torch.Tensor, body_weights: torch.Tensor, k: float = 0.25, chunk: int = 512) -> torch.Tensor:
    """GAPS body participation (paper Eq. 5-7): for garment vertex i with nearest-body distance m_i,
    p_ij = exp(-(d_ij - m_i)^2 / (k m_i^2)) over all body vertices j; weights = normalize(P W_body).

    The paper states k = 0.5; the public code uses 0.25 (the default here). (V,3), (Vb,3), (Vb,J) -> (V,J).
    """
    g, b, W = garment_rest.double(), body_rest.double(), body_weights.double()
    out = []
    for rows in g.split(chunk):
        d = torch.cdist(rows, b)  # (n, Vb)
        m = d.min(1, keepdim=True).values.clamp_min(1e-6)
        P = torch.exp(-((d - m) ** 2) / (k * m * m))
        w = P @ W
        out.append(w / w.sum(1, keepdim=True))
    return torch.cat(out).to(body_weights.dtype)


def nearest_indices(garment_rest: torch.Tensor, body_rest: torch.Tensor) -> torch.Tensor:
    """(V,) index of the nearest body vertex of each garment vertex."""
    _, idx = cKDTree(body_rest.detach().cpu().numpy()).query(garment_rest.detach().cpu().numpy())
    return torch.as_tensor(idx, dtype=torch.long)


def nearest_weights(garment_rest: torch.Tensor, body_rest: torch.Tensor, body_weights: torch.Tensor) -> torch.Tensor:
    """SNUG: each garment vertex copies its nearest body vertex's weights. (V, J)."""
    return body_weights[nearest_indices(garment_rest, body_rest)].clone()


def smoothed_weights(weights: torch.Tensor, topology, iterations: int = 10) -> torch.Tensor:
    """NCS: ``iterations`` rounds of replacing each vertex's weights by the mean over its 1-ring
    (itself included), then renormalising. (V, J) -> (V, J)."""
    owner = topology.ring_owner
    deg = topology.ring_sizes.to(weights.dtype)[:, None]
    w = weights.clone()
    for _ in range(iterations):
        acc = w.clone().index_add(0, owner, w[topology.ring_idx])
        w = acc / (deg + 1)
    return w / w.sum(1, keepdim=True)
