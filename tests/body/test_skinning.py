import torch

from drapebench.body.lbs import inverse_lbs, lbs
from drapebench.body.skinning import nearest_body_vertices, nearest_weights, transfer_shape


def test_body_vertices_bind_to_themselves(body_lowres):
    rest = body_lowres.v_template
    idx = nearest_body_vertices(rest[::7] + 1e-4, body_lowres)
    assert torch.equal(idx, torch.arange(0, len(rest), 7))
    assert torch.allclose(nearest_weights(idx, body_lowres).sum(1), torch.ones(len(idx)), atol=1e-5)


def test_shape_transfer_moves_bound_body_vertices_with_the_body(body_lowres):
    b_from = torch.tensor([0.5, -1.0])
    b_to = torch.tensor([-0.5, 1.0, 0.7])  # another length: zero-padded
    src = body_lowres.shaped(b_from[None])[0][0]
    idx = torch.arange(len(src))
    moved = transfer_shape(src, idx, body_lowres, b_from, b_to)
    assert torch.allclose(moved, body_lowres.shaped(b_to[None])[0][0], atol=1e-5)
    assert torch.equal(transfer_shape(src, idx, body_lowres, b_from, b_from), src)


def test_lbs_keeps_the_root_translation_out_of_the_weights(body_lowres):
    """Every joint's translation is blended relative to the frame's root and the root's added whole: weights whose rows
    do not sum to 1 (learned ones, or float rounding) do not scale the distance travelled, and a body far from the
    origin skins to the body at the origin, moved, to float64's resolution."""
    pose = 0.3 * torch.randn(2, body_lowres.n_joints, 3)
    trans = torch.tensor([[0.0, 0.0, 0.0], [10.0, -3.0, 0.5]])
    out = body_lowres.forward(None, pose[:1].expand(2, -1, -1), trans)
    pts = body_lowres.v_template[:50]
    w = body_lowres.weights[:50]
    drifted = 1.1 * w  # rows sum to 1.1: blending the translations whole would add 10 % of the 10 m travelled
    x = lbs(pts, drifted, out.transforms)
    assert torch.allclose(x[1] - x[0], trans[1].expand(50, 3), atol=1e-4)
    from drapebench.body import load_body

    body64 = load_body("anny_lowres", dtype=torch.float64)
    far = torch.tensor([[30000.123456789, -12000.987654321, 7.0]], dtype=torch.float64)
    w64 = body64.weights[:50] * (1 + 4e-8)  # rows off 1 by float32's rounding
    here = lbs(pts.double(), w64, body64.forward(None, pose[1:].double(), None).transforms)
    there = lbs(pts.double(), w64, body64.forward(None, pose[1:].double(), far).transforms)
    assert (there - far - here).abs().max() < 1e-9  # m; blended whole: 30 km x 4e-8 = 1.2 mm


def test_inverse_lbs_undoes_lbs_away_from_the_origin(body_lowres):
    """The VAE's inverse-skinning projection: a translated, posed frame comes back to the rest points."""
    pose = 0.3 * torch.randn(2, body_lowres.n_joints, 3, generator=torch.Generator().manual_seed(0))
    trans = torch.tensor([[0.0, 0.0, 0.0], [2.0, -1.0, 0.5]])
    A = body_lowres.forward(None, pose, trans).transforms
    pts, w = body_lowres.v_template[:200], body_lowres.weights[:200]
    torch.testing.assert_close(inverse_lbs(lbs(pts, w, A), w, A), pts.expand(2, -1, -1), atol=1e-4, rtol=0)


def test_points_made_on_a_shaped_body_bind_to_that_body(body_lowres):
    """A garment made on a non-mean body binds to the vertices of that body, not of the mean one."""
    betas = torch.tensor([2.0, -2.0, 1.0])
    shaped = body_lowres.shaped(body_lowres.full_betas(betas)[None])[0][0]
    idx = nearest_body_vertices(shaped[::7] + 1e-4, body_lowres, betas)
    assert torch.equal(idx, torch.arange(0, len(shaped), 7))
