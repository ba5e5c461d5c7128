import torch

from drapebench.body.lbs import lbs
from drapebench.body.skinning import nearest_body_vertices, nearest_weights, skin_then_translate, transfer_shape


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


def test_skin_then_translate_keeps_the_translation_out_of_the_weights(body_lowres):
    seq_pose = torch.zeros(2, body_lowres.n_joints, 3)
    trans = torch.tensor([[0.0, 0.0, 0.0], [10.0, -3.0, 0.5]])
    out = body_lowres.forward(None, seq_pose, trans)
    pts = body_lowres.v_template[:50]
    w = body_lowres.weights[:50]
    assert torch.allclose(skin_then_translate(pts, w, out.transforms, trans), lbs(pts, w, out.transforms), atol=1e-5)
    drifted = 1.1 * w  # rows sum to 1.1: plain LBS would scale the 10 m of travel too
    x = skin_then_translate(pts, drifted, out.transforms, trans)
    assert torch.allclose(x[1] - 1.1 * pts, trans[1].expand(50, 3), atol=1e-4)
    assert not torch.allclose(lbs(pts, drifted, out.transforms)[1] - 1.1 * pts, trans[1].expand(50, 3), atol=1e-2)
