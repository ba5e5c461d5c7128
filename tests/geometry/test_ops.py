import numpy as np
import torch
import trimesh

from drapebench.geometry import corners, dihedral_angles, edge_lengths, face_areas, face_normals, get_topology, vertex_normals
from tests.meshes import grid_mesh


def random_mesh(seed=0):
    V, F = grid_mesh(5, 0.3, noise=0.02, seed=seed)
    return torch.as_tensor(V), torch.as_tensor(F)


def test_face_quantities_against_a_loop():
    V, F = random_mesh()
    X = V.numpy()
    areas, normals = face_areas(V, F), face_normals(V, F)
    for k, (a, b, c) in enumerate(F.tolist()):
        cr = np.cross(X[b] - X[a], X[c] - X[a])
        assert np.isclose(areas[k].item(), 0.5 * np.linalg.norm(cr), rtol=1e-12)
        assert np.allclose(normals[k].numpy(), cr / np.linalg.norm(cr), atol=1e-12)


def test_vertex_normals_are_area_weighted():
    V, F = random_mesh(1)
    X = V.numpy()
    n = vertex_normals(V, F).numpy()
    acc = np.zeros_like(X)
    for a, b, c in F.tolist():
        cr = np.cross(X[b] - X[a], X[c] - X[a])  # = 2 A n_f
        for i in (a, b, c):
            acc[i] += cr
    assert np.allclose(n, acc / np.linalg.norm(acc, axis=1, keepdims=True), atol=1e-12)
    # on a sphere they point outwards along the radius
    m = trimesh.creation.icosphere(3)
    ns = vertex_normals(torch.as_tensor(m.vertices), torch.as_tensor(m.faces))
    radial = torch.nn.functional.normalize(torch.as_tensor(m.vertices), dim=-1)
    assert (ns * radial).sum(-1).min() > 0.999


def test_batched_leading_dimensions():
    V, F = random_mesh(2)
    x = V.expand(2, 3, -1, -1) * torch.arange(1, 7, dtype=V.dtype).reshape(2, 3, 1, 1)
    topo = get_topology(V, F, dtype=torch.float64, cache=False)
    assert vertex_normals(x, F).shape == x.shape
    assert torch.allclose(face_areas(x, F)[1, 2], 36 * face_areas(V, F))
    assert torch.allclose(edge_lengths(x, topo)[0, 1], 2 * topo.rest_edge_lengths)
    assert torch.allclose(edge_lengths(x, topo), edge_lengths(x, topo.edges))
    assert torch.allclose(dihedral_angles(x, topo)[1, 0], topo.rest_dihedral)  # scale-invariant


def test_corners_equal_per_corner_gathers():
    V, F = random_mesh(3)
    for x in (V, V + torch.randn(2, 3, *V.shape, dtype=V.dtype)):
        c = corners(x, F)
        assert c.shape == (3, 3, *x.shape[:-2], F.shape[0])
        for j in range(3):
            assert torch.equal(c[j].movedim(0, -1), x[..., F[:, j], :])


def test_dihedral_sign_convention():
    # hinge (0,1) along x; first face (0,1,2) has normal -z; its opposite vertex 3 goes up (+z), behind the plane
    a = 0.4
    V = torch.tensor([[0, 0, 0], [1, 0, 0], [0.5, -1, 0], [0.5, np.cos(a), np.sin(a)]], dtype=torch.float64)
    topo = get_topology(V, torch.tensor([[0, 1, 2], [1, 0, 3]]), dtype=torch.float64, cache=False)
    n0 = face_normals(V, topo.faces)[0]
    assert (n0 * (V[3] - V[0])).sum() < 0
    assert np.isclose(dihedral_angles(V, topo).item(), a)
    V[3, 2] = 0.0  # flat
    assert abs(dihedral_angles(V, topo).item()) < 1e-15


def test_degenerate_inputs_have_finite_gradients():
    V, F = random_mesh(3)
    topo = get_topology(V, F, dtype=torch.float64, cache=False)
    for dtype in (torch.float32, torch.float64):
        x = V.to(dtype).clone()
        x[F[0, 1]] = x[F[0, 0]]  # collapsed edge + zero-area face
        x[topo.hinge_opposite[4, 1]] = x[topo.hinge_opposite[4, 0]]  # hinge at +-pi
        x.requires_grad_(True)
        t = topo.to(dtype=dtype)
        total = (face_areas(x, F).sum() + edge_lengths(x, t).sum() + dihedral_angles(x, t).sum()
                 + vertex_normals(x, F).sum() + face_normals(x, F).sum())  # fmt: skip
        total.backward()
        assert torch.isfinite(total) and torch.isfinite(x.grad).all(), dtype
        assert abs(abs(dihedral_angles(x.detach(), t)[4].item()) - np.pi) < 1e-3


def test_ring_smooth_averages_each_vertex_with_its_one_ring():
    from drapebench.geometry.ops import ring_smooth

    V, F = random_mesh(4)
    topo = get_topology(V, F, dtype=torch.float64, cache=False)
    x = torch.randn(len(V), 2, dtype=torch.float64)
    ptr, idx = topo.ring_ptr.tolist(), topo.ring_idx
    expected = torch.stack([(x[v] + x[idx[ptr[v] : ptr[v + 1]]].sum(0)) / (ptr[v + 1] - ptr[v] + 1) for v in range(len(V))])
    assert torch.allclose(ring_smooth(x, topo, 1), expected, atol=1e-12)
    ones = torch.ones(len(V), 1, dtype=torch.float64)
    assert torch.allclose(ring_smooth(ones, topo, 3), ones, atol=1e-12)  # a constant stays constant
