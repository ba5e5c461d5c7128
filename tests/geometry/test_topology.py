import numpy as np
import pytest
import torch
import trimesh

from drapebench.geometry import dihedral_angles, get_topology
from drapebench.geometry.topology import build_topology_arrays
from drapebench.physics import Material
from tests.meshes import grid_mesh


def test_dihedral_of_folded_pair():
    # two triangles sharing edge (0,1) along x; the second folded up by angle a
    for a in (0.3, -0.7, 2.5):
        V = np.array([[0, 0, 0], [1, 0, 0], [0.5, -1, 0], [0.5, np.cos(a), np.sin(a)]], dtype=float)
        F = np.array([[0, 1, 2], [1, 0, 3]])
        topo = get_topology(V, F, dtype=torch.float64, cache=False)
        assert topo.hinge_edges.shape == (1, 2)
        theta = dihedral_angles(torch.as_tensor(V), topo.hinge_edges, topo.hinge_opposite)
        assert abs(abs(theta.item()) - abs(a)) < 1e-9
        assert np.isclose(topo.rest_dihedral.item(), theta.item())
    # sign flips with the fold direction
    t1 = get_topology(np.array([[0, 0, 0], [1, 0, 0], [0.5, -1, 0], [0.5, 1, 0.3]]), F, cache=False).rest_dihedral
    t2 = get_topology(np.array([[0, 0, 0], [1, 0, 0], [0.5, -1, 0], [0.5, 1, -0.3]]), F, cache=False).rest_dihedral
    assert t1.item() * t2.item() < 0


def test_cot_laplacian_of_flat_grid_vanishes_inside():
    V, F = grid_mesh(6, 0.5)
    topo = get_topology(V, F, dtype=torch.float64, cache=False)
    LX = torch.sparse.mm(topo.laplacian, torch.as_tensor(V))
    boundary = torch.cat(topo.boundary_loops)
    interior = torch.ones(len(V), dtype=torch.bool)
    interior[boundary] = False
    assert LX[interior].abs().max() < 1e-12
    assert LX[~interior].abs().max() > 1e-3
    assert len(topo.boundary_loops) == 1 and len(boundary) == 20


def test_masses_sum_to_density_times_area():
    m = trimesh.creation.icosphere(3)
    topo = get_topology(m.vertices, m.faces, dtype=torch.float64, cache=False)
    mat = Material()
    assert np.isclose(topo.vertex_masses(mat).sum().item(), mat.area_density * m.area)
    assert np.isclose(topo.face_areas.sum().item(), m.area)


def test_ring_eigenvalues_of_regular_hexagon_fan():
    r = 0.7
    ang = np.arange(6) * np.pi / 3
    V = np.concatenate([[[0, 0, 0]], np.stack([r * np.cos(ang), r * np.sin(ang), np.zeros(6)], 1)])
    F = np.array([[0, 1 + i, 1 + (i + 1) % 6] for i in range(6)])
    topo = get_topology(V, F, dtype=torch.float64, cache=False)
    # covariance of 6 points on a circle of radius r: r^2/2 in-plane (twice), 0 normal
    assert np.allclose(topo.rest_ring_eigvals[0].numpy(), [0, r**2 / 2, r**2 / 2], atol=1e-12)
    assert topo.ring_sizes[0] == 6


def test_rest_inverse_shape_matches_flattened_triangle():
    V = np.array([[0, 0, 0], [2, 0, 0], [0, 0, 3.0]])  # a triangle in the xz plane
    topo = get_topology(V, np.array([[0, 1, 2]]), dtype=torch.float64, cache=False)
    Dm = torch.linalg.inv(topo.rest_inv[0])
    assert torch.allclose(Dm, torch.tensor([[2.0, 0.0], [0.0, 3.0]], dtype=torch.float64))


def test_cache_round_trip_and_bad_meshes(tmp_path, monkeypatch):
    monkeypatch.setenv("DRAPEBENCH_DATA", str(tmp_path))
    V, F = grid_mesh(4, 0.3)
    a = get_topology(V + 1.0, F)
    from drapebench.geometry import topology as mod

    mod._MEMORY.clear()
    b = get_topology(V + 1.0, F)  # from disk
    assert torch.equal(a.laplacian.to_dense(), b.laplacian.to_dense()) and a.key == b.key
    assert all(torch.equal(x, y) for x, y in zip(a.boundary_loops, b.boundary_loops))
    with pytest.raises(ValueError, match="degenerate"):
        build_topology_arrays(np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0.0]]), np.array([[0, 1, 2]]))
    with pytest.raises(ValueError, match="non-manifold"):
        build_topology_arrays(np.random.rand(5, 3), np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]]))


def test_cot_laplacian_and_rings_against_brute_force():
    V, F = grid_mesh(5, 0.4, noise=0.05, seed=4)
    topo = get_topology(V, F, dtype=torch.float64, cache=False)
    n = len(V)
    L = np.zeros((n, n))
    for tri in F:
        for k in range(3):
            i, j, o = tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]
            u, w = V[i] - V[o], V[j] - V[o]
            cot = u @ w / np.linalg.norm(np.cross(u, w))
            L[i, j] -= cot / 2
            L[j, i] -= cot / 2
            L[i, i] += cot / 2
            L[j, j] += cot / 2
    assert np.allclose(topo.laplacian.to_dense().numpy(), L, atol=1e-12)
    ptr, idx = topo.ring_ptr.numpy(), topo.ring_idx.numpy()
    for v in range(n):
        ring = sorted(set(F[(F == v).any(1)].ravel()) - {v})
        assert idx[ptr[v] : ptr[v + 1]].tolist() == ring
        P = V[ring] - V[ring].mean(0)
        assert np.allclose(topo.rest_ring_eigvals[v].numpy(), np.linalg.eigvalsh(P.T @ P / len(ring)), atol=1e-14)
    n_edges = len({tuple(sorted((t[k], t[(k + 1) % 3]))) for t in F for k in range(3)})
    assert len(topo.edges) == n_edges and (topo.edges[:, 0] < topo.edges[:, 1]).all()
    assert len(topo.hinge_edges) == n_edges - sum(len(b) for b in topo.boundary_loops)


def test_boundary_loops_of_an_annulus():
    m = trimesh.creation.annulus(0.1, 0.3, height=0.1, sections=24)
    # keep the top cap only: an open ring with an inner and an outer boundary
    top = m.faces[np.isclose(m.triangles_center[:, 2], 0.05)]
    used = np.unique(top)
    remap = np.full(len(m.vertices), -1)
    remap[used] = np.arange(len(used))
    topo = get_topology(m.vertices[used], remap[top], cache=False)
    assert sorted(len(b) for b in topo.boundary_loops) == [24, 24]
    radii = sorted(np.linalg.norm(m.vertices[used][b.numpy(), :2], axis=1).mean() for b in topo.boundary_loops)
    assert np.allclose(radii, [0.1, 0.3])


def test_uv_rest_shape():
    V = np.array([[0, 0, 0], [0.1, 0, 0], [0, 0, 0.2]])  # a triangle in the xz plane
    F = np.array([[0, 1, 2]])
    flat = get_topology(V, F, dtype=torch.float64, cache=False)
    uv_same = np.array([[0.3, 0.3], [0.3, 0.4], [0.1, 0.3]])  # same triangle, rotated and moved in the plane
    topo = get_topology(V, F, dtype=torch.float64, cache=False, uv=uv_same)
    assert topo.uv_rest and not flat.uv_rest
    def metric(t):  # Dm^T Dm: the rest metric, invariant to in-plane rotation and translation
        Dm = torch.linalg.inv(t.rest_inv[0])
        return Dm.T @ Dm

    assert torch.allclose(metric(topo), metric(flat))  # identical metric -> identical strain
    # per-corner uv, shrunk by 10 % -> the 3D template is pre-strained by G = (1/0.81 - 1)/2 I
    shrunk = get_topology(V, F, dtype=torch.float64, cache=False, uv=(0.9 * uv_same)[F])
    Dm_inv = shrunk.rest_inv[0]
    Dm3 = torch.linalg.inv(flat.rest_inv[0])
    Fm = Dm3 @ Dm_inv  # 2D deformation gradient of the template w.r.t. the uv rest shape
    G = 0.5 * (Fm.T @ Fm - torch.eye(2, dtype=torch.float64))
    assert torch.allclose(G, (1 / 0.81 - 1) / 2 * torch.eye(2, dtype=torch.float64))
    with pytest.raises(ValueError, match="uv must be"):
        get_topology(V, F, cache=False, uv=np.zeros((3, 3)))
    with pytest.raises(ValueError, match="zero area in uv"):
        get_topology(V, F, cache=False, uv=np.zeros((3, 2)))


def test_dtype_device_and_cache_keys(tmp_path, monkeypatch):
    monkeypatch.setenv("DRAPEBENCH_DATA", str(tmp_path))
    V, F = grid_mesh(4, 0.3)
    t32 = get_topology(V, F)
    assert t32.dtype == torch.float32 and t32.laplacian.dtype == torch.float32 and t32.faces.dtype == torch.long
    t64 = t32.to(dtype=torch.float64)
    assert t64.dtype == torch.float64 and t64.laplacian.dtype == torch.float64 and t64.edges.dtype == torch.long
    assert torch.allclose(t64.rest_inv, get_topology(V, F, dtype=torch.float64).rest_inv)
    assert get_topology(V, F) is t32  # memory cache
    uv = V[:, :2] * 1.1
    assert get_topology(V, F, uv=uv).key != t32.key  # the rest shape is part of the content hash
    assert len(list((tmp_path / "cache" / "topology").glob("*.npz"))) == 2
    with pytest.raises(ValueError, match="dtype"):
        get_topology(V, F, dtype=torch.int64)
    with pytest.raises(ValueError, match="faces index"):
        get_topology(V, F + len(V), cache=False)


def test_hinge_faces_hold_their_hinge_edge_and_opposite_vertex():
    """Each hinge's two faces are distinct, and face k holds the hinge edge (in its own order for the first) and opposite vertex k."""
    V, F = grid_mesh(5, 0.4, noise=0.05, seed=4)
    topo = get_topology(V, F, dtype=torch.float64, cache=False)
    faces = topo.faces.numpy()
    for (i, j), (k, l), (f0, f1) in zip(topo.hinge_edges.numpy(), topo.hinge_opposite.numpy(), topo.hinge_faces.numpy()):
        assert f0 != f1
        assert sorted(faces[f0]) == sorted((i, j, k)) and sorted(faces[f1]) == sorted((i, j, l))
        at = list(faces[f0]).index(i)
        assert faces[f0][(at + 1) % 3] == j  # oriented as in the first face
