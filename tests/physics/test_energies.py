import numpy as np
import pytest
import torch
import trimesh

from drapebench.geometry import get_topology
from drapebench.physics import (
    Material,
    bending_energy,
    collision_energy,
    energy_terms,
    gravity_energy,
    hinge_collision_energy,
    inertia_energy,
    inextensibility_energy,
    laplacian_smoothness,
    pin_energy,
    restrain_energy,
    stvk_energy,
    validate_mesh_state,
)
from tests.meshes import grid_mesh

MAT = Material()


def rotation(seed=0):
    q, _ = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    return torch.as_tensor(q * np.sign(np.linalg.det(q)))


@pytest.fixture(scope="module")
def sheet():
    V, F = grid_mesh(5, 0.2, noise=0.01)
    return torch.as_tensor(V), get_topology(V, F, dtype=torch.float64, cache=False)


ALL = {
    "stvk": lambda x, t: stvk_energy(x, t, MAT),
    "bending_flat": lambda x, t: bending_energy(x, t, MAT),
    "bending_template": lambda x, t: bending_energy(x, t, MAT, "template"),
    "bending_blend": lambda x, t: bending_energy(x, t, MAT, blend=torch.linspace(0, 1, t.hinge_edges.shape[0], dtype=x.dtype)),
    "gravity": lambda x, t: gravity_energy(x, t, MAT),
    "inertia": lambda x, t: inertia_energy(x, torch.full_like(x, 0.05), torch.ones_like(x) * 0.1, t, MAT),
    "inext": lambda x, t: inextensibility_energy(x * 1.05, t, 1.2),
    "restrain": lambda x, t: restrain_energy(x, t, 1e-3, 2e-3),
    "smooth": lambda x, t: laplacian_smoothness(x, t),
    "pin": lambda x, t: pin_energy(x, torch.zeros(2, 3, dtype=x.dtype), torch.tensor([0, 3])),
}


@pytest.mark.parametrize("name", list(ALL))
def test_gradcheck_float64(name, sheet):
    V, topo = sheet
    x = (V + 0.003 * torch.randn_like(V))[None].clone().requires_grad_(True)
    assert torch.autograd.gradcheck(lambda y: ALL[name](y, topo), (x,), eps=1e-7, atol=1e-5, rtol=1e-4)


def test_collision_gradcheck():
    x = torch.randn(1, 20, 3, dtype=torch.float64, requires_grad=True) * 0.002
    p = torch.zeros(1, 20, 3, dtype=torch.float64)
    n = torch.tensor([0, 0, 1.0], dtype=torch.float64).expand(1, 20, 3)
    assert torch.autograd.gradcheck(lambda y: collision_energy(y, p, n), (x,))


def test_zero_strain_and_bending_at_rest(sheet):
    V, topo = sheet
    assert stvk_energy(V, topo, MAT).abs().item() < 1e-20
    assert bending_energy(V, topo, MAT, "template").abs().item() < 1e-20
    assert bending_energy(V, topo, MAT).item() > 0  # the wavy sheet is not flat
    assert inextensibility_energy(V, topo).item() < 1e-18


def test_rigid_motion_invariance(sheet):
    V, topo = sheet
    y = V + 0.01 * torch.randn_like(V)
    R, t = rotation(3), torch.tensor([0.3, -1.0, 2.0], dtype=torch.float64)
    z = y @ R.T + t
    for fn in (lambda a: stvk_energy(a, topo, MAT), lambda a: bending_energy(a, topo, MAT, "template"),
               lambda a: inextensibility_energy(a, topo)):  # fmt: skip
        assert torch.allclose(fn(y), fn(z), rtol=1e-9, atol=1e-18)


def test_closed_form_stvk_uniform_stretch():
    V = np.array([[0, 0, 0], [0.1, 0, 0], [0, 0.1, 0.0]])
    topo = get_topology(V, np.array([[0, 1, 2]]), dtype=torch.float64, cache=False)
    s = 1.2
    x = torch.as_tensor(V) * torch.tensor([s, 1.0, 1.0], dtype=torch.float64)  # stretch along x
    g = 0.5 * (s * s - 1)  # G = diag(g, 0)
    expected = 0.5 * 0.01 * MAT.thickness * (MAT.lame_mu * g * g + 0.5 * MAT.lame_lambda * g * g)
    assert np.isclose(stvk_energy(x, topo, MAT).item(), expected, rtol=1e-12)


def test_against_per_element_loops():
    V, F = grid_mesh(4, 0.2, noise=0.01, seed=2)
    topo = get_topology(V, F, dtype=torch.float64, cache=False)
    x = torch.as_tensor(V) + 0.01 * torch.randn(len(V), 3, dtype=torch.float64)
    X = x.numpy()
    total = 0.0
    for f, inv, A in zip(F, topo.rest_inv.numpy(), topo.face_areas.numpy()):
        Ds = np.stack([X[f[1]] - X[f[0]], X[f[2]] - X[f[0]]], 1)
        Fm = Ds @ inv
        G = 0.5 * (Fm.T @ Fm - np.eye(2))
        total += A * MAT.thickness * (MAT.lame_mu * (G * G).sum() + 0.5 * MAT.lame_lambda * np.trace(G) ** 2)
    assert np.isclose(stvk_energy(x, topo, MAT).item(), total, rtol=1e-10)
    total = 0.0
    for (i, j), (k, l), (f0, f1) in zip(topo.hinge_edges.numpy(), topo.hinge_opposite.numpy(), topo.hinge_faces.numpy()):
        e = X[j] - X[i]
        n0, n1 = np.cross(e, X[k] - X[i]), np.cross(X[l] - X[i], e)
        th = np.arctan2(np.dot(np.cross(n0, n1), e / np.linalg.norm(e)), np.dot(n0, n1))
        l0 = np.linalg.norm(V[j] - V[i])
        a = topo.face_areas[f0].item() + topo.face_areas[f1].item()
        total += 0.5 * MAT.bending * l0**2 / (4 * a) * th**2
    assert np.isclose(bending_energy(x, topo, MAT).item(), total, rtol=1e-10)


def test_float32_matches_float64_on_5k_mesh():
    m = trimesh.creation.icosphere(subdivisions=5, radius=0.3)  # 10k vertices
    t64 = get_topology(m.vertices, m.faces, dtype=torch.float64, cache=False)
    t32 = get_topology(m.vertices, m.faces, dtype=torch.float32, cache=False)
    x = torch.as_tensor(m.vertices) * torch.tensor([1.05, 0.98, 1.0], dtype=torch.float64)
    for fn in (stvk_energy, gravity_energy):
        a, b = fn(x, t64, MAT), fn(x.float(), t32, MAT)
        assert np.isclose(a.item(), b.item(), rtol=1e-3), fn.__name__
    assert np.isclose(bending_energy(x, t64, MAT, "template").item(), bending_energy(x.float(), t32, MAT, "template").item(), rtol=2e-2)


def test_energy_terms_has_what_the_scene_needs(sheet):
    V, topo = sheet
    x = V[None]
    assert set(energy_terms(x, topo, MAT)) == {"stvk", "bending", "gravity"}
    body = torch.as_tensor(np.random.rand(1, 30, 3)) - 0.5
    normals = torch.nn.functional.normalize(torch.randn(1, 30, 3, dtype=torch.float64), dim=-1)
    t = energy_terms(x, topo, MAT, body, normals, x_prev=x, v_prev=torch.zeros_like(x))
    assert set(t) == {"stvk", "bending", "gravity", "inertia", "collision"}
    with pytest.raises(ValueError, match="x_prev and v_prev"):
        energy_terms(x, topo, MAT, x_prev=x)


def test_hinge_collision_is_zero_outside():
    p = torch.zeros(1, 3, 3)
    n = torch.tensor([0, 0, 1.0]).expand(1, 3, 3)
    x = torch.tensor([[[0, 0, 0.01], [0, 0, -0.01], [0, 0, 0.001]]])
    per = hinge_collision_energy(x, p, n, 2e-3, per_element=True)[0]
    assert per[0] == 0 and np.isclose(per[1].item(), 0.012) and np.isclose(per[2].item(), 0.001)
    assert np.isclose(collision_energy(x, p, n, 2e-3).item(), 0.012**3 + 0.001**3)


def test_degenerate_states_stay_finite_and_are_reported(sheet):
    V, topo = sheet
    F = topo.faces
    cases = {}
    x = V.clone()
    x[F[0, 1]] = x[F[0, 0]]  # collapsed edge and zero-area face
    cases["collapsed"] = x
    x = V.clone()
    x[F[3, 2]] = x[F[3, 0]] * 2 - x[F[3, 2]]  # flip a triangle through its vertex
    cases["flipped"] = x
    x = V.clone()
    h = topo.hinge_opposite[5]
    i, j = topo.hinge_edges[5]
    x[h[1]] = x[h[0]]  # fold a hinge completely: dihedral at +-pi
    cases["folded"] = x
    cases["stretch100"] = V * 100
    for name, x in cases.items():
        for dtype in (torch.float32, torch.float64):
            y = x.to(dtype)[None].clone().requires_grad_(True)
            t = topo.to(dtype=dtype)
            e = (stvk_energy(y, t, MAT) + bending_energy(y, t, MAT, "template") + inextensibility_energy(y, t)
                 + laplacian_smoothness(y, t) + restrain_energy(y, t, 0.0, 1e-3) + gravity_energy(y, t, MAT))  # fmt: skip
            e.sum().backward()
            assert torch.isfinite(e).all() and torch.isfinite(y.grad).all(), (name, dtype)
    report = validate_mesh_state(cases["collapsed"], topo)
    assert not report.ok and report.collapsed_edges and report.degenerate_faces
    assert validate_mesh_state(cases["folded"], topo).folded_hinges
    assert validate_mesh_state(cases["stretch100"], topo).overstretched_edges
    assert validate_mesh_state(V, topo).ok
    bad = V.clone()
    bad[2, 1] = float("nan")
    assert validate_mesh_state(bad, topo).nonfinite_vertices == [(0, 2)]
