"""Garment-to-body proximity: nearest body vertex with its normal (what the losses use), exact signed
distance to the body triangle mesh (what the metrics use), and culling of body parts far from the
garment (``culled_body_vertices``; every query takes the result as ``candidates=``).

CPU queries use scipy's KD-tree (one tree per frame, one thread); CUDA tensors use chunked
``torch.cdist``. Positions are in metres, float32 or float64 (results follow the dtype of ``points``).
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


@dataclass
class SurfacePoint:
    """distance (B,N) exact signed distance to the body surface (m, negative inside); point (B,N,3)
    the closest surface point; face (B,N) the index (into the full ``body_faces``) of its triangle."""

    distance: torch.Tensor
    point: torch.Tensor
    face: torch.Tensor


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


def nearest_indices(points: torch.Tensor, body_vertices: torch.Tensor, candidates: torch.Tensor | None = None) -> torch.Tensor:
    """Index (B,N) long of the nearest body vertex per point (not differentiable).

    points (B,N,3), body_vertices (B,Vb,3) or (1,Vb,3); ``candidates`` (C,) restricts the search to
    those body vertices (returned indices are still global body vertex indices).
    """
    points, body_vertices = _as_batch(points, body_vertices)
    cand = _check_candidates(candidates, body_vertices.shape[1], body_vertices.device)
    shared = body_vertices.stride(0) == 0  # one body frame broadcast over the batch: one search structure
    pts = points.detach()
    body = body_vertices.detach()[:1] if shared else body_vertices.detach()
    if cand is not None:
        body = body[:, cand]
    if pts.is_cuda:
        idx = torch.stack([_knn(pts[b], body[0 if shared else b], 1)[1][:, 0] for b in range(len(pts))])
    else:
        p, q = pts.cpu().numpy(), body.cpu().numpy()
        tree = cKDTree(q[0]) if shared else None
        idx = np.stack([(tree or cKDTree(q[b])).query(p[b], workers=1)[1] for b in range(len(p))])
        idx = torch.from_numpy(idx).long().to(points.device)
    return idx if cand is None else cand[idx]


def nearest_body_vertex(
    points: torch.Tensor,
    body_vertices: torch.Tensor,
    body_normals: torch.Tensor,
    candidates: torch.Tensor | None = None,
) -> NearestVertex:
    """Nearest body vertex per garment point, with the signed normal distance (GAPS/SNUG collision).

    points (B,N,3) m; body_vertices (B,Vb,3) (or (1,Vb,3), shared by the batch); body_normals
    (B,Vb,3) unit area-weighted vertex normals; ``candidates`` (C,) body vertex indices to search
    (see :func:`culled_body_vertices`). Differentiable w.r.t. ``points`` and the body through the
    gather (the index selection itself is not). Returns :class:`NearestVertex`.
    """
    points, body_vertices, body_normals = _as_batch(points, body_vertices, body_normals)
    idx = nearest_indices(points, body_vertices, candidates)
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


# --- exact point-triangle distance ----------------------------------------------------------------
# Region codes of the closest point: 0 face interior, 1/2/3 vertex a/b/c, 4/5/6 edge ab/bc/ca.


def _dot(u: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    return (u * v).sum(-1)


def _closest_on_triangles(p: torch.Tensor, a: torch.Tensor, b: torch.Tensor, c: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Closest point on triangles (a,b,c) (..., 3) to points p (..., 3) (Ericson, Real-Time Collision
    Detection 5.1.5), exact for degenerate triangles too. Returns (closest point (..., 3), region (...))."""
    ab, ac, ap, bp, cp = b - a, c - a, p - a, p - b, p - c
    d1, d2, d3, d4, d5, d6 = _dot(ab, ap), _dot(ac, ap), _dot(ab, bp), _dot(ac, bp), _dot(ab, cp), _dot(ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2

    def ratio(num, den):
        return torch.where(den > 0, num / torch.where(den > 0, den, torch.ones_like(den)), torch.zeros_like(num))

    denom = va + vb + vc
    v, w = ratio(vb, denom), ratio(vc, denom)
    q = a + ab * v[..., None] + ac * w[..., None]
    region = torch.zeros(p.shape[:-1], dtype=torch.long, device=p.device)
    # later assignments win: Ericson's tests run in the reverse of this order
    cases = [
        ((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0), 5, b, c - b, ratio(d4 - d3, (d4 - d3) + (d5 - d6))),
        ((vb <= 0) & (d2 >= 0) & (d6 <= 0), 6, a, ac, ratio(d2, d2 - d6)),
        ((d6 >= 0) & (d5 <= d6), 3, c, None, None),
        ((vc <= 0) & (d1 >= 0) & (d3 <= 0), 4, a, ab, ratio(d1, d1 - d3)),
        ((d3 >= 0) & (d4 <= d3), 2, b, None, None),
        ((d1 <= 0) & (d2 <= 0), 1, a, None, None),
    ]
    for mask, code, origin, direction, t in cases:
        target = origin if direction is None else origin + direction * t[..., None]
        q = torch.where(mask[..., None], target, q)
        region = torch.where(mask, torch.full_like(region, code), region)
    return q, region


class _BodySurface:
    """One posed frame of the body mesh (a face subset) with per-feature pseudonormals.

    Closest points come from libigl's AABB tree on the CPU and from a chunked brute-force search in
    torch on CUDA (both exact). The sign is the angle-weighted pseudonormal test of the closest
    feature (face, edge or vertex; Baerentzen & Aanaes 2005), exact for closed oriented meshes such
    as each component of the body.
    """

    def __init__(self, vertices: torch.Tensor, mesh: "_MeshIndex"):
        self.v, self.mesh = vertices, mesh
        faces = mesh.faces
        tri = vertices[faces]  # (F,3,3)
        cross = torch.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0], dim=-1)
        fn = cross / cross.norm(dim=-1, keepdim=True).clamp_min(1e-30)
        self.face_normals = fn
        corner_angles = []
        for i in range(3):
            e1, e2 = tri[:, (i + 1) % 3] - tri[:, i], tri[:, (i + 2) % 3] - tri[:, i]
            corner_angles.append(torch.atan2(torch.cross(e1, e2, dim=-1).norm(dim=-1), _dot(e1, e2)))
        ang = torch.stack(corner_angles, 1)  # (F,3)
        self.vertex_normals = torch.zeros_like(vertices).index_add_(0, faces.reshape(-1), (fn[:, None] * ang[..., None]).reshape(-1, 3))
        self.edge_normals = torch.zeros(mesh.n_edges, 3, dtype=vertices.dtype, device=vertices.device).index_add_(
            0, mesh.face_edges.reshape(-1), fn[:, None].expand(-1, 3, -1).reshape(-1, 3))  # fmt: skip

    def _closest_face(self, q: torch.Tensor) -> torch.Tensor:
        """Index (n,) of a face closest to each point q (n,3)."""
        if q.is_cuda:
            tri = self.v[self.mesh.faces]
            out = []
            for chunk in q.split(max(1, (1 << 24) // max(1, len(tri)))):
                cp, _ = _closest_on_triangles(chunk[:, None], tri[None, :, 0], tri[None, :, 1], tri[None, :, 2])
                out.append(((chunk[:, None] - cp) ** 2).sum(-1).argmin(1))
            return torch.cat(out)
        import igl

        V, F = self.v.numpy(), self.mesh.faces_np
        tree = igl.AABB()
        tree.init(V, F)
        return torch.from_numpy(np.asarray(tree.squared_distance(V, F, q.numpy())[1])).long()

    def query(self, q: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Signed distance (n,), closest point (n,3) and local face index (n,) for points q (n,3)."""
        f = self._closest_face(q)
        fv = self.mesh.faces[f]
        tri = self.v[fv]
        cp, region = _closest_on_triangles(q, tri[:, 0], tri[:, 1], tri[:, 2])
        fe = self.mesh.face_edges[f]  # edges ab, bc, ca
        normal = self.face_normals[f]
        for code, (source, table, col) in {1: (self.vertex_normals, fv, 0), 2: (self.vertex_normals, fv, 1),
                                           3: (self.vertex_normals, fv, 2), 4: (self.edge_normals, fe, 0),
                                           5: (self.edge_normals, fe, 1), 6: (self.edge_normals, fe, 2)}.items():  # fmt: skip
            normal = torch.where((region == code)[:, None], source[table[:, col]], normal)
        side = _dot(q - cp, normal)
        sign = torch.where(side < 0, -torch.ones_like(side), torch.ones_like(side))
        return sign * (q - cp).norm(dim=-1), cp, f


@dataclass
class _MeshIndex:
    """Connectivity of a face subset: faces (F,3) long (and as int64 numpy for libigl), face_edges
    (F,3) ids of the undirected edges ab, bc, ca, n_edges."""

    faces: torch.Tensor
    faces_np: np.ndarray
    face_edges: torch.Tensor
    n_edges: int

    @classmethod
    def build(cls, faces: torch.Tensor) -> "_MeshIndex":
        e = torch.stack([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]], 1).sort(-1).values  # (F,3,2)
        key = e[..., 0] * (int(faces.max()) + 1) + e[..., 1]
        uniq, face_edges = torch.unique(key.reshape(-1), return_inverse=True)
        return cls(faces, faces.cpu().numpy().astype(np.int64), face_edges.reshape(-1, 3), len(uniq))


def closest_body_point(
    points: torch.Tensor,
    body_vertices: torch.Tensor,
    body_faces: torch.Tensor,
    candidates: torch.Tensor | None = None,
) -> SurfacePoint:
    """Exact closest point on the posed body triangle mesh and the signed distance (negative inside).

    points (B,N,3) m; body_vertices (B,Vb,3) (or (1,Vb,3)); body_faces (F,3) long; ``candidates``
    (C,) body vertex indices (see :func:`culled_body_vertices`): only faces touching them are
    searched. Distances are exact (float64 internally); the sign is the pseudonormal
    test of the closest face/edge/vertex, exact for a closed mesh such as each component of the body
    (a point inside one part but closest to the surface of another part that overlaps it, which only
    happens where the posed body intersects itself, reads as outside).
    CPU: libigl AABB tree per frame; CUDA: chunked brute force in torch. Not differentiable.
    Returns :class:`SurfacePoint`.
    """
    points, body_vertices = _as_batch(points, body_vertices)
    faces = torch.as_tensor(body_faces, device=body_vertices.device).long()
    if faces.dim() != 2 or faces.shape[1] != 3 or len(faces) == 0 or faces.max() >= body_vertices.shape[1] or faces.min() < 0:
        raise ValueError(f"body_faces must be (F, 3) indices into the {body_vertices.shape[1]} body vertices")
    cand = _check_candidates(candidates, body_vertices.shape[1], faces.device)
    face_ids = torch.arange(len(faces), device=faces.device) if cand is None else culled_body_faces(faces, cand)
    if len(face_ids) == 0:
        raise ValueError("no body face touches the candidate vertices; check the candidates")
    mesh = _MeshIndex.build(faces[face_ids])
    shared = body_vertices.stride(0) == 0
    dist, point, face = [], [], []
    with torch.no_grad():
        pts, body = points.detach().double(), body_vertices.detach().double()
        surface = None
        for b in range(len(pts)):
            if surface is None or not shared:
                surface = _BodySurface(body[b], mesh)
            d, p, f = surface.query(pts[b])
            dist.append(d)
            point.append(p)
            face.append(face_ids[f])
    dt = points.dtype
    return SurfacePoint(torch.stack(dist).to(dt), torch.stack(point).to(dt), torch.stack(face))


def signed_distance(
    points: torch.Tensor,
    body_vertices: torch.Tensor,
    body_faces: torch.Tensor,
    candidates: torch.Tensor | None = None,
) -> torch.Tensor:
    """Exact signed distance (B,N) in metres from points (B,N,3) to the posed body mesh
    (body_vertices (B,Vb,3), body_faces (F,3)), negative inside. See :func:`closest_body_point`."""
    return closest_body_point(points, body_vertices, body_faces, candidates).distance
