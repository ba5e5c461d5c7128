"""Topology: the per-garment mesh quantities every method and energy uses, built once and cached.

Built from rest vertices (V, 3) and triangles (F, 3) with vectorised numpy/scipy, stored as torch
tensors; cached in memory and on disk (``data/cache/topology``) by a content hash of the mesh.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

import numpy as np
import scipy.sparse
import torch

from drapebench.cache import Cache, content_hash

_MEMORY: dict[str, "Topology"] = {}
TOPOLOGIES = Cache("topology", 2)  # bump the version when the stored arrays change


def _write_arrays(arr: dict, path) -> None:
    """Store :func:`build_topology_arrays`' dict as npz (boundary loops flattened)."""
    loops = arr["boundary_loops"]
    flat = np.concatenate(loops) if loops else np.zeros(0, np.int64)
    split = np.cumsum([len(lp) for lp in loops])[:-1] if loops else np.zeros(0, np.int64)
    with open(path, "wb") as fh:
        np.savez(fh, loops_flat=flat, loops_split=split, **{k: v for k, v in arr.items() if k != "boundary_loops"})


def _read_arrays(path) -> dict:
    """What :func:`_write_arrays` stored."""
    with np.load(path, allow_pickle=False) as z:
        arr = {k: z[k] for k in z.files}
    arr["boundary_loops"] = np.split(arr.pop("loops_flat"), arr.pop("loops_split"))
    return arr


@dataclass(frozen=True)
class Topology:
    """Immutable mesh topology and rest-state quantities (SI units).

    faces (F,3) long; edges (E,2) long with i < j; rest_edge_lengths (E,) m;
    hinge_edges (H,2) interior edges oriented as in their first face; hinge_faces (H,2);
    hinge_opposite (H,2) the vertex of each face opposite the edge; rest_dihedral (H,) signed
    dihedral angle (rad, 0 = flat, atan2 form); hinge_rest_lengths (H,) m; face_areas (F,) m^2 (3D rest
    areas); rest_inv (F,2,2) inverse of the rest edge matrix Dm = [x1-x0, x2-x0] expressed in 2D: the
    3D rest triangle rotated into its own plane, or the UV (sewing-pattern, metres) triangle when the
    mesh was built with ``uv`` (then ``uv_rest`` is True and the template itself is pre-strained, as
    SNUG and Chen et al. 2024 do for pants, shorts and dresses); vertex_areas (V,) lumped (sum of A/3);
    ring_ptr (V+1,), ring_idx (nnz,) 1-ring neighbours in CSR form; rest_ring_eigvals (V,3)
    ascending eigenvalues of the covariance of each vertex's 1-ring neighbours (centre excluded,
    mean-centred, divided by the count; Chen et al. 2024); laplacian (V,V) sparse cotangent Laplacian
    (positive semi-definite, L_ii = sum of cot weights); boundary_loops: list of (n,) vertex loops.
    """

    faces: torch.Tensor
    edges: torch.Tensor
    rest_edge_lengths: torch.Tensor
    hinge_edges: torch.Tensor
    hinge_faces: torch.Tensor
    hinge_opposite: torch.Tensor
    rest_dihedral: torch.Tensor
    hinge_rest_lengths: torch.Tensor
    face_areas: torch.Tensor
    rest_inv: torch.Tensor
    vertex_areas: torch.Tensor
    ring_ptr: torch.Tensor
    ring_idx: torch.Tensor
    rest_ring_eigvals: torch.Tensor
    laplacian: torch.Tensor
    boundary_loops: tuple
    key: str = ""
    uv_rest: bool = False

    @property
    def n_vertices(self) -> int:
        return self.vertex_areas.shape[0]

    @property
    def n_faces(self) -> int:
        return self.faces.shape[0]

    @property
    def dtype(self) -> torch.dtype:
        return self.face_areas.dtype

    @property
    def device(self) -> torch.device:
        return self.face_areas.device

    @property
    def ring_sizes(self) -> torch.Tensor:
        """Number of 1-ring neighbours per vertex (V,)."""
        return self.ring_ptr[1:] - self.ring_ptr[:-1]

    @property
    def ring_owner(self) -> torch.Tensor:
        """For each CSR entry, the vertex it belongs to (nnz,)."""
        return torch.repeat_interleave(torch.arange(self.n_vertices, device=self.device), self.ring_sizes)

    def vertex_masses(self, material) -> torch.Tensor:
        """Lumped vertex masses (V,) kg = area density x lumped area."""
        return self.vertex_areas * material.area_density

    def to(self, device=None, dtype=None) -> "Topology":
        """A copy with float tensors cast to ``dtype`` and all tensors moved to ``device``."""
        changes = {}
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, torch.Tensor):
                changes[f.name] = v.to(device=device, dtype=dtype if (dtype and v.is_floating_point()) else None)
        changes["boundary_loops"] = tuple(b.to(device) for b in self.boundary_loops)
        return replace(self, **changes)


def boundary_loops(faces: np.ndarray) -> list[np.ndarray]:
    """Boundary loops of a triangle mesh as ordered vertex arrays (following the faces' orientation)."""
    f = np.asarray(faces, dtype=np.int64)
    a, b = f.ravel(), f[:, [1, 2, 0]].ravel()
    n = int(f.max()) + 1 if f.size else 0
    und = np.minimum(a, b) * n + np.maximum(a, b)
    keys, inv, counts = np.unique(und, return_inverse=True, return_counts=True)
    on_boundary = counts[inv] == 1
    nxt = dict(zip(a[on_boundary].tolist(), b[on_boundary].tolist()))
    loops, seen = [], set()
    for v0 in nxt:
        if v0 in seen:
            continue
        loop, v = [], v0
        while v not in seen and v in nxt:
            seen.add(v)
            loop.append(v)
            v = nxt[v]
        loops.append(np.array(loop, dtype=np.int64))
    return loops


def _dihedral(x0, x1, opp0, opp1):
    """Signed dihedral angle of hinges (numpy, for rest state); same convention as ops.dihedral_angles."""
    e = x1 - x0
    n0 = np.cross(e, opp0 - x0)
    n1 = np.cross(opp1 - x0, e)
    eh = e / np.maximum(np.linalg.norm(e, axis=-1, keepdims=True), 1e-30)
    return np.arctan2((np.cross(n0, n1) * eh).sum(-1), (n0 * n1).sum(-1))


def _uv_corners(uv: np.ndarray, faces: np.ndarray, n_vertices: int) -> np.ndarray:
    """UV coordinates per face corner (F, 3, 2) from per-vertex (V, 2) or per-corner (F, 3, 2) input."""
    uv = np.asarray(uv, dtype=np.float64)
    if uv.shape == (n_vertices, 2):
        return uv[faces]
    if uv.ndim == 3 and uv.shape == (faces.shape[0], 3, 2):
        return uv
    raise ValueError(
        f"uv must be per vertex ({n_vertices}, 2) or per face corner ({faces.shape[0]}, 3, 2), got shape {uv.shape}"
    )


def build_topology_arrays(vertices: np.ndarray, faces: np.ndarray, uv: np.ndarray | None = None) -> dict:
    """Compute every Topology quantity in float64 numpy (see :class:`Topology`).

    ``uv`` (V, 2) or (F, 3, 2), metres: optional rest shape for ``rest_inv`` (sewing-pattern coordinates).
    """
    V = vertices.shape[0]
    x = vertices.astype(np.float64)
    f = faces.astype(np.int64)
    F = f.shape[0]
    # half-edges (a -> b) of each face with the opposite vertex
    a = f[:, [0, 1, 2]].reshape(-1)
    b = f[:, [1, 2, 0]].reshape(-1)
    c = f[:, [2, 0, 1]].reshape(-1)
    face_of = np.repeat(np.arange(F), 3)
    key = np.minimum(a, b) * V + np.maximum(a, b)
    order = np.argsort(key, kind="stable")
    uniq, start, counts = np.unique(key[order], return_index=True, return_counts=True)
    edges = np.stack([uniq // V, uniq % V], 1)
    if counts.max(initial=0) > 2:
        bad = edges[counts > 2][:10].tolist()
        raise ValueError(f"non-manifold edges (shared by more than two faces), e.g. {bad}; fix the mesh")
    inner = counts == 2
    h0 = order[start[inner]]
    h1 = order[start[inner] + 1]
    hinge_edges = np.stack([a[h0], b[h0]], 1)
    hinge_faces = np.stack([face_of[h0], face_of[h1]], 1)
    hinge_opp = np.stack([c[h0], c[h1]], 1)
    rest_dihedral = _dihedral(x[hinge_edges[:, 0]], x[hinge_edges[:, 1]], x[hinge_opp[:, 0]], x[hinge_opp[:, 1]])
    # faces: areas, flattened rest shape
    e1 = x[f[:, 1]] - x[f[:, 0]]
    e2 = x[f[:, 2]] - x[f[:, 0]]
    cross = np.cross(e1, e2)
    dbl = np.linalg.norm(cross, axis=1)
    if (dbl <= 1e-14).any():
        bad = np.flatnonzero(dbl <= 1e-14)[:10].tolist()
        raise ValueError(f"degenerate (zero-area) faces {bad}; remove or repair them before building the topology")
    areas = 0.5 * dbl
    l1 = np.linalg.norm(e1, axis=1)
    u = e1 / l1[:, None]
    n = cross / dbl[:, None]
    w = np.cross(n, u)
    Dm = np.zeros((F, 2, 2))
    Dm[:, 0, 0] = l1
    Dm[:, 0, 1] = (e2 * u).sum(1)
    Dm[:, 1, 1] = (e2 * w).sum(1)
    if uv is not None:
        c_uv = _uv_corners(uv, f, V)
        Dm = np.stack([c_uv[:, 1] - c_uv[:, 0], c_uv[:, 2] - c_uv[:, 0]], axis=-1)  # columns = edges
        det = np.abs(np.linalg.det(Dm))
        if (det <= 1e-14).any():
            bad = np.flatnonzero(det <= 1e-14)[:10].tolist()
            raise ValueError(f"faces {bad} have zero area in uv; fix the uv layout or build without uv")
    rest_inv = np.linalg.inv(Dm)
    vertex_areas = np.bincount(f.reshape(-1), np.repeat(areas / 3.0, 3), minlength=V)
    # 1-ring CSR from the undirected edges
    src = np.concatenate([edges[:, 0], edges[:, 1]])
    dst = np.concatenate([edges[:, 1], edges[:, 0]])
    o = np.lexsort((dst, src))
    src, dst = src[o], dst[o]
    ring_ptr = np.concatenate([[0], np.cumsum(np.bincount(src, minlength=V))])
    ring_idx = dst
    # rest 1-ring covariance eigenvalues (neighbours only, mean-centred, / count)
    cnt = np.maximum(np.diff(ring_ptr), 1)
    xn = x[ring_idx]
    mean = np.zeros((V, 3))
    np.add.at(mean, src, xn)
    mean /= cnt[:, None]
    d = xn - mean[src]
    cov = np.zeros((V, 3, 3))
    np.add.at(cov, src, d[:, :, None] * d[:, None, :])
    cov /= cnt[:, None, None]
    eig = np.linalg.eigvalsh(cov)
    # cotangent Laplacian: weight (cot alpha + cot beta) / 2 per edge, opposite angles at c
    pa, pb, pc = x[a], x[b], x[c]
    ua, ub = pa - pc, pb - pc
    cot = (ua * ub).sum(1) / np.maximum(np.linalg.norm(np.cross(ua, ub), axis=1), 1e-30)
    W = scipy.sparse.coo_matrix((0.5 * cot, (a, b)), shape=(V, V)).tocsr()
    W = W + W.T
    L = scipy.sparse.diags(np.asarray(W.sum(1)).ravel()) - W
    L = L.tocoo()
    loops = boundary_loops(f)
    return dict(
        faces=f, edges=edges, rest_edge_lengths=np.linalg.norm(x[edges[:, 1]] - x[edges[:, 0]], axis=1),
        hinge_edges=hinge_edges, hinge_faces=hinge_faces, hinge_opposite=hinge_opp, rest_dihedral=rest_dihedral,
        hinge_rest_lengths=np.linalg.norm(x[hinge_edges[:, 1]] - x[hinge_edges[:, 0]], axis=1),
        face_areas=areas, rest_inv=rest_inv, vertex_areas=vertex_areas, ring_ptr=ring_ptr, ring_idx=ring_idx,
        rest_ring_eigvals=eig, lap_row=L.row, lap_col=L.col, lap_val=L.data, boundary_loops=loops,
        uv_rest=np.array(uv is not None),
    )  # fmt: skip


def _from_arrays(arr: dict, key: str, dtype: torch.dtype) -> Topology:
    V = arr["vertex_areas"].shape[0]
    t = lambda k: torch.as_tensor(arr[k], dtype=dtype, device="cpu")  # noqa: E731  (built on the CPU, then moved: get_topology)
    i = lambda k: torch.as_tensor(arr[k], dtype=torch.long, device="cpu")  # noqa: E731
    lap = torch.sparse_coo_tensor(
        torch.as_tensor(np.stack([arr["lap_row"], arr["lap_col"]]), dtype=torch.long, device="cpu"), t("lap_val"), (V, V), check_invariants=True
    ).coalesce()
    return Topology(
        faces=i("faces"), edges=i("edges"), rest_edge_lengths=t("rest_edge_lengths"), hinge_edges=i("hinge_edges"),
        hinge_faces=i("hinge_faces"), hinge_opposite=i("hinge_opposite"), rest_dihedral=t("rest_dihedral"),
        hinge_rest_lengths=t("hinge_rest_lengths"), face_areas=t("face_areas"), rest_inv=t("rest_inv"), vertex_areas=t("vertex_areas"), ring_ptr=i("ring_ptr"),
        ring_idx=i("ring_idx"), rest_ring_eigvals=t("rest_ring_eigvals"), laplacian=lap,
        boundary_loops=tuple(torch.as_tensor(b, dtype=torch.long, device="cpu") for b in arr["boundary_loops"]), key=key,
        uv_rest=bool(arr["uv_rest"]),
    )  # fmt: skip


def get_topology(
    vertices, faces, dtype: torch.dtype = torch.float32, device="cpu", cache: bool = True, uv=None
) -> Topology:
    """The :class:`Topology` of a mesh, cached in memory and on disk (``data/cache/topology``) by content hash.

    Args:
        vertices: (V, 3) rest positions (m), numpy or torch.
        faces: (F, 3) triangle indices.
        dtype: float32 (default) or float64 for the float tensors.
        device: where the tensors live.
        cache: False builds afresh and stores nothing.
        uv: optional (V, 2) or (F, 3, 2) sewing-pattern coordinates (m) used as the StVK rest shape.
    Raises:
        ValueError for malformed arrays, non-manifold edges or zero-area faces (named by index).
    """
    if dtype not in (torch.float32, torch.float64):
        raise ValueError(f"dtype must be torch.float32 or torch.float64, got {dtype}")
    x = np.asarray(vertices.detach().cpu() if isinstance(vertices, torch.Tensor) else vertices, dtype=np.float64)
    f = np.asarray(faces.detach().cpu() if isinstance(faces, torch.Tensor) else faces, dtype=np.int64)
    if x.ndim != 2 or x.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3:
        raise ValueError(f"expected vertices (V,3) and faces (F,3), got {x.shape} and {f.shape}")
    if f.size and (f.min() < 0 or f.max() >= len(x)):
        raise ValueError(f"faces index outside [0, {len(x)})")
    uv_arr = None
    if uv is not None:
        uv_arr = np.asarray(uv.detach().cpu() if isinstance(uv, torch.Tensor) else uv, dtype=np.float64)
        _uv_corners(uv_arr, f, len(x))  # validates the shape before anything is hashed or built
    key = content_hash(x, f) if uv_arr is None else content_hash(x, f, uv_arr)
    mem_key = f"{key}-{dtype}-{device}"
    if cache and mem_key in _MEMORY:
        return _MEMORY[mem_key]
    path = TOPOLOGIES.path(x, f, uv_arr)
    arr = TOPOLOGIES.get_or_build(path, lambda: build_topology_arrays(x, f, uv_arr), _write_arrays, _read_arrays, enabled=cache)
    topo = _from_arrays(arr, key, dtype)
    if str(device) != "cpu":
        topo = topo.to(device=device)
    if cache:
        _MEMORY[mem_key] = topo
    return topo
