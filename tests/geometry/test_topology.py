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
