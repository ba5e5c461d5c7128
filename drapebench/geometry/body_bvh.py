"""A posed body as a warp BVH, refitted per frame: the closest face of points, the body's winding
number at them by signed ray crossings (the fast path of :mod:`drapebench.geometry.sdf`) and, on
request, their nearest body vertex (the fast path of :mod:`drapebench.geometry.proximity`).

The body mesh is closed and consistently oriented, so its winding number at a point off the surface
is an integer: the sum over the triangles a ray from the point crosses of sign(dir . n) (+1 leaving a
part, -1 entering one; parts that overlap add up, as in the exact generalized winding number). The
ray leaves along the closest face's outward normal; one whose crossing lies within a relative 1e-5
of a triangle edge, grazes a triangle, starts on the surface or runs parallel to a coordinate plane
(warp's BVH slab test divides 0 by 0 for a box face the ray runs in, and drops that box) is recast
along the next of three fixed directions. Closest faces come from warp's
BVH in float32, the closest point on that face is computed in float64.

With the body's outer faces given (:mod:`drapebench.geometry.outer_surface`), the closest face and
the nearest vertex are those of the outer surface: a point whose closest face or nearest vertex is
buried is searched again on a second mesh of the outer faces over the same points.

The nearest body vertex is exact over the whole body: the nearest corner of the closest face is at a
distance r, and every vertex within r belongs to a face whose bounding box meets the cube of half-size
r around the point, so only those faces' corners are compared (in float32: of two vertices within
about 1e-7 m of the same distance either may come back).

warp is set up by :mod:`drapebench.warp_env` (the kernel compiles once per machine).
"""

from __future__ import annotations

import threading
from functools import lru_cache
from typing import NamedTuple

import numpy as np
import torch

from drapebench.warp_env import wp  # noqa: E402

_EDGE_TOL = wp.constant(1e-5)  # barycentric margin below which a crossing is too close to an edge to count
_DIRECTIONS = ((0.5377, 0.8301, -0.1472), (-0.7071, 0.1183, 0.6971), (0.2213, -0.5619, -0.7972))


@wp.func
def _crossings(bvh: wp.uint64, points: wp.array(dtype=wp.vec3), faces: wp.array(dtype=wp.int32), p: wp.vec3, d: wp.vec3):
    """Signed crossings of the ray p + t d (t >= 0) with the triangles, and 1 when one is ambiguous."""
    w = int(0)
    ambiguous = int(0)
    if wp.min(wp.min(wp.abs(d[0]), wp.abs(d[1])), wp.abs(d[2])) < 1e-6:  # the BVH's slab test can drop boxes it runs along
        return w, 1
    query = wp.bvh_query_ray(bvh, p, d)
    f = int(0)
    while wp.bvh_query_next(query, f):
        a = points[faces[3 * f]]
        e1 = points[faces[3 * f + 1]] - a
        e2 = points[faces[3 * f + 2]] - a
        pv = wp.cross(d, e2)
        det = wp.dot(e1, pv)  # = -d . n with n = e1 x e2 the outward normal
        if wp.abs(det) <= 1e-5 * wp.length(wp.cross(e1, e2)):  # the ray grazes the triangle's plane
            ambiguous = 1
            continue
        inv = 1.0 / det
        s = p - a
        u = wp.dot(s, pv) * inv
        qv = wp.cross(s, e1)
        v = wp.dot(d, qv) * inv
        t = wp.dot(e2, qv) * inv
        margin = wp.min(wp.min(u, v), 1.0 - u - v)
        if margin < -_EDGE_TOL or t < -1e-7:
            continue
        if margin <= _EDGE_TOL or t <= 1e-7:
            ambiguous = 1
        elif det < 0.0:  # leaving through the outward side
            w = w + 1
        else:
            w = w - 1
    return w, ambiguous


@wp.func
def _ratio(num: wp.float64, den: wp.float64):
    return num / wp.max(den, wp.float64(1e-300))


@wp.func
def _closest_on_triangle(p: wp.vec3d, a: wp.vec3d, b: wp.vec3d, c: wp.vec3d):
    """Closest point on triangle abc to p in float64 (Ericson, Real-Time Collision Detection 5.1.5)."""
    zero = wp.float64(0.0)
    ab = b - a
    ac = c - a
    ap = p - a
    d1 = wp.dot(ab, ap)
    d2 = wp.dot(ac, ap)
    if d1 <= zero and d2 <= zero:
        return a
    bp = p - b
    d3 = wp.dot(ab, bp)
    d4 = wp.dot(ac, bp)
    if d3 >= zero and d4 <= d3:
        return b
    vc = d1 * d4 - d3 * d2
    if vc <= zero and d1 >= zero and d3 <= zero:
        return a + ab * _ratio(d1, d1 - d3)
    cp = p - c
    d5 = wp.dot(ab, cp)
    d6 = wp.dot(ac, cp)
    if d6 >= zero and d5 <= d6:
        return c
    vb = d5 * d2 - d1 * d6
    if vb <= zero and d2 >= zero and d6 <= zero:
        return a + ac * _ratio(d2, d2 - d6)
    va = d3 * d6 - d5 * d4
    if va <= zero and d4 - d3 >= zero and d5 - d6 >= zero:
        return b + (c - b) * _ratio(d4 - d3, (d4 - d3) + (d5 - d6))
    den = va + vb + vc
    return a + ab * _ratio(vb, den) + ac * _ratio(vc, den)


@wp.func
def _nearest_vertex(mesh: wp.uint64, points: wp.array(dtype=wp.vec3), faces: wp.array(dtype=wp.int32), p: wp.vec3, f: int):
    """Index of the body vertex nearest to p, given f, the face closest to p (module docstring)."""
    best = faces[3 * f]
    best_d2 = wp.length_sq(points[best] - p)
    for k in range(1, 3):
        d2 = wp.length_sq(points[faces[3 * f + k]] - p)
        if d2 < best_d2:
            best_d2 = d2
            best = faces[3 * f + k]
    r = wp.sqrt(best_d2)
    box = wp.vec3(r, r, r)
    query = wp.mesh_query_aabb(mesh, p - box, p + box)
    g = int(0)
    while wp.mesh_query_aabb_next(query, g):
        for k in range(3):
            v = faces[3 * g + k]
            d2 = wp.length_sq(points[v] - p)
            if d2 < best_d2:
                best_d2 = d2
                best = v
    return best


@wp.kernel
def _query(
    mesh: wp.uint64,
    points: wp.array(dtype=wp.vec3),
    points64: wp.array(dtype=wp.vec3d),
    faces: wp.array(dtype=wp.int32),
    queries: wp.array(dtype=wp.vec3d),
    directions: wp.array(dtype=wp.vec3),
    winding: wp.array(dtype=wp.int32),
    face: wp.array(dtype=wp.int32),
    closest: wp.array(dtype=wp.vec3d),
    vertex: wp.array(dtype=wp.int32),
    outer_face: wp.array(dtype=wp.int32),
    outer_vertex: wp.array(dtype=wp.int32),
    redo: wp.array(dtype=wp.int32),
):
    i = wp.tid()
    q = queries[i]
    p = wp.vec3(wp.float32(q[0]), wp.float32(q[1]), wp.float32(q[2]))
    hit = wp.mesh_query_point_no_sign(mesh, p, 1.0e6)
    f = hit.face
    face[i] = f
    if vertex.shape[0] > 0:
        vertex[i] = _nearest_vertex(mesh, points, faces, p, f)
    if outer_face.shape[0] > 0:  # a buried closest face or nearest vertex: searched again on the outer surface
        redo[i] = 0
        if outer_face[f] == 0:
            redo[i] = 1
        if vertex.shape[0] > 0:
            if outer_vertex[vertex[i]] == 0:
                redo[i] = 1
    closest[i] = _closest_on_triangle(q, points64[faces[3 * f]], points64[faces[3 * f + 1]], points64[faces[3 * f + 2]])
    a = points[faces[3 * f]]  # first ray: along the closest face's outward normal, out of the body nearby
    w, ambiguous = _crossings(wp.mesh_get_bvh(mesh), points, faces, p, wp.normalize(wp.cross(points[faces[3 * f + 1]] - a, points[faces[3 * f + 2]] - a)))
    for k in range(directions.shape[0]):
        if ambiguous == 0:
            break
        w, ambiguous = _crossings(wp.mesh_get_bvh(mesh), points, faces, p, directions[k])
    winding[i] = w


@wp.kernel
def _query_outer(
    mesh: wp.uint64,
    points: wp.array(dtype=wp.vec3),
    points64: wp.array(dtype=wp.vec3d),
    faces: wp.array(dtype=wp.int32),
    face_ids: wp.array(dtype=wp.int32),
    queries: wp.array(dtype=wp.vec3d),
    which: wp.array(dtype=wp.int64),
    face: wp.array(dtype=wp.int32),
    closest: wp.array(dtype=wp.vec3d),
    vertex: wp.array(dtype=wp.int32),
):
    """Closest face, closest point and nearest vertex of the points ``which`` on the outer-surface mesh
    (faces: its local faces, face_ids: their indices in the whole body)."""
    i = int(which[wp.tid()])
    q = queries[i]
    p = wp.vec3(wp.float32(q[0]), wp.float32(q[1]), wp.float32(q[2]))
    f = wp.mesh_query_point_no_sign(mesh, p, 1.0e6).face
    face[i] = face_ids[f]
    if vertex.shape[0] > 0:
        vertex[i] = _nearest_vertex(mesh, points, faces, p, f)
    closest[i] = _closest_on_triangle(q, points64[faces[3 * f]], points64[faces[3 * f + 1]], points64[faces[3 * f + 2]])


class _Body:
    """A warp mesh of one body topology on one device (BVH built on the first frame it is given,
    refitted to every later frame)."""

    def __init__(self, faces: np.ndarray, vertices: torch.Tensor, device: str, outer: np.ndarray | None):
        self.device = device
        self.points = wp.array(vertices.numpy() if device == "cpu" else vertices, dtype=wp.vec3, device=device)
        self.points64 = wp.zeros(len(vertices), dtype=wp.vec3d, device=device)
        self.faces = wp.array(faces.reshape(-1).astype(np.int32), dtype=wp.int32, device=device)
        self.mesh = wp.Mesh(points=self.points, indices=self.faces)
        d = np.asarray(_DIRECTIONS, np.float32)
        self.directions = wp.array(d / np.linalg.norm(d, axis=1, keepdims=True), dtype=wp.vec3, device=device)
        self.outer_mesh = None
        if outer is not None:  # the outer faces as a second mesh over the same points, refitted when a frame needs it
            ids = np.flatnonzero(outer)
            vertex_flag = np.zeros(len(vertices), np.int32)
            vertex_flag[faces[ids].reshape(-1)] = 1
            self.outer_face = wp.array(outer.astype(np.int32), dtype=wp.int32, device=device)
            self.outer_vertex = wp.array(vertex_flag, dtype=wp.int32, device=device)
            self.outer_ids = wp.array(ids.astype(np.int32), dtype=wp.int32, device=device)
            self.outer_faces = wp.array(faces[ids].reshape(-1).astype(np.int32), dtype=wp.int32, device=device)
            self.outer_mesh = wp.Mesh(points=self.points, indices=self.outer_faces)
        else:
            self.outer_face = self.outer_vertex = wp.zeros(0, dtype=wp.int32, device=device)
        self.posed_at: torch.Tensor | None = None  # the frame (Vb, 3) float64 the meshes are refitted to
        self.outer_fitted = False

    def pose(self, vertices32: torch.Tensor, vertices64: torch.Tensor) -> None:
        """Move the meshes to one body frame, (Vb, 3) in float32 (the BVHs) and float64 (the closest points): copied
        and the BVH refitted, unless it is the frame they already hold (a caller querying one frame again and
        again, as a collision push after every step of a solver does, refits once)."""
        if self.posed_at is not None and self.posed_at.device == vertices64.device and torch.equal(self.posed_at, vertices64):
            return
        wp.copy(self.points, wp.from_torch(vertices32, dtype=wp.vec3))
        wp.copy(self.points64, wp.from_torch(vertices64, dtype=wp.vec3d))
        self.mesh.refit()
        self.outer_fitted = False
        self.posed_at = vertices64.clone()

    def fit_outer(self) -> None:
        """Refit the outer-surface mesh to the frame :meth:`pose` gave, once per frame."""
        if not self.outer_fitted:
            self.outer_mesh.refit()
            self.outer_fitted = True


_BODIES: dict = {}
_LOCK = threading.Lock()  # the cache of meshes, and the module's kernels loading (or compiling) once, for threads querying at once


def _body(faces: np.ndarray, vertices: torch.Tensor, device: str, outer: np.ndarray | None, slot) -> _Body:
    """The cached warp mesh of this topology (faces (F,3) int64, outer (F,) bool or None) on this
    device, built on ``vertices``; one per ``slot`` (calling thread, k), k the thread of :func:`query`'s own
    split of the frames: threads that query at the same time each have their own meshes."""
    key = (faces.tobytes(), None if outer is None else outer.tobytes(), vertices.shape[0], device, slot)
    with _LOCK:
        if key not in _BODIES:
            if len(_BODIES) >= 8:
                _BODIES.pop(next(iter(_BODIES)))
            _BODIES[key] = _Body(faces, vertices, device, outer)
        return _BODIES[key]


class BodyQuery(NamedTuple):
    """What :func:`query` found per point: ``winding`` (B,N) int32 winding number of the body;
    ``face`` (B,N) long closest face; ``closest`` (B,N,3) float64 closest body point; ``vertex`` (B,N)
    long nearest body vertex (None unless ``nearest_vertex=True``)."""

    winding: torch.Tensor
    face: torch.Tensor
    closest: torch.Tensor
    vertex: torch.Tensor | None


def query(points: torch.Tensor, body_vertices: torch.Tensor, body_faces: torch.Tensor, nearest_vertex: bool = False,
          outer_faces: torch.Tensor | None = None) -> BodyQuery:  # fmt: skip
    """Winding number, closest face and closest point of points against the posed body, frame by
    frame, and their nearest body vertex (``nearest_vertex``): a :class:`BodyQuery`.

    points (B,N,3) m; body_vertices (B,Vb,3); body_faces (F,3) long, a closed consistently oriented
    mesh (:func:`is_closed`). ``outer_faces`` (F,) bool (:mod:`drapebench.geometry.outer_surface`):
    the closest face and the nearest vertex are searched among the outer faces and their corners
    only (the winding number stays that of the whole mesh); a point whose closest face or nearest
    vertex over the whole mesh is buried is searched again on the outer faces. The closest face is
    searched in float32 (of two faces within about 1e-7 m of the same distance either may come back);
    the closest point on it is computed in float64. On the CPU the frames are split over
    ``torch.get_num_threads()`` threads (warp's CPU kernels release the GIL), each with its own mesh; callers on
    different threads may query at the same time (each has its own meshes).
    """
    faces = body_faces.detach().cpu().numpy().astype(np.int64)
    outer = None if outer_faces is None else torch.as_tensor(outer_faces).detach().cpu().numpy().astype(bool)
    if outer is not None and outer.shape != (len(faces),):
        raise ValueError(f"outer_faces must be one flag per body face ({len(faces)},), got {outer.shape}")
    if outer is not None and outer.all():
        outer = None
    device = "cpu" if points.device.type == "cpu" else f"cuda:{points.device.index or 0}"
    pts = points.detach().to(torch.float64).contiguous()
    verts = body_vertices.detach().to(pts.device, torch.float64).contiguous()
    verts32 = verts.float()
    B, N = pts.shape[:2]
    winding = torch.empty(B, N, dtype=torch.int32, device=pts.device)
    face = torch.empty(B, N, dtype=torch.int32, device=pts.device)
    closest = torch.empty(B, N, 3, dtype=torch.float64, device=pts.device)
    vertex = torch.empty(B, N if nearest_vertex else 0, dtype=torch.int32, device=pts.device)
    redo = torch.zeros(B, N if outer is not None else 0, dtype=torch.int32, device=pts.device)

    def frames(slot, chunk: range) -> None:
        body = _body(faces, verts32[0].cpu() if device == "cpu" else verts32[0], device, outer, slot)
        for b in chunk:
            body.pose(verts32[b], verts[b])
            q, cp, fb, vb = wp.from_torch(pts[b], dtype=wp.vec3d), wp.from_torch(closest[b], dtype=wp.vec3d), wp.from_torch(face[b]), wp.from_torch(vertex[b])
            wp.launch(_query, dim=N, device=device, inputs=[body.mesh.id, body.points, body.points64, body.faces, q, body.directions,
                                                            wp.from_torch(winding[b]), fb, cp, vb, body.outer_face, body.outer_vertex,
                                                            wp.from_torch(redo[b])])  # fmt: skip
            if body.outer_mesh is None:
                continue
            if device != "cpu":
                wp.synchronize_device(device)
            which = torch.nonzero(redo[b]).squeeze(1)
            if len(which):
                body.fit_outer()
                wp.launch(_query_outer, dim=len(which), device=device, inputs=[body.outer_mesh.id, body.points, body.points64, body.outer_faces,
                                                                               body.outer_ids, q, wp.from_torch(which), fb, cp, vb])  # fmt: skip

    with _LOCK:
        _query.module.load(wp.get_device(device))
    caller = threading.get_ident()  # each calling thread, and each thread of its split, has its own meshes
    n_threads = min(torch.get_num_threads(), B) if device == "cpu" else 1
    if n_threads <= 1:
        frames((caller, 0), range(B))
    else:
        from concurrent.futures import ThreadPoolExecutor

        with ThreadPoolExecutor(n_threads) as pool:
            list(pool.map(frames, [(caller, k) for k in range(n_threads)], [range(k, B, n_threads) for k in range(n_threads)]))
    return BodyQuery(winding, face.long(), closest, vertex.long() if nearest_vertex else None)


@lru_cache(maxsize=8)
def _closed(faces_bytes: bytes) -> bool:
    F = np.frombuffer(faces_bytes, dtype=np.int64).reshape(-1, 3)
    directed = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    key = directed[:, 0] * (int(F.max()) + 1) + directed[:, 1]
    reverse = directed[:, 1] * (int(F.max()) + 1) + directed[:, 0]
    key_sorted = np.sort(key)
    unique = len(np.unique(key)) == len(key)
    i = np.searchsorted(key_sorted, reverse)
    paired = (i < len(key_sorted)) & (key_sorted[np.minimum(i, len(key_sorted) - 1)] == reverse)
    return bool(unique and paired.all())


def is_closed(body_faces: torch.Tensor) -> bool:
    """True when every directed edge of body_faces (F,3) appears once and its reverse once: a closed,
    consistently oriented mesh, whose winding number :func:`query` computes exactly."""
    return _closed(torch.as_tensor(body_faces).detach().cpu().numpy().astype(np.int64).tobytes())
