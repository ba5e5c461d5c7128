"""Mesh surgery for garment construction: isoline cuts, connected components, remeshing."""

from __future__ import annotations

import numpy as np
import scipy.sparse
from scipy.sparse.csgraph import connected_components


def cut_by_field(V: np.ndarray, F: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Keep the part of a triangle mesh where the per-vertex scalar ``s`` <= 0, cutting faces exactly
    along the zero isoline (edge-interpolated vertices, shared between neighbouring faces).
    Orientation is preserved."""
    inside = s <= 0
    n_in = inside[F].sum(1)
    keep_full = F[n_in == 3]
    straddle = F[(n_in == 1) | (n_in == 2)]
    new_pts: dict[tuple[int, int], int] = {}
    verts = [V]
    count = [len(V)]

    def cross(a: int, b: int) -> int:
        key = (a, b) if a < b else (b, a)
        if key not in new_pts:
            t = s[key[0]] / (s[key[0]] - s[key[1]])
            verts.append((V[key[0]] + t * (V[key[1]] - V[key[0]]))[None])
            new_pts[key] = count[0]
            count[0] += 1
        return new_pts[key]

    tris = [keep_full]
    extra = []
    for f in straddle:
        ins = inside[f]
        # rotate so the odd vertex (the one alone on its side) is first, keeping orientation
        odd = int(np.flatnonzero(ins != (ins.sum() >= 2))[0]) if ins.sum() in (1, 2) else 0
        a, b, c = f[odd], f[(odd + 1) % 3], f[(odd + 2) % 3]
        pab, pac = cross(a, b), cross(a, c)
        if inside[a]:  # one vertex inside: a small triangle
            extra.append([a, pab, pac])
        else:  # two inside (b, c): a quad split in two
            extra += [[pab, b, c], [pab, c, pac]]
    if extra:
        tris.append(np.array(extra, dtype=np.int64))
    return np.concatenate(verts), np.concatenate(tris)


def remove_unreferenced(V: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Drop vertices no face uses and renumber."""
    used = np.unique(F)
    remap = -np.ones(len(V), dtype=np.int64)
    remap[used] = np.arange(len(used))
    return V[used], remap[F]


def face_components(F: np.ndarray, n_vertices: int) -> np.ndarray:
    """Connected-component label per face (faces sharing a vertex are connected)."""
    rows = np.repeat(np.arange(len(F)), 3)
    inc = scipy.sparse.coo_matrix((np.ones(rows.size), (rows, F.ravel())), shape=(len(F), n_vertices)).tocsr()
    _, lab = connected_components(inc @ inc.T, directed=False)
    return lab


def keep_component_near(V: np.ndarray, F: np.ndarray, seed: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Keep the connected component with the face vertex nearest ``seed`` (drops hands, head, feet);
    vertices no face uses are not candidates. Raises ValueError when ``F`` has no faces."""
    if len(F) == 0:
        raise ValueError("the mesh has no faces to keep")
    lab = face_components(F, len(V))
    used = np.unique(F)
    nearest_v = used[np.argmin(np.linalg.norm(V[used] - seed, axis=1))]
    return remove_unreferenced(V, F[lab == lab[np.flatnonzero((F == nearest_v).any(1))[0]]])


def smooth_boundaries(V: np.ndarray, F: np.ndarray, iterations: int = 2) -> np.ndarray:
    """Relax every boundary loop along itself (each vertex towards the mean of its two loop
    neighbours, weight 1/2): removes the zig-zag a remesher leaves on curved openings (sleeve holes)."""
    from drapebench.geometry.topology import boundary_loops

    V = V.copy()
    loops = boundary_loops(F)
    for _ in range(iterations):
        for lp in loops:
            V[lp] = 0.5 * V[lp] + 0.25 * (V[np.roll(lp, 1)] + V[np.roll(lp, -1)])
    return V


def isotropic_remesh(V: np.ndarray, F: np.ndarray, target: float, iterations: int = 10) -> tuple[np.ndarray, np.ndarray]:
    """pymeshlab isotropic explicit remeshing to mean edge length ``target`` (m); boundaries are
    resampled but kept on the cut (surface distance checked within 2 mm), then relaxed along
    themselves and remeshed once more so boundary triangles stay well shaped."""
    from drapebench.extras import require

    pymeshlab = require("pymeshlab", "making a parametric garment (its remeshing, once per garment: the result is cached in data/cache/garments)")

    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(V.astype(np.float64), F.astype(np.int32)))
    ms.meshing_remove_duplicate_vertices()
    ms.meshing_remove_null_faces()
    ms.meshing_isotropic_explicit_remeshing(
        iterations=iterations, targetlen=pymeshlab.PureValue(target), featuredeg=75,
        checksurfdist=True, maxsurfdist=pymeshlab.PureValue(0.002),
    )  # fmt: skip
    m = ms.current_mesh()
    F0 = m.face_matrix().astype(np.int64)
    ms.add_mesh(pymeshlab.Mesh(smooth_boundaries(m.vertex_matrix(), F0), F0.astype(np.int32)))
    for attempt in range(4):  # a pass can leave a sliver; a few more iterations remove it
        ms.meshing_isotropic_explicit_remeshing(
            iterations=3, targetlen=pymeshlab.PureValue(target), featuredeg=75,
            checksurfdist=True, maxsurfdist=pymeshlab.PureValue(0.002),
        )  # fmt: skip
        # collapse micro-triangles the remesher can leave behind (edges of a few micrometres)
        ms.meshing_merge_close_vertices(threshold=pymeshlab.PureValue(0.05 * target))
        ms.meshing_remove_null_faces()
        ms.meshing_remove_unreferenced_vertices()
        m = ms.current_mesh()
        V, F = m.vertex_matrix().astype(np.float64), m.face_matrix().astype(np.int64)
        area = 0.5 * np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1)
        if area.min() > 1e-9:
            break
    return V, F
