"""Garment-to-body proximity: nearest body vertex with its normal (what the losses use) and exact
signed distance to the body triangle mesh (what the metrics use), with culling of body parts far
from the garment.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from scipy.spatial import cKDTree


@dataclass
class NearestVertex:
    """index (B,N) body vertex index; point (B,N,3) its position; normal (B,N,3) its unit normal;
    distance (B,N) signed normal distance n . (x - p) in metres (negative = behind the body surface)."""

    index: torch.Tensor
    point: torch.Tensor
    normal: torch.Tensor
    distance: torch.Tensor


def nearest_indices(points: torch.Tensor, body_vertices: torch.Tensor, candidates: torch.Tensor | None = None) -> torch.Tensor:
    """Index (B,N) of the nearest body vertex per point; KD-tree on CPU, chunked cdist on GPU.

    ``candidates`` (C,) restricts the search to those body vertices (returned indices are global).
    """
    pts = points.detach()
    body = body_vertices.detach()
    if candidates is not None:
        body = body[:, candidates]
    B = pts.shape[0]
    if pts.is_cuda:
        out = []
        for b in range(B):
            rows = [torch.cdist(chunk, body[b]).argmin(-1) for chunk in pts[b].split(4096)]
            out.append(torch.cat(rows))
        idx = torch.stack(out)
    else:
        p, q = pts.cpu().numpy(), body.cpu().numpy()
        idx = torch.from_numpy(np.stack([cKDTree(q[b]).query(p[b], workers=1)[1] for b in range(B)])).to(points.device)
    if candidates is not None:
        idx = candidates[idx]
    return idx.long()


def nearest_body_vertex(
    points: torch.Tensor,
    body_vertices: torch.Tensor,
    body_normals: torch.Tensor,
    candidates: torch.Tensor | None = None,
) -> NearestVertex:
    """Nearest body vertex per garment point, with the signed normal distance.

    points (B,N,3), body_vertices (B,Vb,3), body_normals (B,Vb,3) unit; differentiable w.r.t.
    ``points`` and the body (the index selection itself is not).
    """
    if points.dim() == 2:
        points = points[None]
    idx = nearest_indices(points, body_vertices, candidates)
    gather = idx[..., None].expand(-1, -1, 3)
    p = torch.gather(body_vertices.expand(points.shape[0], -1, -1), 1, gather)
    n = torch.gather(body_normals.expand(points.shape[0], -1, -1), 1, gather)
    return NearestVertex(idx, p, n, ((points - p) * n).sum(-1))


def culled_body_vertices(
    garment_rest: torch.Tensor,
    body_rest: torch.Tensor,
    body_weights: torch.Tensor,
    margin: float = 0.1,
    min_weight: float = 0.05,
) -> torch.Tensor:
    """Body vertices a garment can touch under any pose: (C,) indices.

    Selects the joints that drive the body near the garment at rest (vertices within ``margin`` of
    the garment), then every body vertex skinned to those joints (weight > ``min_weight``).
    Because whole joint-driven parts are kept, the set stays valid when the body moves (a skirt
    keeps the pelvis and legs, never the head or arms).
    """
    tree = cKDTree(garment_rest.detach().cpu().numpy())
    d, _ = tree.query(body_rest.detach().cpu().numpy(), distance_upper_bound=margin)
    near = torch.from_numpy(np.isfinite(d))
    w = body_weights.detach().cpu()
    joints = (w[near] > min_weight).any(0)
    keep = (w[:, joints] > min_weight).any(1) | near
    return torch.nonzero(keep).squeeze(1).to(body_rest.device)


def signed_distance(points: torch.Tensor, body_vertices: torch.Tensor, body_faces: torch.Tensor) -> torch.Tensor:
    """Exact signed distance (m) from points (B,N,3) to the posed body mesh (B,Vb,3), negative inside.

    Uses libigl's point-mesh distance with the fast generalised winding number for the sign (robust
    to the body's small extra components such as the eyes). Not differentiable (a metric).
    """
    import igl

    if points.dim() == 2:
        points = points[None]
    F = body_faces.detach().cpu().numpy().astype(np.int64)
    out = []
    for b in range(points.shape[0]):
        P = points[b].detach().cpu().double().numpy()
        V = body_vertices[min(b, body_vertices.shape[0] - 1)].detach().cpu().double().numpy()
        s = igl.signed_distance(P, V, F, sign_type=igl.SIGNED_DISTANCE_TYPE_FAST_WINDING_NUMBER)[0]
        out.append(torch.from_numpy(np.asarray(s)))
    return torch.stack(out).to(points.device, points.dtype)
