"""Garment skinning weights from the body: GAPS's RBF body participation and NCS's smoothing of the
nearest-vertex weights (the nearest-vertex weights themselves: ``drapebench.body.skinning``)."""

from __future__ import annotations

import torch

from drapebench.geometry.ops import ring_smooth


def rbf_average(garment_rest: torch.Tensor, body_rest: torch.Tensor, values: torch.Tensor, k: float = 0.25, chunk: int = 512) -> torch.Tensor:
    """GAPS body participation (paper Eq. 5-7) as an average: for garment vertex i with nearest-body distance
    m_i, p_ij = exp(-(d_ij - m_i)^2 / (k m_i^2)) over all body vertices j, and the result is
    sum_j p_ij values_j / sum_j p_ij. (V, 3) m, (Vb, 3) m, (Vb, D) -> (V, D)."""
    g, b, vals = garment_rest.double(), body_rest.double(), values.double()
    out = []
    for rows in g.split(chunk):
        d = torch.cdist(rows, b)  # (n, Vb)
        m = d.min(1, keepdim=True).values.clamp_min(1e-6)
        P = torch.exp(-((d - m) ** 2) / (k * m * m))
        out.append((P @ vals) / P.sum(1, keepdim=True))
    return torch.cat(out).to(values.dtype)


def rbf_weights(garment_rest: torch.Tensor, body_rest: torch.Tensor, body_weights: torch.Tensor, k: float = 0.25) -> torch.Tensor:
    """GAPS skinning weights normalize(P W_body) (paper Eq. 5-7; :func:`rbf_average` of the body's weights).
    The paper states k = 0.5; the public code uses 0.25 (the default here). (V,3), (Vb,3), (Vb,J) -> (V,J)."""
    w = rbf_average(garment_rest, body_rest, body_weights, k)
    return w / w.sum(1, keepdim=True)


def rbf_shapedirs(garment_rest: torch.Tensor, body_rest: torch.Tensor, shapedirs: torch.Tensor, k: float = 0.25) -> torch.Tensor:
    """The body's shape blend shapes carried to the garment by the same participation: (V, 3) m, (Vb, 3) m,
    shapedirs (Vb, 3, S) m per unit beta -> (V, 3, S)."""
    Vb, _, S = shapedirs.shape
    return rbf_average(garment_rest, body_rest, shapedirs.reshape(Vb, 3 * S), k).reshape(-1, 3, S)


def smoothed_weights(weights: torch.Tensor, topology, iterations: int = 10) -> torch.Tensor:
    """NCS: ``iterations`` rounds of replacing each vertex's weights by the mean over its 1-ring
    (itself included), then renormalising. (V, J) -> (V, J)."""
    w = ring_smooth(weights, topology, iterations)
    return w / w.sum(1, keepdim=True)
