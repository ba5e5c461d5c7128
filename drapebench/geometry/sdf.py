"""The one signed distance from points to a posed body: exact magnitude (distance to the closest
point of the body triangle mesh), sign from the body's winding number (inside any body part counts
as inside, also where the posed body intersects itself).

Rule: a point is inside when the winding number of the whole body mesh at it exceeds 0.5. Overlapping
parts add up, so a point inside the thigh but closest to the belly reads as inside. With the body's
outer faces given (``outer_faces=``, :mod:`drapebench.geometry.outer_surface`) the magnitude is the
distance to the closest point of the outer surface: faces buried inside another part (the back of an
eyeball, the socket's skin behind it) are not searched, so a point deep in the head reads its depth
to the skin, not to the eye behind it. For a point outside the body the two agree (the
closest point of the whole mesh then lies on the outer surface).

Two paths give the same result up to a stated tolerance:

- default (closed, consistently oriented body meshes such as the baked bodies): a warp BVH refitted
  per frame (:mod:`drapebench.geometry.body_bvh`) finds a closest face in float32 and the integer
  winding number by signed ray crossings; the closest point on that face is computed in float64.
  Against the exact path: distances agree within 1e-6 m (a float32 near-tie between two faces), the
  inside test agrees except within about 1e-6 m of the surface, where the fast winding number of
  the exact path is itself approximate.
- ``exact=True`` (and any mesh that is not closed, and every query where warp, the ``sim`` extra, is
  not installed): libigl in float64. The sign is libigl's fast
  winding number of the whole mesh (Barill et al. 2018); the closest point is searched among the
  body faces that can hold it: per frame, the distance r from every point to its nearest body vertex
  bounds its distance to the surface, so only faces whose bounding box comes within r of the
  points' bounding box are searched (the result equals the unculled one).

Differentiable use: :class:`SurfacePoint` carries the closest point and a unit ``normal`` with
``(x - point) . normal == distance``; ``((x - sp.point.detach()) * sp.normal.detach()).sum(-1)``
is a signed distance whose gradient w.r.t. ``x`` is the exact one (away from the medial axis).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from functools import cache
from typing import TYPE_CHECKING

import numpy as np
import torch
from scipy.spatial import cKDTree

from drapebench.extras import MissingExtra
from drapebench.geometry.proximity import NearestVertex, _as_batch, nearest_body_vertex, nearest_from_indices

if TYPE_CHECKING:
    from drapebench.geometry import body_bvh

log = logging.getLogger("drapebench")

@dataclass
class SurfacePoint:
    """distance (B,N) exact signed distance to the body surface (m, negative inside); point (B,N,3)
    the closest surface point; face (B,N) the index (into the full ``body_faces``) of its triangle;
    normal (B,N,3) unit vector with ``(x - point) . normal = distance`` (where x lies on the surface:
    the closest face's outward normal, or with ``exact=True`` the closest feature's pseudonormal)."""

    distance: torch.Tensor
    point: torch.Tensor
    face: torch.Tensor
    normal: torch.Tensor


@cache
def _body_bvh():
    """:mod:`drapebench.geometry.body_bvh`, imported on first use: importing it loads and initialises warp
    (about 0.3 s), which a caller that never queries a posed body (an inference in the canonical space, for one) skips.
    None without warp (the ``sim`` extra): every query then takes the exact libigl path (said once in the log)."""
    try:
        from drapebench.geometry import body_bvh
    except MissingExtra as err:
        log.info("%s; signed distances and inside tests take the exact libigl path", err)
        return None
    return body_bvh


def _fast_path(faces: torch.Tensor, exact: bool):
    """The warp BVH module when the default path applies to body ``faces`` (F,3): not ``exact``, warp
    installed, a closed and consistently oriented mesh; else None (the exact path)."""
    if exact:
        return None
    bvh = _body_bvh()
    return bvh if bvh is not None and bvh.is_closed(faces) else None


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
        """Closest point (n,3), local face index (n,) and the closest feature's unit outward
        pseudonormal (n,3) for points q (n,3)."""
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
        return cp, f, normal / normal.norm(dim=-1, keepdim=True).clamp_min(1e-30)


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


def inside_body(points: torch.Tensor, body_vertices: torch.Tensor, body_faces: torch.Tensor, exact: bool = False) -> torch.Tensor:
    """(B,N) bool: points (B,N,3) m lie inside the posed body (body_vertices (B,Vb,3) or (1,Vb,3),
    body_faces (F,3)): the whole mesh's winding number exceeds 0.5 (inside any body part counts as
    inside). Default: signed ray crossings on a closed mesh; ``exact=True`` or an open mesh: libigl's
    fast winding number, CPU float64 (module docstring)."""
    points, body_vertices = _as_batch(points, body_vertices)
    faces = torch.as_tensor(body_faces).long()
    bvh = _fast_path(faces, exact)
    if bvh is not None:
        return (bvh.query(points, body_vertices, faces).winding > 0).to(points.device)
    import igl

    F = faces.detach().cpu().numpy().astype(np.int64)
    pts, body = points.detach().cpu().double().numpy(), body_vertices.detach().cpu().double().numpy()
    w = np.stack([igl.fast_winding_number(body[b], F, pts[b]) for b in range(len(pts))])
    return torch.from_numpy(w > 0.5).to(points.device)


def _near_faces(points: torch.Tensor, body: torch.Tensor, faces: torch.Tensor, searched: torch.Tensor) -> torch.Tensor:
    """Indices of the faces among ``searched`` (S,) that can hold the closest point of any of points
    (n,3) on those faces: r is the largest distance from a point to its nearest corner of a searched
    face (an upper bound of its distance to them); a face whose bounding box stays farther than r
    from the points' bounding box cannot."""
    corners = body[torch.unique(faces[searched])]
    r = float(cKDTree(corners.cpu().numpy()).query(points.cpu().numpy(), workers=1)[0].max())
    lo, hi = points.min(0).values - r, points.max(0).values + r
    tri = body[faces[searched]]  # (S,3,3)
    keep = ((tri.min(1).values <= hi) & (tri.max(1).values >= lo)).all(-1)
    return searched[keep]


def _checked_faces(body_faces: torch.Tensor, body_vertices: torch.Tensor) -> torch.Tensor:
    """body_faces as (F,3) long on the body's device, or a ValueError naming what is wrong."""
    faces = torch.as_tensor(body_faces, device=body_vertices.device).long()
    if faces.dim() != 2 or faces.shape[1] != 3 or len(faces) == 0 or faces.max() >= body_vertices.shape[1] or faces.min() < 0:
        raise ValueError(f"body_faces must be (F, 3) indices into the {body_vertices.shape[1]} body vertices")
    return faces


def _searched_faces(outer_faces: torch.Tensor | None, faces: torch.Tensor) -> torch.Tensor:
    """(S,) long indices of the faces the closest point is searched on: the outer ones (``outer_faces``
    (F,) bool) or all; a ValueError when the mask does not fit the faces or marks none."""
    if outer_faces is None:
        return torch.arange(len(faces), device=faces.device)
    outer = torch.as_tensor(outer_faces, device=faces.device)
    if outer.shape != (len(faces),) or outer.dtype != torch.bool or not outer.any():
        raise ValueError(f"outer_faces must be a bool mask with one flag per body face ({len(faces)},) and at least one "
                         f"face set, got {tuple(outer.shape)} {outer.dtype} (build it with "
                         "drapebench.geometry.outer_surface.outer_faces, or leave it None to search every face)")  # fmt: skip
    return torch.nonzero(outer).squeeze(1)


def closest_body_point(points: torch.Tensor, body_vertices: torch.Tensor, body_faces: torch.Tensor, exact: bool = False,
                       outer_faces: torch.Tensor | None = None) -> SurfacePoint:  # fmt: skip
    """Closest point on the posed body triangle mesh and the signed distance (negative inside).

    points (B,N,3) m; body_vertices (B,Vb,3) (or (1,Vb,3)); body_faces (F,3) long; ``outer_faces``
    (F,) bool, the body's outer surface (:mod:`drapebench.geometry.outer_surface`; None: every
    face): the closest point is searched on those faces only. The magnitude is the distance to the
    closest point (float64), the sign :func:`inside_body` of the whole mesh. Default: warp BVH per
    frame (CPU or CUDA); ``exact=True`` (or an open mesh): libigl AABB per frame on the CPU, chunked
    brute force in torch on CUDA (module docstring: the tolerance between the two). Not
    differentiable (see the module docstring for a differentiable use of the result). Returns
    :class:`SurfacePoint`.
    """
    points, body_vertices = _as_batch(points, body_vertices)
    faces = _checked_faces(body_faces, body_vertices)
    searched = _searched_faces(outer_faces, faces)
    bvh = _fast_path(faces, exact)
    if bvh is None:
        return _closest_exact(points, body_vertices, faces, searched)
    return _surface_point(points, body_vertices, faces, bvh.query(points, body_vertices, faces, outer_faces=outer_faces))


def body_proximity(points: torch.Tensor, body_vertices: torch.Tensor, body_normals: torch.Tensor, body_faces: torch.Tensor,
                   exact: bool = False, outer_faces: torch.Tensor | None = None) -> tuple[SurfacePoint, NearestVertex]:  # fmt: skip
    """:func:`closest_body_point` and :func:`drapebench.geometry.proximity.nearest_body_vertex` (whole
    body, or the corners of ``outer_faces``) of the same points in one pass over the body (one BVH
    refit per frame on the default path).

    points (B,N,3) m; body_vertices and body_normals (B,Vb,3) (or (1,Vb,3)); body_faces (F,3) long;
    ``outer_faces`` (F,) bool as in :func:`closest_body_point`. ``exact=True`` (or an open mesh):
    libigl for the surface point, scipy's KD-tree for the vertex.
    """
    points, body_vertices, body_normals = _as_batch(points, body_vertices, body_normals)
    faces = _checked_faces(body_faces, body_vertices)
    searched = _searched_faces(outer_faces, faces)
    bvh = _fast_path(faces, exact)
    if bvh is None:
        candidates = None if outer_faces is None else torch.unique(faces[searched])
        return _closest_exact(points, body_vertices, faces, searched), nearest_body_vertex(points, body_vertices, body_normals, candidates)
    found = bvh.query(points, body_vertices, faces, nearest_vertex=True, outer_faces=outer_faces)
    return _surface_point(points, body_vertices, faces, found), nearest_from_indices(points, body_vertices, body_normals, found.vertex.to(points.device))


def _surface_point(points: torch.Tensor, body_vertices: torch.Tensor, faces: torch.Tensor, found: body_bvh.BodyQuery) -> SurfacePoint:
    """:class:`SurfacePoint` of points (B,N,3) from a signed :func:`body_bvh.query` of them."""
    with torch.no_grad():
        offset = points.detach().double() - found.closest
        d = offset.norm(dim=-1)
        sign = torch.where(found.winding.to(d.device) > 0, -torch.ones_like(d), torch.ones_like(d))
        direction = offset / d.clamp_min(1e-12)[..., None] * sign[..., None]
        on = d <= 1e-12
        if on.any():  # on the surface: the closest face's outward normal
            tri = body_vertices.detach().double()[torch.nonzero(on)[:, 0][:, None], faces[found.face[on]].to(body_vertices.device)]
            fn = torch.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0], dim=-1)
            direction[on] = fn / fn.norm(dim=-1, keepdim=True).clamp_min(1e-30)
    dt = points.dtype
    return SurfacePoint((sign * d).to(dt), found.closest.to(dt), found.face.to(points.device), direction.to(dt))


def _closest_exact(points: torch.Tensor, body_vertices: torch.Tensor, faces: torch.Tensor, searched: torch.Tensor) -> SurfacePoint:
    """:func:`closest_body_point` by libigl (CPU) or torch brute force (CUDA) over the faces
    ``searched`` (S,) culled to those near the points; the sign from the whole mesh."""
    inside = inside_body(points, body_vertices, faces, exact=True)
    dist, point, face, normal = [], [], [], []
    with torch.no_grad():
        pts, body = points.detach().double(), body_vertices.detach().double()
        for b in range(len(pts)):
            face_ids = _near_faces(pts[b], body[b], faces, searched)
            cp, f, n = _BodySurface(body[b], _MeshIndex.build(faces[face_ids])).query(pts[b])
            offset = pts[b] - cp
            d = offset.norm(dim=-1)
            sign = torch.where(inside[b], -torch.ones_like(d), torch.ones_like(d))
            direction = torch.where((d > 1e-12)[:, None], offset / d.clamp_min(1e-12)[:, None] * sign[:, None], n)
            dist.append(sign * d)
            point.append(cp)
            face.append(face_ids[f])
            normal.append(direction)
    dt = points.dtype
    return SurfacePoint(torch.stack(dist).to(dt), torch.stack(point).to(dt), torch.stack(face), torch.stack(normal).to(dt))


def signed_distance(points: torch.Tensor, body_vertices: torch.Tensor, body_faces: torch.Tensor, exact: bool = False,
                    outer_faces: torch.Tensor | None = None) -> torch.Tensor:  # fmt: skip
    """Signed distance (B,N) in metres from points (B,N,3) to the posed body mesh (body_vertices
    (B,Vb,3), body_faces (F,3); depth to its ``outer_faces`` (F,) bool when given), negative
    inside. See :func:`closest_body_point`."""
    return closest_body_point(points, body_vertices, body_faces, exact, outer_faces).distance
