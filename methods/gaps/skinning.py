"""Garment skinning weights from the body: GAPS's RBF body participation and NCS's smoothing of the
nearest-vertex weights (the nearest-vertex weights themselves: ``drapebench.body.skinning``)."""

from __future__ import annotations

import torch


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
