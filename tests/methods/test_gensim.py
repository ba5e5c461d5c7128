"""GenSim: the ARAP stage (Alg. 1-2), the PEN direction (Eq. 1), each loss term (Eq. 2-8), state round trip."""

import math

import numpy as np

import pytest
import torch

import methods
from drapebench.geometry.ops import vertex_normals
from drapebench.geometry.sdf import inside_body
from drapebench.physics import Material
from methods.gensim import losses
from methods.gensim.arap import ArapConfig, bind, front_aligned, handle_targets, motion_aware_arap, neighbour_mean, skinned_template
from methods.gensim.config import ADDED_KEYS
from methods.gensim.network import PEN, displacement_direction, local_frame_displacement, tangent_basis
from drapebench.geometry.topology import get_topology
from tests.meshes import grid_mesh


def _sheet(n, size):
    """A flat n x n grid: vertices (V, 3) float32 tensor and its Topology."""
    V, F = grid_mesh(n, size)
    return torch.as_tensor(V, dtype=torch.float32), get_topology(V.astype("float32"), F)


def _one_leg_case():
    """A 'leg' body vertex at the origin moving +x by 10 cm, a static one far away; garment vertices in
    front of the leg (+x), behind it (-x), beside it (+y), and a pin at the static vertex."""
    canonical = torch.tensor([[0.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    target = canonical + torch.tensor([[0.1, 0.0, 0.0], [0.0, 0.0, 0.0]])
    normals = torch.tensor([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    template = torch.tensor([[0.05, 0.0, 0.0], [-0.05, 0.0, 0.0], [0.0, 0.05, 0.0], [0.0, 0.0, 1.02]])
    return canonical, target, normals, template, torch.tensor([3])


@pytest.mark.parametrize("side, handle", [("pushed", 0), ("printed", 1)])
def test_handles_and_targets_follow_alg2(side, handle):
    canonical, target, normals, template, pins = _one_leg_case()
    b = bind(template, canonical, pins)
    skinned = template.clone()  # pins where the skinning puts them: here, unmoved
    H, T, d = handle_targets(b, template, canonical, target, normals, skinned, ArapConfig(handle_side=side))
    expected = torch.zeros(4, dtype=torch.bool)
    expected[[handle, 3]] = True  # the handle on the chosen side of the moving leg, and the pin
    assert torch.equal(H, expected)
    # Alg. 2 line 8: G~ = G + d_hat (|d| - q): the handle lands on the moved body vertex (u is along d)
    assert torch.allclose(T[handle], target[0], atol=1e-6)
    assert torch.allclose(d[2], torch.tensor([0.1, 0.0, 0.0]))
    assert torch.equal(T[3], skinned[3])


def test_a_vertex_the_moving_part_does_not_reach_is_no_handle():
    canonical, target, normals, template, pins = _one_leg_case()
    template[0, 0] = 0.2  # 20 cm in front of the leg, which moves 10 cm: |d| - q < 0
    b = bind(template, canonical, pins)
    H, _, _ = handle_targets(b, template, canonical, target, normals, template, ArapConfig())
    assert not H[0] and H[3]


def test_pin_rule_normal_keeps_the_offset_along_the_target_normal():
    canonical, target, normals, template, pins = _one_leg_case()
    b = bind(template, canonical, pins)
    _, T, _ = handle_targets(b, template, canonical, target, normals, template, ArapConfig(pin_rule="normal"))
    assert torch.allclose(T[3], target[1] + normals[1] * 0.02, atol=1e-6)


def test_neighbour_mean_averages_over_the_masked_neighbours_only():
    values = torch.tensor([[0.0, 0, 0], [3.0, 0, 0], [6.0, 0, 0], [9.0, 0, 0]])
    edges = torch.tensor([[0, 1], [1, 2], [2, 3]])
    mask = torch.tensor([True, True, True, False])
    out = neighbour_mean(values, edges, mask)
    assert torch.allclose(out[:, 0], torch.tensor([1.5, 3.0, 4.5, 9.0]))  # vertex 3 is outside: kept, and not averaged in


def test_arap_without_body_motion_returns_the_template(body_lowres):
    from drapebench.garments import make_garment

    g = make_garment("skirt", body_lowres)
    canonical = body_lowres.shaped(g.betas[None])[0][0]
    b = bind(g.vertices, canonical, g.pins)
    pose = torch.zeros(1, body_lowres.n_joints, 3)
    verts, transforms = front_aligned(body_lowres, g.betas, pose)
    normals = vertex_normals(verts, body_lowres.faces)
    pins_at = skinned_template(g.vertices, b, body_lowres, g.betas, g.betas, transforms)
    cfg = ArapConfig()
    H, T, _ = handle_targets(b, g.vertices, canonical, verts[0], normals[0], pins_at[0], cfg)
    assert torch.equal(H, b.pin)  # no motion: the pins are the only handles
    x = motion_aware_arap(g.vertices, g.faces, H, T, verts[0], normals[0], cfg)
    # within 0.5 mm: the few template vertices behind their nearest body vertex's tangent plane are pushed out
    assert (x - g.vertices).norm(dim=-1).max() < 5e-4
    assert (x - g.vertices).norm(dim=-1).median() < 1e-5


def test_the_pins_follow_the_frames_body_shape(body_lowres):
    """Pin rule "skinned": the template's pins move from the garment's body shape to the frame's (then are posed);
    at the rest pose they sit where the body's shape change carries them."""
    from drapebench.body.skinning import transfer_shape
    from drapebench.garments import make_garment

    g = make_garment("skirt", body_lowres, resolution=0.03)
    b = bind(g.vertices, body_lowres.shaped(g.betas[None])[0][0], g.pins)
    other = torch.tensor([2.0, -1.5])
    _, transforms = front_aligned(body_lowres, other, torch.zeros(1, body_lowres.n_joints, 3))
    pins_at = skinned_template(g.vertices, b, body_lowres, g.betas, other, transforms)[0]
    moved = transfer_shape(g.vertices, b.nu, body_lowres, g.betas, other)
    assert (moved - g.vertices).norm(dim=-1).max() > 5e-3  # the shape change moves them
    torch.testing.assert_close(pins_at, moved, atol=1e-5, rtol=0)


def test_front_alignment_removes_the_root_motion(body_lowres):
    pose = torch.zeros(2, body_lowres.n_joints, 3)
    pose[1, 0] = torch.tensor([0.0, 0.0, 1.2])  # the whole body turned about Z
    pose[:, 7] = torch.tensor([0.4, 0.0, 0.0])
    verts, _ = front_aligned(body_lowres, torch.zeros(body_lowres.n_betas), pose)
    assert torch.allclose(verts[0], verts[1], atol=1e-5)
    world = body_lowres.forward(None, pose, torch.tensor([[0.0, 0, 0], [1.0, 2.0, 0.0]]))
    root = world.transforms[:, 0]
    assert torch.allclose(verts @ root[:, :3, :3].transpose(1, 2) + root[:, None, :3, 3], world.vertices, atol=1e-5)


def _random_normals(n=5000):
    nrm = torch.randn(n, 3)
    nrm[:200, 2] = 0.0  # body sides: normals with n3 = 0
    nrm[200:210] = torch.tensor([0.0, 0.0, -1.0])
    return nrm / nrm.norm(dim=-1, keepdim=True)


def test_tangent_direction_lies_in_the_normal_half_space_for_any_input():
    n = _random_normals()
    b1, b2, rho = torch.randn(3, len(n)) * 3
    rho = torch.tanh(rho)
    rho[:20] = 0.0
    D = displacement_direction(b1, b2, rho, n, "tangent")
    assert torch.isfinite(D).all()
    assert torch.allclose(D.norm(dim=-1), torch.ones(len(n)), atol=1e-5)
    assert ((D * n).sum(-1) >= -1e-6).all()
    t1, t2 = tangent_basis(n)
    assert (t1 * n).sum(-1).abs().max() < 1e-5 and (t2 * n).sum(-1).abs().max() < 1e-5


def test_paper_direction_breaks_where_n3_is_zero():
    n = _random_normals()
    b1, b2, rho = torch.randn(3, len(n))
    D = displacement_direction(b1, b2, torch.tanh(rho), n, "paper")
    bad = ~torch.isfinite(D).all(-1)
    assert bad[:200].all() and not bad[210:].any()
    assert ((D[~bad] * n[~bad]).sum(-1) >= -1e-6).all()


def _tiny_pen_inputs(decoder, decoder_init="default", normal_part="abs"):
    verts, topo = _sheet(6, 0.1)
    V = len(verts)
    e = topo.edges
    senders, receivers = torch.cat([e[:, 0], e[:, 1]]), torch.cat([e[:, 1], e[:, 0]])
    torch.manual_seed(0)
    net = PEN(latent=16, geometry=8, steps=2, decoder=decoder, decoder_init=decoder_init, normal_part=normal_part)
    normal = torch.nn.functional.normalize(torch.randn(2, V, 3), dim=-1)
    inputs = (torch.randn(2, V, PEN.N_NODE), torch.randn(2, len(senders), PEN.N_EDGE), senders, receivers, verts,
              torch.randn(1, 30, 3), torch.randint(0, 30, (2, V)), normal)  # fmt: skip
    return net, inputs, normal


@pytest.mark.parametrize("decoder", ["local", "eq1"])
def test_pen_output_moves_outward_or_along_the_body(decoder):
    net, inputs, normal = _tiny_pen_inputs(decoder)
    delta, (_, _, _, w) = net(*inputs)
    assert delta.shape == normal.shape and torch.isfinite(delta).all()
    assert ((delta * normal).sum(-1) >= -1e-7).all() and (w >= 0).all()  # Eq. 1's half-space


def test_local_decoder_leaves_zero_and_every_direction_is_learnable():
    net, inputs, normal = _tiny_pen_inputs("local")
    delta, _ = net(*inputs)
    assert delta.norm(dim=-1).mean() > 1e-4  # not stuck at zero displacement: mm at initialisation
    tangential = delta - (delta * normal).sum(-1, keepdim=True) * normal
    assert tangential.norm(dim=-1).mean() > 1e-4
    target = torch.randn_like(delta)  # any direction: the output layer's gradient is not vanishing
    ((delta - target) ** 2).sum().backward()
    assert net.decoder[-1].weight.grad.abs().sum() > 1e-3
    assert torch.isclose(delta, net(*inputs, geometry=net.encode_geometry(inputs[4], inputs[5]))[0]).all()  # geometry encoded once


def test_zero_initialised_local_decoder_starts_at_the_normal_offset_and_learns():
    net, inputs, normal = _tiny_pen_inputs("local", "zero", "softplus")
    delta, _ = net(*inputs)
    offset = 0.01 * torch.log(torch.tensor(2.0)) / 100  # scale x softplus(0) with sharpness 100, along the normal
    assert torch.allclose(delta, offset * normal, atol=1e-9)
    ((delta - torch.randn_like(delta)) ** 2).sum().backward()
    assert net.decoder[-1].weight.grad.abs().sum() > 1e-3  # the zero layer has a gradient: it leaves zero
    with pytest.raises(ValueError, match="decoder_init"):
        PEN(decoder_init="small")
    with pytest.raises(ValueError, match="no gradient"):  # |a| at a = 0: the normal coefficient could never leave it
        PEN(decoder_init="zero", normal_part="abs")


def test_abs_normal_part_keeps_its_gradient_where_softplus_loses_it():
    n = _random_normals(100)
    a = torch.full((100,), -1.0, requires_grad=True)  # a trained PEN's normal coefficient sat at -1.0 to -1.7
    b, c = torch.randn(2, 100)
    grads = {}
    for mode in ("abs", "softplus", "relu", "square"):
        delta = local_frame_displacement(a, b, c, n, 0.01, normal_part=mode)
        assert ((delta * n).sum(-1) >= -1e-7).all()  # Eq. 1's half-space in every reading
        (g,) = torch.autograd.grad((delta * n).sum(), a)
        grads[mode] = g.abs().mean()
        if mode == "relu":  # exactly no normal move for a <= 0, the rest tangential
            assert (delta * n).sum(-1).abs().max() < 1e-7  # up to the tangent basis's rounding
    assert grads["abs"] > 1e-3 and grads["square"] > 1e-3  # below 0: a way back to pushing outward
    assert grads["softplus"] < 1e-30 and grads["relu"] == 0  # below 0: none
    with pytest.raises(ValueError, match="normal_part"):
        local_frame_displacement(a, b, c, n, 0.01, normal_part="cube")


def test_square_normal_part_turns_noise_around_zero_into_less_outward_push_than_abs():
    n = _random_normals(4000)
    a = 0.1 * torch.randn(4000, generator=torch.Generator().manual_seed(0))  # a coefficient that should be 0, with noise
    b = c = torch.zeros(4000)
    push = {mode: (local_frame_displacement(a, b, c, n, 0.01, normal_part=mode) * n).sum(-1).mean() for mode in ("abs", "square")}
    assert push["abs"] == pytest.approx(0.01 * 0.1 * (2 / torch.pi) ** 0.5, rel=0.05)  # |a|: the noise's spread, outward
    assert push["square"] == pytest.approx(0.01 * 0.1**2, rel=0.1)  # a^2: its variance, ten times less here


def test_input_norm_standardises_pens_inputs_with_the_stored_statistics():
    net, inputs, _ = _tiny_pen_inputs("local")
    normed = PEN(latent=16, geometry=8, steps=2, decoder="local", input_norm=True)
    normed.load_state_dict({**net.state_dict(), **{k: v for k, v in normed.state_dict().items() if k.endswith(("_mean", "_std"))}})
    node, edge = inputs[0], inputs[1]
    stats = node.flatten(0, 1).mean(0), node.flatten(0, 1).std(0), edge.flatten(0, 1).mean(0), edge.flatten(0, 1).std(0)
    normed.set_input_statistics(*stats)
    standardised = ((node - stats[0]) / stats[1], (edge - stats[2]) / stats[3], *inputs[2:])
    assert torch.allclose(normed(*inputs)[0], net(*standardised)[0], atol=1e-6)
    assert not torch.allclose(normed(*inputs)[0], net(*inputs)[0], atol=1e-6)
    assert "node_std" in normed.state_dict() and "node_std" not in net.state_dict()  # saved with the weights
    with pytest.raises(ValueError, match="without input_norm"):
        net.set_input_statistics(*stats)


# ---------------------------------------------------------------------- losses against hand computations
def test_restrain_term_as_printed_and_as_configured():
    verts, topo = _sheet(2, 1.0)  # unit square, 5 edges
    x = verts.clone()
    x[1, 0] += 0.1  # vertex 1 moves out along x: the edges at it change
    phi = ((x[topo.edges[:, 0]] - x[topo.edges[:, 1]]).norm(dim=-1) - topo.rest_edge_lengths).abs()
    printed = (((phi - 0.01) / 0.02) ** 2).sum() * 7.0
    assert torch.allclose(losses.restrain(x[None], topo, 0.01, 0.02, 7.0, "sum", "printed", None), printed)
    z = (phi - 0.01).clamp_min(0) / 0.02
    assert torch.allclose(losses.restrain(x[None], topo, 0.01, 0.02, 7.0, "mean", "dead_zone", None), (z**2).mean() * 7.0)
    plain = ((phi / 0.02) ** 2).mean() * 7.0
    assert torch.allclose(losses.restrain(x[None], topo, 0.01, 0.02, 7.0, "mean", "none", None), plain)
    h = 2.0  # beyond h sigmas the square goes on linearly: 2 h z - h^2
    robust = torch.where(z <= h, z**2, 2 * h * z - h * h).mean() * 7.0
    assert torch.allclose(losses.restrain(x[None], topo, 0.01, 0.02, 7.0, "mean", "dead_zone", h), robust)


def test_restrain_dead_zone_makes_the_rest_length_a_minimum_and_pulls_a_stretched_edge_back():
    verts, topo = _sheet(3, 0.1)
    at_rest = verts[None]
    assert losses.restrain(at_rest, topo, 1e-3, 2e-3, 1.0) == 0  # printed: > 0 at rest, smallest at |dl| = mu
    assert losses.restrain(at_rest, topo, 1e-3, 2e-3, 1.0, offset="printed") > 0
    x = at_rest.clone()
    x[0, -1, 0] += 0.01  # stretch the corner vertex 10 mm outward
    x.requires_grad_(True)
    value = losses.restrain(x, topo, 1e-3, 2e-3, 1.0)
    value.backward()
    assert value > 0 and x.grad[0, -1, 0] > 0  # descent moves it back


def test_pin_term_and_its_gradient():
    x = torch.zeros(1, 4, 3, requires_grad=True)
    G = torch.ones(1, 4, 3)
    value = losses.pin(x, G, torch.tensor([1, 2]), 100.0)
    assert torch.isclose(value, torch.tensor(100.0 * 2 * 3))
    value.backward()
    assert torch.equal(x.grad[0, [0, 3]], torch.zeros(2, 3))
    assert (x.grad[0, [1, 2]] < 0).all()  # the pins are pulled toward G


def test_potential_term_pulls_free_vertices_down_only():
    verts, topo = _sheet(3, 0.1)
    mat = Material()
    x = verts.clone()[None].requires_grad_(True)
    free = torch.ones(len(verts), dtype=torch.bool)
    free[0] = False
    value = losses.potential(x, topo, mat, free, 100.0)
    m = topo.vertex_masses(mat)
    assert torch.isclose(value, 100.0 * 9.81 * (m * x[0, :, 2])[free].sum(), rtol=1e-5)
    value.backward()
    assert x.grad[0, 0].abs().max() == 0 and (x.grad[0, 1:, 2] > 0).all()  # descent moves z down


def test_collision_term_pushes_an_inside_vertex_out_along_the_normal():
    body = torch.tensor([[[0.0, 0.0, 0.0], [5.0, 5.0, 5.0]]])
    normals = torch.tensor([[[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]]])
    x = torch.tensor([[[0.1, 0.0, -0.01]]], requires_grad=True)  # 1 cm inside, below the normal's plane
    value = losses.collision(x, body, normals, 0.003, 100.0)
    assert torch.isclose(value, torch.tensor(100.0 * (0.003 + 0.01)))
    value.backward()
    assert x.grad[0, 0, 2] < 0 and x.grad[0, 0, :2].abs().max() == 0  # descent = +z, out along n
    outside = torch.tensor([[[0.1, 0.0, 0.05]]])
    assert losses.collision(outside, body, normals, 0.003, 100.0) == 0


def _cube():
    """A closed, outward-oriented cube [-1, 1]^3 (8 vertices, 12 faces) with its vertex normals: a coarse body
    whose nearest vertex (a corner) says little about a point near the middle of a face."""
    v = torch.tensor([[x, y, z] for x in (-1.0, 1.0) for y in (-1.0, 1.0) for z in (-1.0, 1.0)])
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]  # -x, +x, -y, +y, -z, +z
    f = torch.tensor([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))])
    return v, f, vertex_normals(v[None], f)[0]


def test_surface_contact_measures_the_penetration_through_a_face_not_the_nearest_vertex():
    v, f, n = _cube()
    inside = torch.tensor([[[0.0, 0.1, 0.99]]], requires_grad=True)  # 1 cm under the middle of the top face
    outside = torch.tensor([[[0.0, 0.1, 1.01]]])  # 1 cm above it: the nearest corner's tangent plane puts it 1.1 m deep
    value = losses.collision(inside, v[None], n[None], 0.003, 100.0, contact="surface", body_faces=f)
    assert torch.isclose(value, torch.tensor(100.0 * (0.003 + 0.01)), rtol=1e-5)
    value.backward()
    assert inside.grad[0, 0, 2] < 0 and inside.grad[0, 0, :2].abs().max() < 1e-6  # descent: straight up, out of the face
    assert losses.collision(outside, v[None], n[None], 0.003, 100.0, contact="surface", body_faces=f) == 0
    assert losses.collision(outside, v[None], n[None], 0.003, 100.0, contact="vertex") > 50.0  # the proxy, labelled


def test_the_arap_push_moves_an_inside_vertex_onto_the_body_surface():
    v, f, n = _cube()
    template = torch.tensor([[0.0, 0.0, 0.99], [0.1, 0.0, 0.99], [0.0, 0.1, 0.99], [0.1, 0.1, 0.99]])  # 1 cm inside the top face
    faces = torch.tensor([[0, 1, 3], [0, 3, 2]])
    handles = torch.tensor([True, False, False, False])
    cfg = ArapConfig(n_iterations=2, contact="surface")
    x = motion_aware_arap(template, faces, handles, template, v, n, cfg, body_faces=f, outer_faces=torch.ones(len(f), dtype=torch.bool))
    assert torch.allclose(x[1:, 2], torch.ones(3), atol=1e-6)  # onto the face
    assert (x[1:, :2] - template[1:, :2]).abs().max() < 2e-3  # straight up (the ARAP solve keeps the square's shape)
    proxy = motion_aware_arap(template, faces, handles, template, v, n, ArapConfig(n_iterations=2, contact="vertex"))
    assert (proxy[1:, :2] - template[1:, :2]).abs().max() > 0.05  # along the corners' normals
    margin = ArapConfig(n_iterations=2, contact="surface", push_margin=1e-5)
    x = motion_aware_arap(template, faces, handles, template, v, n, margin, body_faces=f, outer_faces=torch.ones(len(f), dtype=torch.bool))
    assert torch.allclose(x[1:, 2], torch.full((3,), 1.0 + 1e-5), atol=1e-7)
    assert not inside_body(x[None, 1:], v[None], f).any()  # beyond float32 rounding: counted outside, as eps_c counts


def test_push_handles_puts_a_handle_target_inside_the_body_on_its_surface():
    """Alg. 2 line 8 can put a handle's target inside the body; with push_handles its target moves onto the
    surface (the free vertices follow), as printed it stays inside."""
    v, f, n = _cube()
    template = torch.tensor([[0.0, 0.0, 1.05], [0.1, 0.0, 1.05], [0.0, 0.1, 1.05], [0.1, 0.1, 1.05]])  # 5 cm above the top face
    faces = torch.tensor([[0, 1, 3], [0, 3, 2]])
    handles = torch.tensor([True, False, False, False])
    targets = template.clone()
    targets[0, 2] = 0.98  # 2 cm inside the top face
    outer = torch.ones(len(f), dtype=torch.bool)
    cfg = ArapConfig(n_iterations=2, contact="surface", push_margin=1e-5)
    printed = motion_aware_arap(template, faces, handles, targets, v, n, cfg, body_faces=f, outer_faces=outer)
    assert inside_body(printed[None, :1], v[None], f).all()  # as printed: the handle is held inside
    pushed = motion_aware_arap(template, faces, handles, targets, v, n, ArapConfig(n_iterations=2, contact="surface", push_margin=1e-5,
                               push_handles=True), body_faces=f, outer_faces=outer)  # fmt: skip
    assert torch.allclose(pushed[0], torch.tensor([0.0, 0.0, 1.0 + 1e-5]), atol=1e-6)  # onto the face, straight up
    assert not inside_body(pushed[None], v[None], f).any()


def test_surface_contact_requeries_only_the_points_that_may_have_crossed_the_surface():
    from drapebench.geometry.sdf import closest_body_point
    from methods.gensim.arap import body_contact

    v, f, n = _cube()
    rng = torch.Generator().manual_seed(0)
    points = (torch.rand(200, 3, generator=rng, dtype=torch.float64) * 2.4 - 1.2).numpy()
    contact = body_contact(v, n, "surface", body_faces=f)
    first, _ = contact(points)
    exact = closest_body_point(torch.from_numpy(points)[None], v[None].double(), f).distance[0].numpy()
    assert abs(first - exact).max() < 1e-9  # the first call measures every point
    moved = points + (torch.rand(200, 3, generator=rng, dtype=torch.float64) - 0.5).numpy() * 0.2
    zeta, _ = contact(moved)
    exact = closest_body_point(torch.from_numpy(moved)[None], v[None].double(), f).distance[0].numpy()
    skipped = np.isinf(zeta)
    assert skipped.sum() > 20 and (exact[skipped] > 0).all()  # the points left alone are all outside
    assert abs(zeta[~skipped] - exact[~skipped]).max() < 1e-9


def test_gensim_rejects_an_unknown_contact():
    with pytest.raises(ValueError, match="contact"):
        methods.get("gensim")({"contact": "nearest"})


def test_bending_and_smoothness_are_zero_on_a_flat_sheet_and_positive_when_folded():
    verts, topo = _sheet(4, 0.3)
    mat = Material()
    flat = verts[None]
    folded = flat.clone()
    folded[0, :, 2] = (folded[0, :, 0] - 0.15).clamp_min(0) * 0.8
    assert losses.bending(flat, topo, mat, 1.0) == 0
    assert losses.bending(folded, topo, mat, 1.0) > 0
    # |L x| is not zero at an open sheet's boundary, but folding adds to it and moving the sheet does not
    assert losses.smoothness(folded, topo, 1.0) > losses.smoothness(flat, topo, 1.0) + 1e-3
    assert torch.isclose(losses.smoothness(flat + 0.3, topo, 1.0), losses.smoothness(flat, topo, 1.0), rtol=1e-4)
    # Eq. 4 carries no stiffness: the value does not depend on the material's bending stiffness
    stiff = Material(bending_multiplier=5000.0)
    assert torch.isclose(losses.bending(folded, topo, stiff, 1.0), losses.bending(folded, topo, mat, 1.0))
    assert math.isfinite(float(losses.bending(folded, topo, mat, 1.0)))


# ---------------------------------------------------------------------- training, drape, state
TINY = {"latent": 16, "geometry": 8, "steps": 2, "fabric_mean": 1e-3, "fabric_std": 2e-3, "arap_steps": 3,
        "train": {"garments": [["skirt", {}]], "seeds": [1], "resolutions": [0.03], "sequences": 1, "n_frames": 20, "frames_per_sequence": 2}}


@pytest.fixture(scope="module")
def trained(body_lowres):
    import methods
    from drapebench.data import TrainData

    m = methods.get("gensim")(TINY)
    report = m.fit(TrainData(body=body_lowres, material=Material()), {"steps": 3, "batch_size": 2, "lr": 1e-3})
    return m, report


def test_fit_logs_every_term_and_a_finite_loss(trained):
    _, report = trained
    assert report.n_steps == 3
    assert set(report.final_losses) >= {"restrain", "bending", "pin", "potential", "smoothness", "collision"}
    assert math.isfinite(report.final_losses["loss"])


def test_one_model_drapes_any_garment_and_round_trips_its_state(trained, body_lowres):
    import methods
    from drapebench.body import make_sequence
    from drapebench.garments import make_garment

    m, _ = trained
    seq = make_sequence("kick", 3, seed=0, transition=2)
    garment = make_garment("shorts", body_lowres, resolution=0.025)  # a kind it never saw
    out = m.drape(garment, seq)
    assert out.vertices.shape == (seq.n_frames, garment.n_vertices, 3) and torch.isfinite(out.vertices).all()
    assert out.extras["arap"].shape == out.vertices.shape and out.extras["handles"][:, garment.pins].all()
    again = methods.get("gensim")(TINY)
    again.bind(body_lowres, Material())
    again.load_state_dict(m.state_dict())
    assert torch.allclose(again.drape(garment, seq).vertices, out.vertices, atol=1e-6)
    with pytest.raises(ValueError, match="trained with"):
        other = methods.get("gensim")({**TINY, "latent": 8})
        other.bind(body_lowres, Material())
        other.load_state_dict(m.state_dict())
    older = {**m.state_dict(), "params": {k: v for k, v in m.state_dict()["params"].items() if k not in ADDED_KEYS}}
    with pytest.raises(ValueError, match="trained with"):  # a checkpoint older than a key: trained with its old behaviour
        again.load_state_dict(older)
    before = methods.get("gensim")({**TINY, **ADDED_KEYS})  # e.g. push_handles false: the handles as printed
    before.bind(body_lowres, Material())
    before.load_state_dict(older)


def test_a_fixed_training_body_makes_one_checkpoint_for_every_run_body(body_lowres):
    import methods
    from drapebench.cache import body_key

    class OtherBody:  # a run body that is not the training body
        dtype, device = torch.float32, torch.device("cpu")

    fixed = methods.get("gensim")({**TINY, "train": {**TINY["train"], "body": "anny_lowres"}})
    assert body_key(fixed.trained_body(OtherBody())) == body_key(body_lowres)  # the checkpoint key's body
    run = OtherBody()
    assert methods.get("gensim")(TINY).trained_body(run) is run  # no train.body: trains on the run's body


def test_diagnostic_term_balance_on_a_small_garment(body_lowres):
    from methods.gensim.diagnose import PRINTED, input_roughness, loss_changes, term_balance, training_frames

    configured = methods_get(TINY)
    configured.bind(body_lowres, Material())
    configured.fabric = configured._fabric()
    graph, G, d, verts, normals = training_frames(configured, "skirt", "random", 2, 3, 0.04)
    printed = methods_get({**TINY, **PRINTED})
    printed.bind(body_lowres, Material())
    printed.fabric = configured.fabric
    rows, rows_printed = (term_balance(m, graph, G, G, verts, normals) for m in (configured, printed))
    assert set(rows) == set(losses.UNSUPERVISED) and all(math.isfinite(v) for r in rows.values() for v in r.values())
    assert rows["potential"]["grad_median"] > 0  # gravity pulls on every free vertex
    # as printed, the restrain's pull on a vertex is (number of edges) times the per-edge mean's or more
    n_edges = len(graph.topology.edges)
    assert rows_printed["restrain"]["grad_median"] > 0.5 * n_edges * rows["restrain"]["grad_median"] > 0
    changes = loss_changes(configured, graph, G, verts, normals)
    assert math.isfinite(changes["noise"]) and math.isfinite(changes["drop"])
    for name in losses.UNSUPERVISED:  # a term of weight 0 is left out of Eq. 9, the others are unchanged
        dropped = methods_get({**TINY, "weights": {name: 0.0}})
        dropped.bind(body_lowres, Material())
        dropped.fabric = configured.fabric
        left = dropped.terms(graph, G, G, verts, normals)
        assert set(left) == set(rows) - {name} and all(torch.isclose(v, torch.tensor(rows[k]["value"])) for k, v in left.items())
    rough = {}
    for query in ("vertex", "surface"):  # the closest surface point moves with the cloth, the nearest vertex jumps
        reading = methods_get({**TINY, "body_query": query})
        reading.bind(body_lowres, Material())
        rough[query] = input_roughness(reading, graph, G, d, verts, normals)
    assert all(0 < v < 1 for r in rough.values() for v in r.values())
    assert rough["surface"]["u"] < 0.5 * rough["vertex"]["u"] and rough["surface"]["v (x - body point)"] < 0.5 * rough["vertex"]["v (x - body point)"]


def test_strain_change_splits_the_change_of_eps_e_by_strain_class():
    from methods.gensim.diagnose import strain_change

    x, topo = _sheet(6, 0.1)
    before = x[None].double()
    after = before * torch.tensor([1.03, 1.0, 1.0], dtype=torch.float64)  # every edge along x 3 % longer
    rows = strain_change(before, after, topo)
    assert rows[0]["share"] == pytest.approx(1.0) and sum(r["share"] for r in rows) == pytest.approx(1.0)
    eps = lambda y: ((torch.linalg.norm(y[:, topo.edges[:, 0]] - y[:, topo.edges[:, 1]], dim=-1) / topo.rest_edge_lengths - 1).abs().mean() * 100)  # noqa: E731
    change = (eps(after) - eps(before)).item()
    assert change > 0 and sum(r["eps_e_change"] for r in rows) == pytest.approx(change, abs=1e-9)
    back = strain_change(after, before, topo)  # from the stretched sheet: its x and diagonal edges are no longer below 1 %
    assert sum(r["eps_e_change"] for r in back) < 0 and back[0]["share"] < 1.0


def test_displacement_parts_separate_an_even_offset_of_a_curved_sheet_from_a_slide():
    """A sheet rolled onto a cylinder of radius R: moving it 2 mm along its normals stretches the edges around
    the cylinder by about 2 mm / R, and that strain is the normal part's; sliding it along the axis strains nothing."""
    from methods.gensim.diagnose import displacement_parts

    flat, topo = _sheet(12, 0.2)
    R = 0.1
    x, y = flat[:, 0].double(), flat[:, 1].double()
    rolled = torch.stack([R * torch.sin(x / R), y, R * torch.cos(x / R)], -1)[None]  # lengths kept up to the chords
    radial = torch.stack([torch.sin(x / R), torch.zeros_like(x), torch.cos(x / R)], -1)[None]
    offset = rolled + 0.002 * radial
    parts = displacement_parts(rolled, offset, topo)
    assert abs(parts["normal_mm"]) == pytest.approx(2.0, rel=0.02)
    assert parts["after"] - parts["before"] > 0.5  # the edges around the cylinder: +2 % each
    added = parts["after"] - parts["before"]  # the grid's vertex normals tilt at its border: most, not all, of it is normal
    assert parts["normal"] - parts["before"] > 0.8 * added and parts["uniform_normal"] - parts["before"] > 0.8 * added
    assert parts["tangential"] - parts["before"] < 0.1 * added
    slide = displacement_parts(rolled, rolled + torch.tensor([0.0, 0.01, 0.0], dtype=torch.float64), topo)
    assert slide["normal_mm"] == pytest.approx(0.0, abs=1e-9) and slide["after"] == pytest.approx(slide["before"], abs=1e-9)
    assert slide["normal"] == pytest.approx(slide["before"], abs=1e-9)


def test_normal_push_by_distance_puts_each_move_in_its_distance_class():
    """A rolled sheet whose half near the body (distance 1 mm) moves 2 mm out and whose far half (30 mm) moves
    1 mm in: each class gets its own mean move along the normals, and the empty classes are NaN."""
    from methods.gensim.diagnose import normal_push_by_distance

    flat, topo = _sheet(12, 0.2)
    R = 0.1
    x, y = flat[:, 0].double(), flat[:, 1].double()
    rolled = torch.stack([R * torch.sin(x / R), y, R * torch.cos(x / R)], -1)[None]
    radial = torch.stack([torch.sin(x / R), torch.zeros_like(x), torch.cos(x / R)], -1)[None]
    near = (y < y.median())[None]
    moved = rolled + torch.where(near[..., None], 0.002, -0.001) * radial
    rows = normal_push_by_distance(rolled, moved, topo, torch.where(near, 1.0, 30.0))
    by_class = {(r["lo"], r["hi"]): r for r in rows}
    assert by_class[(0.0, 3.0)]["normal_mm"] == pytest.approx(2.0, rel=0.05)  # outward where the sheet's normals point out
    assert by_class[(20.0, float("inf"))]["normal_mm"] == pytest.approx(-1.0, rel=0.05)
    assert by_class[(0.0, 3.0)]["share"] + by_class[(20.0, float("inf"))]["share"] == pytest.approx(1.0)
    assert math.isnan(by_class[(3.0, 10.0)]["normal_mm"])


def test_surface_body_query_gives_pen_continuous_body_points_and_outward_normals(body_lowres):
    """body_query "surface": the body point PEN sees moves with the garment (no jumps between the body
    vertices of a coarse body, as the nearest vertex makes), u is the template's offset from the canonical
    surface, and (x - point) . normal is the signed distance (the normal points out, inside or not)."""
    from drapebench.garments import make_garment
    from methods.gensim.method import garment_graph

    garment = make_garment("tshirt", body_lowres, resolution=0.025)
    graph = garment_graph(garment, body_lowres, Material())
    x = graph.template[None]
    body = body_lowres.v_template[None].to(x.dtype)
    normals = vertex_normals(body, body_lowres.faces)
    e = graph.topology.edges
    jump = {}
    for query in ("surface", "vertex"):
        m = methods_get({**TINY, "body_query": query})
        m.bind(body_lowres, Material())
        point, normal = m.body_query(x, body, normals)
        jump[query] = ((point[0, e[:, 0]] - point[0, e[:, 1]]).norm(dim=-1) / (x[0, e[:, 0]] - x[0, e[:, 1]]).norm(dim=-1)).quantile(0.99)
        assert torch.allclose(normal.norm(dim=-1), torch.ones(1), atol=1e-5)
    assert jump["surface"] < 3.0 < jump["vertex"]
    from drapebench.geometry.sdf import signed_distance

    m = methods_get({**TINY, "body_query": "surface"})
    m.bind(body_lowres, Material())
    x = torch.where(torch.arange(len(graph.template))[:, None] % 2 == 0, graph.template - 1.2 * graph.u_surface, graph.template)[None]
    point, normal = m.body_query(x, body, normals)  # half the vertices inside the body
    sd = signed_distance(x, body, body_lowres.faces, outer_faces=body_lowres.outer_faces)
    assert (sd < 0).float().mean() > 0.4 and torch.allclose(((x - point) * normal).sum(-1), sd, atol=1e-5)
    # u_surface ends on the canonical surface, no farther than the nearest body vertex (Alg. 2's u) and nearer on average
    canonical = body_lowres.shaped(graph.betas[None, : body_lowres.n_betas])[0]
    on = signed_distance((graph.template - graph.u_surface)[None], canonical, body_lowres.faces, outer_faces=body_lowres.outer_faces)
    surface_gap, vertex_gap = graph.u_surface.norm(dim=-1), graph.binding.u.norm(dim=-1)
    assert on.abs().max() < 1e-6 and (surface_gap <= vertex_gap + 1e-6).all() and surface_gap.mean() < 0.9 * vertex_gap.mean()


def test_distance_input_adds_the_signed_body_distance_to_pens_node_inputs(body_lowres):
    from drapebench.garments import make_garment
    from drapebench.geometry.sdf import signed_distance
    from methods.gensim.method import garment_graph

    graph = garment_graph(make_garment("skirt", body_lowres, resolution=0.03), body_lowres, Material())
    body = body_lowres.v_template[None].to(graph.template.dtype)
    normals = vertex_normals(body, body_lowres.faces)
    x = graph.template[None] - 0.5 * graph.u_surface[None]  # some vertices inside the body, some out
    d = torch.zeros_like(x)
    nodes = {}
    for flag in (False, True):
        m = methods_get({**TINY, "body_query": "surface", "distance_input": flag})
        m.bind(body_lowres, Material())
        nodes[flag], edge, normal = m.features(graph, x, d, body, normals)
        m.net = m._new_net()
        _, delta = m.pen(graph, x, d, body, normals, torch.zeros(1, body_lowres.n_betas))  # the network takes the extra input
        assert torch.isfinite(delta).all()
    assert nodes[False].shape[-1] == 14 and nodes[True].shape[-1] == 15 and torch.equal(nodes[True][..., :14], nodes[False])
    sd = signed_distance(x, body, body_lowres.faces, outer_faces=body_lowres.outer_faces)
    assert torch.allclose(nodes[True][..., 14], sd, atol=1e-5)


def methods_get(cfg):
    import methods

    return methods.get("gensim")(cfg)


def test_unknown_parameters_are_named():
    import methods

    with pytest.raises(ValueError, match="unknown gensim parameter"):
        methods.get("gensim")({"latnet": 3})
    with pytest.raises(ValueError, match="direction must be one of"):
        methods.get("gensim")({"direction": "sideways"})


def test_training_motions_are_checked_and_cycled_over_the_sequences(body_lowres, monkeypatch):
    for motions in (["kick"], []):  # a held-out motion, or none: refused with the configuration, before any work
        with pytest.raises(ValueError, match="train.motions must name training motions"):
            methods_get({**TINY, "train": {**TINY["train"], "motions": motions}})
    import drapebench.body

    calls, real = [], drapebench.body.make_sequence
    monkeypatch.setattr(drapebench.body, "make_sequence", lambda name, *a, **k: calls.append(name) or real(name, *a, **k))
    m = methods_get({**TINY, "train": {**TINY["train"], "motions": ["walk", "random"], "sequences": 3, "resolutions": [0.03, 0.035]}})
    m.bind(body_lowres, Material())
    m._training_frames(12345)  # a fresh cache (tests/conftest.py): the frames are computed
    assert calls == ["walk", "random", "walk", "random", "walk", "random"]  # the list cycles on from one garment to the next


def test_pen_displacement_is_measured_after_the_transition_and_not_for_the_arap_stage_alone():
    from drapebench.body import make_sequence
    from methods.base import DrapeResult

    seq = make_sequence("walk", 6, seed=0, transition=2)
    arap = torch.zeros(6, 4, 3)
    x = arap.clone()
    x[:2, :, 0] = 1.0  # the transition frames are not counted
    x[2:, 0, 2] = 0.003  # one vertex of four PEN moved 3 mm
    stats = methods.get("gensim")().diagnostics(None, seq, DrapeResult(x, extras={"arap": arap}))
    assert stats["pen_mm"] == pytest.approx(0.75) and stats["pen_max_mm"] == pytest.approx(3.0)
    assert methods.get("gensim")().diagnostics(None, seq, DrapeResult(x, extras={})) == {}


def test_hem_drop_is_the_mean_lowering_of_the_lowest_boundary_loop(body_lowres):
    from drapebench.body import make_sequence
    from drapebench.garments import make_garment
    from methods.base import DrapeResult
    from methods.gensim.method import hem_vertices

    g = make_garment("skirt", body_lowres, resolution=0.03)
    hem = hem_vertices(g)
    assert g.vertices[hem, 2].mean() < g.vertices[:, 2].mean()  # the lower of the skirt's two loops
    seq = make_sequence("walk", 4, seed=0, transition=1)
    arap = g.vertices[None].expand(4, -1, -1).clone()
    x = arap.clone()
    x[:, hem, 2] -= 0.01  # PEN lowers the hem by 10 mm and moves nothing else down
    x[:, :, 0] += 0.002
    stats = methods.get("gensim")().diagnostics(g, seq, DrapeResult(x, extras={"arap": arap}))
    assert stats["hem_drop_mm"] == pytest.approx(10.0, abs=1e-4) and stats["pin_drop_mm"] == pytest.approx(0.0, abs=1e-4)
    x[:, g.pins.long(), 2] -= 0.004  # the waistband 4 mm down: the garment falls
    assert methods.get("gensim")().diagnostics(g, seq, DrapeResult(x, extras={"arap": arap}))["pin_drop_mm"] == pytest.approx(4.0, abs=1e-4)


def test_frames_draped_on_two_threads_are_the_frames_draped_one_by_one_and_bf16_stays_near_fp32(body_lowres):
    from drapebench.body import make_sequence
    from drapebench.garments import make_garment

    g = make_garment("skirt", body_lowres, resolution=0.03)
    seq = make_sequence("kick", 2, seed=0, transition=1)
    out = {}
    for name, params in {"one": {"workers": 1}, "two": {"workers": 2}, "bf16": {"workers": 1, "pen_precision": "bf16"}}.items():
        m = methods.get("gensim")(params)
        m.bind(body_lowres, Material())
        torch.manual_seed(0)
        m.fabric, m.net = {"mean": 4.4e-4, "std": 8.1e-4}, m._new_net()
        out[name] = m.drape(g, seq).vertices
    assert torch.equal(out["one"], out["two"])
    apart = (out["bf16"] - out["one"]).norm(dim=-1)
    assert 0 < apart.mean() < 1e-3  # bf16 arithmetic ran, and moved the drape by well under a millimetre


def test_eq1_weighs_the_normal_by_rho_and_the_tangent_by_one_minus_rho():
    """Eq. 1 (tangent reading): D = |rho| n + (1 - |rho|) s b_hat, b_hat . n = 0, normalised."""
    g = torch.Generator().manual_seed(0)
    n = torch.nn.functional.normalize(torch.randn(50, 3, generator=g), dim=-1)
    b1, b2, rho = torch.randn(50, generator=g), torch.randn(50, generator=g), 2 * torch.rand(50, generator=g) - 1
    D, r = displacement_direction(b1, b2, rho, n, "tangent"), rho.abs()
    torch.testing.assert_close((D * n).sum(-1), r / torch.sqrt(r**2 + (1 - r) ** 2))
