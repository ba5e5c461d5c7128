"""Each GAPS loss term on its own: its value is the physics energy times its weight, its gradient points
the physical way, and the stop-gradients hold (the checks of tests/terms.py)."""

import pytest
import torch

from drapebench.geometry import get_topology
from drapebench.geometry.proximity import nearest_body_vertex
from drapebench.physics import (
    Material,
    bending_energy,
    collision_aware_kext,
    collision_energy,
    gravity_energy,
    inertia_energy,
    inextensibility_energy,
    stvk_energy,
)
from methods.gaps import losses
from methods.gaps.config import gaps_params
from tests.meshes import grid_mesh
from tests.terms import assert_moves_along, assert_no_gradient_to, assert_weighted, descent

MAT = Material()
B, W = 2, 3
EPS = 2e-3


@pytest.fixture(scope="module")
def sheet():
    V, F = grid_mesh(5, 0.2, noise=0.002)
    return torch.as_tensor(V), get_topology(V, F, dtype=torch.float64, cache=False)


@pytest.fixture(scope="module")
def plane():
    """A 'body' of vertices on z = 0 with normals +z, denser than the sheet and covering it."""
    V, _ = grid_mesh(21, 0.3)
    bv = torch.as_tensor(V) - torch.tensor([0.05, 0.05, 0.0], dtype=torch.float64)
    bv[:, 2] = 0.0
    return bv[None], torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64).expand_as(bv)[None]


def frames(rest, seed=0):
    """(B*W, V, 3) jittered copies of the rest sheet lifted 5 cm above z = 0."""
    g = torch.Generator().manual_seed(seed)
    x = rest[None] + 3e-3 * torch.randn(B * W, *rest.shape, generator=g, dtype=rest.dtype)
    return x + torch.tensor([0.0, 0.0, 0.05], dtype=rest.dtype)


def near(x, plane):
    bv, bn = plane
    return nearest_body_vertex(x, bv, bn)


def test_each_term_is_its_physics_energy_times_its_weight(sheet, plane):
    rest, topo = sheet
    x = frames(rest)
    x[:, ::3, 2] -= 0.06  # a third of the vertices 1 cm inside the plane: the collision term is not zero
    blend = torch.linspace(0, 1, topo.hinge_edges.shape[0], dtype=x.dtype)
    assert_weighted(lambda y: losses.strain(y, topo, MAT, B), x, lambda y: stvk_energy(y, topo, MAT), 1.0, B)
    for mode, kw in (("flat", {}), ("template", {"rest_angle": "template"}), ("blend", {"blend": blend})):
        for scale in ("edge", "rest"):
            assert_weighted(lambda y: losses.bending(y, topo, MAT, B, mode, blend, scale), x,
                            lambda y: bending_energy(y, topo, MAT, scale=scale, **kw), 1.0, B)  # fmt: skip
    assert_weighted(lambda y: losses.gravity(y, topo, MAT, B), x, lambda y: gravity_energy(y, topo, MAT), 1.0, B)
    nn = near(x, plane)
    assert (nn.distance < EPS).any()
    assert_weighted(lambda y: losses.collision(y, nn, B, 250.0, EPS), x, lambda y: collision_energy(y, nn.point, nn.normal, EPS), 250.0, B)
    k = losses.extension_factor(nn.distance, 2, "collision", EPS, 3)  # two thirds of the way: the paper's epoch 66.7
    assert torch.allclose(k, collision_aware_kext(nn.distance, 200 / 3, EPS, ramp_epochs=100)) and k.max() > 1.0
    deep = nn.distance < EPS - 3e-3  # d_c past 0.03 / 10: k_ext at the paper's cap, 4, once the ramp is over
    assert deep.any() and torch.allclose(losses.extension_factor(nn.distance, 5, "collision", EPS, 3)[deep], torch.tensor(4.0, dtype=x.dtype))
    assert torch.equal(losses.extension_factor(nn.distance, 2, "one", EPS, 3), torch.ones(1, dtype=x.dtype))
    assert_weighted(lambda y: losses.inextensibility(y, topo, k, B, 2e8), x, lambda y: inextensibility_energy(y, topo, k), 2e8, B)
    xw = x.reshape(B, W, *rest.shape)
    x1, x0 = xw[:, 1], xw[:, 0]
    assert_weighted(lambda y: losses.inertia(y, topo, MAT), xw, lambda y: inertia_energy(y[:, 2], x1, (x1 - x0) / MAT.dt, topo, MAT), 1.0, B)


def test_loss_terms_assembles_the_terms_of_the_parameters(sheet, plane):
    rest, topo = sheet
    x = frames(rest, seed=1)
    nn = near(x, plane)
    blend = torch.linspace(0, 1, topo.hinge_edges.shape[0], dtype=x.dtype)
    p = gaps_params({"train": {"kext_ramp_epochs": 3}})
    assert p["normalisation"] == "code"
    terms, k = losses.loss_terms(x, W, nn, topo, MAT, p, 1, blend)
    assert list(terms) == ["strain", "bending", "gravity", "collision", "inertia", "inext"]
    # the public code: per-frame terms over the B x W frames, collision and inertia over the B windows
    assert torch.equal(terms["collision"], losses.collision(x, nn, B, p["collision_weight"], EPS))
    assert torch.equal(terms["inertia"], losses.inertia(x.reshape(B, W, *x.shape[1:]), topo, MAT))
    assert torch.equal(terms["inext"], losses.inextensibility(x, topo, k, B * W, p["inextensibility_weight"]))
    assert torch.equal(terms["bending"], losses.bending(x, topo, MAT, B * W, "blend", blend))
    for name in ("strain", "gravity"):
        assert torch.equal(terms[name], getattr(losses, name)(x, topo, MAT, B * W))
    per_batch, _ = losses.loss_terms(x, W, nn, topo, MAT, {**p, "normalisation": "batch"}, 1, blend)
    for name in terms:
        ratio = W if name in ("strain", "bending", "gravity", "inext") else 1
        assert torch.allclose(per_batch[name], ratio * terms[name]), name
    terms, k = losses.loss_terms(x, W, nn, topo, MAT, gaps_params({"inextensibility_weight": 0.0}), 1, blend)
    assert "inext" not in terms and k is None


def test_collision_pushes_an_inside_vertex_out_along_the_normal(sheet, plane):
    rest, topo = sheet
    x = frames(rest)[:1]  # 5 cm above the plane: no vertex within the margin
    inside = torch.zeros(x.shape[:2], dtype=torch.bool)
    inside[0, 7] = True
    x[inside] -= torch.tensor([0.0, 0.0, 0.06], dtype=x.dtype)  # 1 cm behind the surface
    assert_moves_along(lambda y: losses.collision(y, near(y, plane), 1, 250.0, EPS), x, inside, plane[1][0, :1])


def test_gravity_pulls_every_vertex_down(sheet):
    rest, topo = sheet
    x = frames(rest)
    down = torch.tensor(MAT.gravity, dtype=x.dtype)
    assert down[2] < 0
    assert_moves_along(lambda y: losses.gravity(y, topo, MAT, B), x, torch.ones(x.shape[:2], dtype=torch.bool), down)


def test_strain_pulls_a_stretched_edge_back(sheet):
    rest, topo = sheet
    x = rest.clone()[None]
    pulled = 12  # the centre vertex of the 5 x 5 sheet
    stretch = torch.tensor([0.02, 0.0, 0.0], dtype=x.dtype)
    x[0, pulled] += stretch
    d = descent(lambda y: losses.strain(y, topo, MAT, 1), x)
    cos = torch.nn.functional.cosine_similarity(d[0, pulled], stretch, dim=0)
    assert cos < -0.9, cos  # back towards where it came from


def test_inertia_pulls_the_last_frame_to_its_prediction_and_not_the_earlier_frames(sheet):
    rest, topo = sheet
    xw = frames(rest, seed=2).reshape(B, W, *rest.shape)
    earlier = torch.ones(B, W, dtype=torch.bool)
    earlier[:, -1] = False
    term = lambda y: losses.inertia(y, topo, MAT)  # noqa: E731
    assert_no_gradient_to(term, xw, earlier)
    predicted = 2 * xw[:, 1] - xw[:, 0]  # x1 + dt (x1 - x0) / dt
    toward = torch.zeros_like(xw)
    toward[:, -1] = predicted - xw[:, -1]
    assert_moves_along(term, xw, ~earlier[..., None].expand(B, W, rest.shape[0]), toward)


def test_blend_weight_is_the_signed_distance_along_the_body_normal(plane):
    """GAPS Eq. 12's alpha as the code computes it: a hinge inside the body (below the plane) gets the smallest
    weight of the template angle, one far outside the largest; by the Euclidean distance ("distance", this suite's
    earlier reading) the inside hinge 3 cm deep would rank above the one 2 cm outside."""
    bv, bn = plane[0][0], plane[1][0]
    heights = torch.tensor([0.02, 0.02, -0.03, -0.03, 0.05, 0.05], dtype=bv.dtype)  # three hinges, two ends each
    template = torch.stack([torch.full_like(heights, 0.1), torch.linspace(0.05, 0.15, 6, dtype=bv.dtype), heights], -1)
    nearest = (template[:, None, :2] - bv[None, :, :2]).norm(dim=-1).argmin(1)
    hinges = torch.tensor([[0, 1], [2, 3], [4, 5]])
    alpha = losses.blend_weights(template, bv, bn, nearest, hinges)
    assert torch.allclose(alpha, torch.tensor([0.625, 0.0, 1.0], dtype=bv.dtype))  # (0.02 + 0.03) / (0.05 + 0.03)
    unsigned = losses.blend_weights(template, bv, bn, nearest, hinges, "distance")
    assert unsigned[1] > unsigned[0]  # the old reading orders the inside hinge above the outside one


def test_gaps_defaults_bend_as_the_code():
    """The model's defaults are the code's bending (the deformed edge's length, alpha along the body normal); the
    earlier readings stay reachable and are what a checkpoint without the keys was trained with."""
    from methods.gaps.config import ADDED_KEYS

    p = gaps_params(None)
    assert (p["bending_scale"], p["bending_blend"]) == ("edge", "normal")
    assert (ADDED_KEYS["bending_scale"], ADDED_KEYS["bending_blend"]) == ("rest", "distance")
    assert gaps_params({"bending_scale": "rest", "bending_blend": "distance"})["bending_scale"] == "rest"


def test_k_ext_follows_the_garment_in_the_gradient_as_in_the_code(sheet, plane):
    """k_ext (Eq. 16) is a function of each vertex's body distance; the GAPS code differentiates it through that
    distance, so L_inext's gradient is the derivative of its value with k_ext recomputed where the vertices move
    (a central difference along a random direction). Held constant (``kext_gradient: false``, this suite's earlier
    reading) the gradient misses that part: near the body it would not see that moving into the band raises k_ext."""
    rest, topo = sheet
    g = torch.Generator().manual_seed(3)
    x = rest[None].repeat(W, 1, 1) + 1e-3 * torch.randn(W, *rest.shape, generator=g, dtype=rest.dtype)
    x[..., 2] = -0.8e-3 + 2.6e-3 * torch.rand(x.shape[:2], generator=g, dtype=x.dtype)  # inside the ramp: 0 < 10 d_c < 0.03
    blend = torch.zeros(topo.hinge_edges.shape[0], dtype=x.dtype)
    v = torch.randn(x.shape, generator=g, dtype=x.dtype)
    h = 1e-8

    def inext(y, p):
        return losses.loss_terms(y, W, near(y, plane), topo, MAT, p, 3, blend)[0]["inext"]

    for follows in (True, False):
        p = gaps_params({"train": {"kext_ramp_epochs": 3}, "kext_gradient": follows})
        y = x.clone().requires_grad_(True)
        (grad,) = torch.autograd.grad(inext(y, p), y)
        with torch.no_grad():
            numeric = (inext(x + h * v, p) - inext(x - h * v, p)) / (2 * h)
        analytic = (grad * v).sum()
        if follows:
            assert torch.isclose(analytic, numeric, rtol=1e-4), (float(analytic), float(numeric))
        else:
            assert not torch.isclose(analytic, numeric, rtol=0.05), (float(analytic), float(numeric))
    assert gaps_params(None)["kext_gradient"], "the default follows the code"
