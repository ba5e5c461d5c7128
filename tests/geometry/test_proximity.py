import numpy as np
import pytest
import torch
import trimesh
from scipy.spatial import cKDTree

from drapebench.geometry.proximity import body_vertex_tree, culled_body_faces, culled_body_vertices, nearest_body_vertex


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_nearest_body_vertex_matches_brute_force_and_differentiates(dtype):
    g = torch.Generator().manual_seed(1)
    x = torch.randn(3, 200, 3, generator=g, dtype=dtype).requires_grad_(True)
    body = torch.randn(3, 500, 3, generator=g, dtype=dtype)
    normals = torch.nn.functional.normalize(torch.randn(3, 500, 3, generator=g, dtype=dtype), dim=-1)
    nn = nearest_body_vertex(x, body, normals)
    assert torch.equal(nn.index, torch.cdist(x.double(), body.double()).argmin(-1))
    p = body.gather(1, nn.index[..., None].expand(-1, -1, 3))
    assert nn.distance.dtype == dtype and torch.allclose(nn.point, p)
    assert torch.allclose(nn.distance, ((x - p) * normals.gather(1, nn.index[..., None].expand(-1, -1, 3))).sum(-1))
    nn.distance.sum().backward()
    assert torch.allclose(x.grad, nn.normal)  # d(n . (x - p))/dx = n
    shared = nearest_body_vertex(x, body[:1], normals[:1])  # one body frame for the whole batch
    assert torch.equal(shared.index, torch.cdist(x.double(), body[:1].double()).argmin(-1))
    cand = torch.arange(0, 500, 3)
    sub = nearest_body_vertex(x, body, normals, cand)
    assert torch.equal(sub.index, cand[torch.cdist(x.double(), body[:, cand].double()).argmin(-1)])


def test_frames_split_over_threads_each_search_their_own_body(monkeypatch):
    """The KD-tree path hands frames to torch's threads: each frame is answered against its own body."""
    g = torch.Generator().manual_seed(5)
    x = torch.randn(5, 300, 3, generator=g)
    body = torch.randn(5, 400, 3, generator=g) + torch.arange(5.0)[:, None, None]
    normals = torch.nn.functional.normalize(torch.randn(5, 400, 3, generator=g), dim=-1)
    monkeypatch.setattr(torch, "get_num_threads", lambda: 3)
    split = nearest_body_vertex(x, body, normals)
    assert torch.equal(split.index, torch.cdist(x.double(), body.double()).argmin(-1))


def test_a_prebuilt_tree_gives_the_same_answers_and_is_only_for_one_body_frame():
    g = torch.Generator().manual_seed(2)
    x = torch.randn(2, 100, 3, generator=g, dtype=torch.float64)
    body = torch.randn(1, 400, 3, generator=g, dtype=torch.float64)
    normals = torch.nn.functional.normalize(torch.randn(1, 400, 3, generator=g, dtype=torch.float64), dim=-1)
    cand = torch.arange(1, 400, 2)
    for c in (None, cand):
        tree = body_vertex_tree(body[0], c)
        assert torch.equal(nearest_body_vertex(x, body, normals, c, tree).index, nearest_body_vertex(x, body, normals, c).index)
    with pytest.raises(ValueError, match="one body frame"):
        nearest_body_vertex(x, body.expand(2, -1, -1).clone(), normals.expand(2, -1, -1).clone(), tree=body_vertex_tree(body[0]))


def test_bad_inputs_are_named():
    body, normals = torch.randn(1, 10, 3), torch.randn(1, 10, 3)
    with pytest.raises(ValueError, match="NaN/Inf"):
        nearest_body_vertex(torch.full((1, 4, 3), float("nan")), body, normals)
    with pytest.raises(ValueError, match="body_vertices"):
        nearest_body_vertex(torch.zeros(2, 4, 3), torch.randn(3, 10, 3), torch.randn(3, 10, 3))
    with pytest.raises(ValueError, match="candidates"):
        nearest_body_vertex(torch.zeros(1, 4, 3), body, normals, torch.tensor([3, 12]))


def _skinned_garment(kind, body, motion, n_frames=12):
    from drapebench.body import make_sequence
    from drapebench.body.lbs import lbs
    from drapebench.garments import make_garment

    g = make_garment(kind, body)
    seq = make_sequence(motion, n_frames, seed=2)
    idx = torch.as_tensor(cKDTree(body.v_template.numpy()).query(g.vertices.numpy())[1])
    x = lbs(g.vertices, body.weights[idx], seq.transforms(body))
    return g, seq, x + 0.005 * torch.randn_like(x)


@pytest.mark.parametrize("kind,motion", [("skirt", "kick"), ("tshirt", "arm_raise")])
def test_vertex_culling_gives_the_same_answers_on_a_posed_sequence(body_lowres, kind, motion):
    body = body_lowres
    g, seq, x = _skinned_garment(kind, body, motion)
    bv, bn = seq.vertices(body), seq.vertex_normals(body)
    cand = culled_body_vertices(g.vertices, body.v_template, body.weights)
    assert len(cand) < 0.8 * body.n_vertices
    assert torch.equal(nearest_body_vertex(x, bv, bn, cand).index, nearest_body_vertex(x, bv, bn).index)
    assert len(culled_body_faces(body.faces, cand)) < body.faces.shape[0]


def test_a_skirt_never_looks_at_the_head_or_the_arms(body_lowres):
    from drapebench.garments import make_garment

    body = body_lowres
    cand = culled_body_vertices(make_garment("skirt", body).vertices, body.v_template, body.weights)
    dominant = body.weights[cand].argmax(1)
    far = [body.joint_index(n) for n in ("head", "neck") + tuple(f"{s}_{p}" for s in ("left", "right")
                                                                 for p in ("collar", "shoulder", "elbow", "wrist"))]  # fmt: skip
    assert not torch.isin(dominant, torch.tensor(far)).any()
    legs = body.weights[:, [body.joint_index("left_knee"), body.joint_index("right_knee")]].sum(1) > 0.5
    assert torch.isin(torch.nonzero(legs).squeeze(1), cand).all()


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs CUDA")
def test_gpu_path_matches_cpu():
    mesh = trimesh.creation.torus(0.3, 0.1, 24, 12)
    V, F = torch.as_tensor(mesh.vertices)[None], torch.as_tensor(mesh.faces)
    p = torch.randn(2, 500, 3, dtype=torch.float64) * 0.3
    normals = torch.nn.functional.normalize(V, dim=-1)
    cpu = nearest_body_vertex(p, V, normals)
    gpu = nearest_body_vertex(p.cuda(), V.cuda(), normals.cuda())
    assert torch.equal(cpu.index, gpu.index.cpu())


def test_negative_candidate_indices_are_refused():
    body, normals = torch.randn(1, 10, 3), torch.randn(1, 10, 3)
    with pytest.raises(ValueError, match="candidates"):
        nearest_body_vertex(torch.zeros(1, 4, 3), body, normals, torch.tensor([-1, 3]))
    with pytest.raises(ValueError, match="candidates"):
        body_vertex_tree(body[0], torch.tensor([-2, 0, 1]))
