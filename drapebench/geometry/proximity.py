"""Garment-to-body proximity: nearest body vertex with its normal (what the losses of Chen et al. 2024 and SNUG use) and
culling of body parts far from the garment (``culled_body_vertices``; every query takes the result
as ``candidates=``). The exact signed distance lives in :mod:`drapebench.geometry.sdf`.

CPU queries use scipy's KD-tree (one tree per frame, the frames split over torch's threads) and CUDA
tensors chunked ``torch.cdist``; the metrics find the nearest vertex of the whole body in the signed
distance's BVH pass instead (:func:`drapebench.geometry.sdf.body_proximity`). Positions are in metres, float32 or float64 (results follow the dtype of ``points``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from scipy.spatial import cKDTree

_CHUNK = 4096  # query points per cdist block on the GPU


@dataclass
class NearestVertex:
    """index (B,N) body vertex index; point (B,N,3) its position; normal (B,N,3) its unit normal;
    distance (B,N) signed normal distance n . (x - p) in metres (negative = behind the body surface)."""

    index: torch.Tensor
    point: torch.Tensor
    normal: torch.Tensor
    distance: torch.Tensor


def _as_batch(points: torch.Tensor, body_vertices: torch.Tensor, *others: torch.Tensor) -> tuple[torch.Tensor, ...]:
    """Check shapes, add a batch dimension to 2-D inputs and broadcast a single body frame to B frames."""
    if points.dim() == 2:
        points = points[None]
    if points.dim() != 3 or points.shape[-1] != 3:
        raise ValueError(f"points must be (B, N, 3) or (N, 3), got {tuple(points.shape)}")
    out = []
    for name, t in zip(("body_vertices", "body_normals"), (body_vertices, *others)):
        if t.dim() == 2:
            t = t[None]
        if t.dim() != 3 or t.shape[-1] != 3 or t.shape[0] not in (1, points.shape[0]):
            raise ValueError(f"{name} must be (B, Vb, 3) or (1, Vb, 3) with B = {points.shape[0]} (the batch of points), "
                             f"got {tuple(t.shape)}")  # fmt: skip
        out.append(t.expand(points.shape[0], -1, -1))
    if len(out) == 2 and out[0].shape != out[1].shape:
        raise ValueError(f"body_vertices {tuple(out[0].shape)} and body_normals {tuple(out[1].shape)} differ in shape")
    bad = ~torch.isfinite(points.detach()).all(-1)
    if bad.any():
        b, n = torch.nonzero(bad)[0].tolist()
        raise ValueError(f"points contain NaN/Inf ({int(bad.sum())} points, first at batch {b}, point {n}); "
                         "check the prediction before querying the body")  # fmt: skip
    return (points, *out)


def _knn(query: torch.Tensor, ref: torch.Tensor, k: int, tree: cKDTree | None = None) -> tuple[torch.Tensor, torch.Tensor]:
    """k nearest rows of ``ref`` (M,3) for each row of ``query`` (N,3): distances (N,k), indices (N,k) long.

    KD-tree on CPU (``tree`` may be a prebuilt tree of ``ref``), chunked cdist + topk on CUDA.
    """
    k = min(k, ref.shape[0])
    if query.is_cuda:
        ds, ids = [], []
        for chunk in query.split(_CHUNK):
            d, i = torch.cdist(chunk, ref).topk(k, dim=-1, largest=False)
            ds.append(d)
            ids.append(i)
        return torch.cat(ds), torch.cat(ids)
    tree = tree if tree is not None else cKDTree(ref.numpy())
    d, i = tree.query(query.numpy(), k=k, workers=1)
    d, i = np.asarray(d).reshape(len(query), k), np.asarray(i).reshape(len(query), k)
    return torch.from_numpy(d).to(query.dtype), torch.from_numpy(i).long()


def _check_candidates(candidates: torch.Tensor | None, n_body: int, device: torch.device) -> torch.Tensor | None:
    if candidates is None:
        return None
    c = torch.as_tensor(candidates, device=device).long().reshape(-1)
    if len(c) == 0 or c.min() < 0 or c.max() >= n_body:
        raise ValueError(f"candidates must be a non-empty index set of body vertices in [0, {n_body}); "
                         "build it with culled_body_vertices(...)")  # fmt: skip
    return c


def body_vertex_tree(body_vertices: torch.Tensor, candidates: torch.Tensor | None = None) -> cKDTree | None:
    """A KD-tree over one body frame's vertices (Vb, 3) (only ``candidates`` when given), to pass as ``tree=``
    to :func:`nearest_indices` / :func:`nearest_body_vertex` when the same body is queried many times
    (None on CUDA, where the search is a cdist)."""
    if body_vertices.is_cuda:
        return None
    v = body_vertices.detach().reshape(-1, 3)
    cand = _check_candidates(candidates, len(v), v.device)
    return cKDTree((v if cand is None else v[cand]).cpu().numpy())


def nearest_indices(points: torch.Tensor, body_vertices: torch.Tensor, candidates: torch.Tensor | None = None,
                    tree: cKDTree | None = None) -> torch.Tensor:  # fmt: skip
    """Index (B,N) long of the nearest body vertex per point (not differentiable).

    points (B,N,3), body_vertices (B,Vb,3) or (1,Vb,3); ``candidates`` (C,) restricts the search to
    those body vertices (returned indices are still global body vertex indices); ``tree`` is
    :func:`body_vertex_tree` of the same single body frame and candidates (built here when None).
    """
    points, body_vertices = _as_batch(points, body_vertices)
    cand = _check_candidates(candidates, body_vertices.shape[1], body_vertices.device)
    shared = len(body_vertices) == 1 or body_vertices.stride(0) == 0  # one body frame for the batch: one search structure
    if tree is not None and not shared:
        raise ValueError("tree= is a search structure of one body frame; pass body_vertices as (1, Vb, 3)")
    pts = points.detach()
    body = body_vertices.detach()[:1] if shared else body_vertices.detach()
    if cand is not None:
        body = body[:, cand]
    if pts.is_cuda:
        idx = torch.stack([_knn(pts[b], body[0 if shared else b], 1)[1][:, 0] for b in range(len(pts))])
    else:
        p, q = pts.cpu().numpy(), body.cpu().numpy()
        tree = tree or (cKDTree(q[0]) if shared else None)

        def frame(b: int) -> np.ndarray:
            return (tree or cKDTree(q[b])).query(p[b], workers=1)[1]

        n_threads = min(torch.get_num_threads(), len(p))
        if n_threads <= 1:
            idx = np.stack([frame(b) for b in range(len(p))])
        else:  # scipy builds and queries its trees without the GIL: one frame per thread
            from concurrent.futures import ThreadPoolExecutor

            with ThreadPoolExecutor(n_threads) as pool:
                idx = np.stack(list(pool.map(frame, range(len(p)))))
        idx = torch.from_numpy(idx).long().to(points.device)
    return idx if cand is None else cand[idx]


def nearest_body_vertex(
    points: torch.Tensor,
    body_vertices: torch.Tensor,
    body_normals: torch.Tensor,
    candidates: torch.Tensor | None = None,
    tree: cKDTree | None = None,
) -> NearestVertex:
    """Nearest body vertex per garment point, with the signed normal distance (the SNUG collision term's).

    points (B,N,3) m; body_vertices (B,Vb,3) (or (1,Vb,3), shared by the batch); body_normals
    (B,Vb,3) unit area-weighted vertex normals; ``candidates`` (C,) body vertex indices to search
    (see :func:`culled_body_vertices`); ``tree`` a prebuilt :func:`body_vertex_tree` of a single body
    frame. Differentiable w.r.t. ``points`` and the body through the gather (the index selection itself
    is not). Returns :class:`NearestVertex`.
    """
    points, body_vertices, body_normals = _as_batch(points, body_vertices, body_normals)
    return nearest_from_indices(points, body_vertices, body_normals, nearest_indices(points, body_vertices, candidates, tree))


def nearest_from_indices(points: torch.Tensor, body_vertices: torch.Tensor, body_normals: torch.Tensor, idx: torch.Tensor) -> NearestVertex:
    """:class:`NearestVertex` of points (B,N,3) whose nearest body vertices are idx (B,N) long, on the
    body (B,Vb,3) with unit normals (B,Vb,3) (B may be 1 or broadcast); differentiable through the gather."""
    body_vertices, body_normals = (t.expand(points.shape[0], -1, -1) for t in (body_vertices, body_normals))
    gather = idx[..., None].expand(-1, -1, 3)
    p = torch.gather(body_vertices, 1, gather).to(points.dtype)
    n = torch.gather(body_normals, 1, gather).to(points.dtype)
    return NearestVertex(idx, p, n, ((points - p) * n).sum(-1))


def culled_body_vertices(
    garment_rest: torch.Tensor,
    body_rest: torch.Tensor,
    body_weights: torch.Tensor,
    margin: float = 0.1,
    min_share: float = 0.05,
) -> torch.Tensor:
    """Body vertices a garment can touch under pose: sorted (C,) long indices into the body.

    garment_rest (V,3) and body_rest (Vb,3) in the same rest pose (m); body_weights (Vb,J) skinning
    weights. The body vertices near the garment at rest (within ``margin`` m of it, plus the nearest
    body vertex of every garment vertex) name the joints that drive that region (their dominant
    joints); every body vertex skinned at least ``min_share`` to those joints is kept, with the near
    vertices. Whole joint-driven parts are kept, so the set stays valid when the body moves: a skirt
    keeps the pelvis, spine and legs, never the head or the arms.
    """
    if garment_rest.dim() != 2 or body_rest.dim() != 2 or body_weights.shape[0] != body_rest.shape[0]:
        raise ValueError("culled_body_vertices takes garment_rest (V,3), body_rest (Vb,3) and body_weights (Vb,J) "
                         f"in the rest pose, got {tuple(garment_rest.shape)}, {tuple(body_rest.shape)}, "
                         f"{tuple(body_weights.shape)}")  # fmt: skip
    g = garment_rest.detach().cpu().double().numpy()
    b = body_rest.detach().cpu().double().numpy()
    d, _ = cKDTree(g).query(b, distance_upper_bound=margin, workers=1)
    near = np.isfinite(d)
    near[cKDTree(b).query(g, workers=1)[1]] = True
    near = torch.from_numpy(near)
    w = body_weights.detach().cpu()
    joints = torch.unique(w[near].argmax(1))
    keep = (w[:, joints].sum(1) >= min_share) | near
    return torch.nonzero(keep).squeeze(1).to(body_rest.device)


def culled_body_faces(body_faces: torch.Tensor, candidates: torch.Tensor) -> torch.Tensor:
    """Indices (Fc,) of the body faces with at least one vertex in ``candidates`` (C,)."""
    mask = torch.zeros(int(body_faces.max()) + 1, dtype=torch.bool, device=body_faces.device)
    mask[candidates.to(body_faces.device)] = True
    return torch.nonzero(mask[body_faces].any(1)).squeeze(1)
