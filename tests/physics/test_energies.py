import numpy as np
import pytest
import torch
import trimesh

from drapebench.geometry import get_topology
from drapebench.geometry.ops import dihedral_angles
from drapebench.physics import (
    Material,
    bending_energy,
    collision_aware_kext,
    collision_energy,
    energy_terms,
    gravity_energy,
    hinge_collision_energy,
    inertia_energy,
    inextensibility_energy,
    laplacian,
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
    "bending_current_scale": lambda x, t: bending_energy(x, t, MAT, "template", scale="current"),
    "smooth": lambda x, t: laplacian_smoothness(x, t),
    "smooth_squared": lambda x, t: laplacian_smoothness(x, t, squared=True),
    "inext_per_vertex_kext": lambda x, t: inextensibility_energy(x, t, torch.linspace(1, 1.3, t.n_vertices, dtype=x.dtype)[None]),
    "pin": lambda x, t: pin_energy(x, torch.zeros(2, 3, dtype=x.dtype), torch.tensor([0, 3])),
}


@pytest.mark.parametrize("name", list(ALL))
def test_gradcheck_float64(name, sheet):
    V, topo = sheet
    x = (V + 0.003 * torch.randn_like(V))[None].clone().requires_grad_(True)
    assert torch.autograd.gradcheck(lambda y: ALL[name](y, topo), (x,), eps=1e-7, atol=1e-5, rtol=1e-4)


@pytest.mark.parametrize("fn", [collision_energy, hinge_collision_energy])
def test_collision_gradcheck(fn):
    # keep points away from the kink at d = eps, where the hinge is not differentiable
    z = torch.linspace(-0.01, 0.01, 20, dtype=torch.float64)
    z = z[(z - 2e-3).abs() > 5e-4]
    x = torch.stack([torch.randn_like(z) * 0.01, torch.randn_like(z) * 0.01, z], -1)[None].requires_grad_(True)
    p = torch.randn(1, len(z), 3, dtype=torch.float64) * 0.01 * torch.tensor([1, 1, 0.0], dtype=torch.float64)
    n = torch.tensor([0, 0, 1.0], dtype=torch.float64).expand(1, len(z), 3)
    assert torch.autograd.gradcheck(lambda y: fn(y, p, n, 2e-3), (x,))


def test_per_element_values_sum_to_the_totals(sheet):
    V, topo = sheet
    x = V + 0.01 * torch.randn(2, *V.shape, dtype=V.dtype)
    for name, fn in {
        "stvk": lambda **k: stvk_energy(x, topo, MAT, **k),
        "bending": lambda **k: bending_energy(x, topo, MAT, "template", **k),
        "gravity": lambda **k: gravity_energy(x, topo, MAT, **k),
        "inext": lambda **k: inextensibility_energy(x, topo, **k),
        "restrain": lambda **k: restrain_energy(x, topo, 1e-3, 2e-3, **k),
        "smooth": lambda **k: laplacian_smoothness(x, topo, **k),
    }.items():
        total, per = fn(), fn(per_element=True)
        assert total.shape == (2,) and per.shape[0] == 2 and per.shape[1] > 1, name
        assert torch.allclose(per.sum(-1), total), name
        assert not torch.allclose(total[0], total[1]), name  # the batch entries are computed separately


def test_closed_forms_of_the_simple_terms(sheet):
    V, topo = sheet
    x = V[None]
    m = topo.vertex_masses(MAT)
    h = 0.37
    lifted = x + torch.tensor([0, 0, h], dtype=x.dtype)
    assert np.isclose((gravity_energy(lifted, topo, MAT) - gravity_energy(x, topo, MAT)).item(), 9.81 * h * m.sum().item())
    v = torch.randn_like(x)
    dt = MAT.dt
    assert inertia_energy(x + dt * v, x, v, topo, MAT).abs().item() < 1e-20  # x == x_hat
    off = 0.01 * torch.randn_like(x)
    expected = (m * (off[0] ** 2).sum(-1)).sum() / (2 * dt * dt)
    assert np.isclose(inertia_energy(x + dt * v + off, x, v, topo, MAT).item(), expected.item())
    pins = torch.tensor([0, 5, 7])
    assert np.isclose(pin_energy(x + 0.1, x[0, pins], pins).item(), 3 * 3 * 0.01)
    # restrain: uniform scaling by s changes every edge by (s - 1) l0
    s = 1.02
    phi = (s - 1) * topo.rest_edge_lengths
    assert np.isclose(restrain_energy(x * s, topo, 1e-3, 2e-3).item(), (((phi - 1e-3) / 2e-3) ** 2).sum().item())
    with pytest.raises(ValueError, match="fabric_std"):
        restrain_energy(x, topo, 1e-3, 0.0)
    # smoothness: sum over vertices of |L x| (m), or of |L x|^2 with squared (the cotangent Laplacian applied to positions)
    bumped = x + 0.01 * torch.randn_like(x)
    lx = laplacian(bumped, topo)[0]
    assert np.isclose(laplacian_smoothness(bumped, topo).item(), lx.norm(dim=-1).sum().item())
    assert np.isclose(laplacian_smoothness(bumped, topo, squared=True).item(), (lx * lx).sum().item())


def test_gaps_bending_blend_interpolates_flat_and_template(sheet):
    V, topo = sheet
    x = (V + 0.01 * torch.randn_like(V))[None]
    H = topo.hinge_edges.shape[0]
    flat, tmpl = bending_energy(x, topo, MAT, "flat"), bending_energy(x, topo, MAT, "template")
    assert torch.allclose(bending_energy(x, topo, MAT, blend=torch.zeros(H, dtype=x.dtype)), flat)
    assert torch.allclose(bending_energy(x, topo, MAT, blend=torch.ones(H, dtype=x.dtype)), tmpl)
    half = bending_energy(x, topo, MAT, blend=torch.full((H,), 0.5, dtype=x.dtype))
    assert torch.allclose(half, 0.5 * (flat + tmpl))
    custom = bending_energy(x, topo, MAT, topo.rest_dihedral)
    assert torch.allclose(custom, tmpl)
    with pytest.raises(ValueError, match="rest_angle"):
        bending_energy(x, topo, MAT, "curved")


def test_inextensibility_against_a_per_vertex_loop(sheet):
    V, topo = sheet
    x = V + 0.02 * torch.randn_like(V)
    k = 1.0 + 0.1 * torch.rand(topo.n_vertices, dtype=V.dtype)
    X, ptr, idx = x.numpy(), topo.ring_ptr.numpy(), topo.ring_idx.numpy()
    total = 0.0
    for v in range(topo.n_vertices):
        P = X[idx[ptr[v] : ptr[v + 1]]]
        C = np.cov(P.T, bias=True)  # neighbours only, mean-centred, divided by the count
        total += sum(abs(np.linalg.det(C - k[v].item() * sig * np.eye(3))) for sig in topo.rest_ring_eigvals[v].numpy())
    assert np.isclose(inextensibility_energy(x, topo, k[None]).item(), total, rtol=1e-10)
    # a uniform scale s multiplies the covariance by s^2: k_ext = s^2 makes the residual vanish
    assert inextensibility_energy(V * 1.1, topo, 1.21).item() < 1e-9 * inextensibility_energy(V * 1.1, topo).item()


def test_collision_aware_kext_follows_gaps_eq16():
    d = torch.tensor([[0.05, 2e-3, 1e-3, -1e-3, -0.05]])
    assert torch.allclose(collision_aware_kext(d, epoch=0), torch.ones_like(d))
    k = collision_aware_kext(d, epoch=250)
    assert torch.allclose(k, torch.tensor([[1.0, 1.0, 1.0 + 0.01 * 100, 4.0, 4.0]]))
    assert torch.allclose(collision_aware_kext(d, epoch=50)[0, -1], torch.tensor(1 + 0.03 * 50))



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
    total, total_edge = 0.0, 0.0
    for (i, j), (k, l), (f0, f1) in zip(topo.hinge_edges.numpy(), topo.hinge_opposite.numpy(), topo.hinge_faces.numpy()):
        e = X[j] - X[i]
        n0, n1 = np.cross(e, X[k] - X[i]), np.cross(X[l] - X[i], e)
        th = np.arctan2(np.dot(np.cross(n0, n1), e / np.linalg.norm(e)), np.dot(n0, n1))
        l0 = np.linalg.norm(V[j] - V[i])
        a = topo.face_areas[f0].item() + topo.face_areas[f1].item()  # rest areas in both scales
        total += 0.5 * MAT.bending * l0**2 / (4 * a) * th**2
        total_edge += 0.5 * MAT.bending * np.dot(e, e) / (4 * a) * th**2  # the SNUG/GAPS code: the deformed edge's length
    assert np.isclose(bending_energy(x, topo, MAT).item(), total, rtol=1e-10)
    assert np.isclose(bending_energy(x, topo, MAT, scale="edge").item(), total_edge, rtol=1e-10)


def test_edge_scale_grows_with_the_hinge_stretch_squared():
    """One hinge of two triangles, folded, then stretched 1.25x along its edge: the code's ("edge") scale is the
    rest one times 1.25^2 for the same angle, and the rest scale does not change."""
    V = np.array([[0.0, 0, 0], [0.1, 0, 0], [0.05, 0.08, 0], [0.05, -0.08, 0]])
    F = np.array([[0, 1, 2], [1, 0, 3]])
    topo = get_topology(V, F, dtype=torch.float64, cache=False)
    folded = torch.as_tensor(V).clone()
    folded[3, 2] = 0.04  # the second face turned about the hinge edge (x axis)
    stretched = folded * torch.tensor([1.25, 1.0, 1.0], dtype=torch.float64)  # the hinge edge 1.25x, the angle kept
    assert torch.isclose(dihedral_angles(stretched[None], topo), dihedral_angles(folded[None], topo)).all()
    rest = bending_energy(stretched, topo, MAT)
    assert torch.isclose(bending_energy(folded, topo, MAT, scale="edge"), rest)  # unstretched: the two scales agree
    assert torch.isclose(bending_energy(stretched, topo, MAT, scale="edge"), 1.25**2 * rest)
    with pytest.raises(ValueError, match="scale must be"):
        bending_energy(folded, topo, MAT, scale="length")


def test_float32_matches_float64_on_5k_mesh():
    m = trimesh.creation.icosphere(subdivisions=4, radius=0.3)
    V, F = np.asarray(m.vertices), np.asarray(m.faces)
    V = np.concatenate([V, V + [0.7, 0, 0]])  # two spheres: 5124 vertices
    F = np.concatenate([F, F + len(m.vertices)])
    t64 = get_topology(V, F, dtype=torch.float64, cache=False)
    t32 = get_topology(V, F, dtype=torch.float32, cache=False)
    rng = np.random.default_rng(0)
    x = torch.as_tensor(V * [1.05, 0.98, 1.0] + 0.002 * rng.normal(size=V.shape))
    fns = {**ALL, "bending_template": lambda x, t: bending_energy(x, t, MAT, "template")}
    for name, fn in fns.items():
        a, b = fn(x[None], t64), fn(x.float()[None], t32)
        assert b.dtype == torch.float32 and np.isclose(a.item(), b.item(), rtol=2e-3), name


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
    from drapebench.geometry.proximity import nearest_body_vertex

    near = nearest_body_vertex(x, body, normals)  # a query the caller already has is used as it is
    assert torch.equal(energy_terms(x, topo, MAT, near=near)["collision"], t["collision"])
    near.normal = -near.normal
    assert not torch.equal(energy_terms(x, topo, MAT, near=near)["collision"], t["collision"])


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
            p, n = torch.zeros_like(y), torch.nn.functional.normalize(torch.ones_like(y), dim=-1)
            e = (stvk_energy(y, t, MAT) + bending_energy(y, t, MAT, "template") + inextensibility_energy(y, t)
                 + bending_energy(y, t, MAT, blend=torch.rand(len(t.hinge_edges), dtype=dtype), scale="current")
                 + laplacian_smoothness(y, t) + laplacian_smoothness(y, t, squared=True)
                 + restrain_energy(y, t, 0.0, 1e-3) + gravity_energy(y, t, MAT) + pin_energy(y, V[:2].to(dtype), torch.arange(2))
                 + inertia_energy(y, V.to(dtype), torch.zeros_like(y), t, MAT)
                 + collision_energy(y, p, n) + hinge_collision_energy(y, p, n))  # fmt: skip
            e.sum().backward()
            assert torch.isfinite(e).all() and torch.isfinite(y.grad).all(), (name, dtype)
    report = validate_mesh_state(cases["collapsed"], topo)
    assert not report.ok and report.collapsed_edges and report.degenerate_faces
    assert validate_mesh_state(cases["folded"], topo).folded_hinges
    assert (0, 3) in validate_mesh_state(cases["flipped"], topo).flipped_faces
    assert validate_mesh_state(cases["stretch100"], topo).overstretched_edges
    assert validate_mesh_state(V, topo).ok
    bad = V.clone()
    bad[2, 1] = float("nan")
    assert validate_mesh_state(bad, topo).nonfinite_vertices == [(0, 2)]


def test_collision_by_signed_distance_penalises_points_inside_the_body():
    """With body_faces the collision term is sum max(eps - sd, 0)^3 of the exact signed distance,
    and its gradient pushes inside points outward (away from the sphere's centre)."""
    import trimesh

    from drapebench.geometry import get_topology
    from drapebench.geometry.sdf import signed_distance

    s = trimesh.creation.icosphere(3, radius=0.5)
    BV, BF = torch.as_tensor(s.vertices)[None], torch.as_tensor(s.faces)
    g = trimesh.creation.icosphere(1, radius=0.45)  # a garment just inside the body
    topo = get_topology(g.vertices, g.faces)
    x = torch.as_tensor(g.vertices, dtype=topo.dtype)[None].clone().requires_grad_()
    BV = BV.to(topo.dtype)
    e = energy_terms(x, topo, MAT, body_vertices=BV, body_faces=BF, collision_eps=2e-3)["collision"]
    sd = signed_distance(x.detach(), BV, BF)
    assert (sd < 0).all()
    assert torch.allclose(e, (torch.relu(2e-3 - sd) ** 3).sum(-1))
    e.sum().backward()
    assert ((x.grad * x.detach()).sum(-1) < 0).all()  # descent direction -grad points outward
    with pytest.raises(ValueError, match="body_normals .* or body_faces"):
        energy_terms(x.detach(), topo, MAT, body_vertices=BV)


def test_collision_by_signed_distance_measures_depth_on_the_outer_surface():
    """A sphere body with a part buried in it (radius 0.15): points at radius 0.3 are 0.2 m deep below
    the outer surface, 0.15 m from the buried part; with body_outer_faces the penalty uses 0.2."""
    from drapebench.geometry.outer_surface import outer_faces

    outer, buried = trimesh.creation.icosphere(3, radius=0.5), trimesh.creation.icosphere(2, radius=0.15)
    BV = torch.as_tensor(np.concatenate([outer.vertices, buried.vertices]))[None]
    BF = torch.as_tensor(np.concatenate([outer.faces, buried.faces + len(outer.vertices)]))
    g = trimesh.creation.icosphere(1, radius=0.3)
    topo = get_topology(g.vertices, g.faces)
    x, BV = torch.as_tensor(g.vertices, dtype=topo.dtype)[None], BV.to(topo.dtype)
    mask = outer_faces(BV[0], BF)
    e_outer = energy_terms(x, topo, MAT, body_vertices=BV, body_faces=BF, body_outer_faces=mask, collision_eps=0.0)["collision"]
    e_whole = energy_terms(x, topo, MAT, body_vertices=BV, body_faces=BF, collision_eps=0.0)["collision"]
    n = topo.n_vertices
    assert torch.allclose(e_outer, torch.tensor([n * 0.2**3], dtype=topo.dtype), rtol=0.05)
    assert torch.allclose(e_whole, torch.tensor([n * 0.15**3], dtype=topo.dtype), rtol=0.05)
