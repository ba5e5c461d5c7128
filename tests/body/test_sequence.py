import h5py
import numpy as np
import pytest
import torch

from drapebench.body import BodySequence, load_body, make_sequence


def test_h5_round_trip_is_exact(tmp_path):
    seq = make_sequence("dance", 40, seed=7, betas=torch.randn(10), amplitude=0.8, split="test")
    seq.save(tmp_path / "s.h5")
    back = BodySequence.load(tmp_path / "s.h5")
    for key in ("betas", "poses", "trans"):
        assert getattr(back, key).dtype == torch.float32
        assert torch.equal(getattr(seq, key), getattr(back, key))
    assert (back.name, back.motion, back.fps, back.seed, back.split, back.n_transition, back.params) == (
        seq.name, seq.motion, seq.fps, seq.seed, seq.split, seq.n_transition, seq.params)  # fmt: skip
    with h5py.File(tmp_path / "s.h5") as f:
        assert f["poses"].dtype == np.float32 and f.attrs["params"] == '{"amplitude": 0.8}'
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.h5"]  # atomic write leaves no temp file


def test_load_rejects_a_file_that_is_not_a_sequence(tmp_path):
    with h5py.File(tmp_path / "x.h5", "w") as f:
        f.create_dataset("poses", data=np.zeros((2, 22, 3), np.float32))
    with pytest.raises(ValueError, match=r"missing \['betas', 'trans'\]"):
        BodySequence.load(tmp_path / "x.h5")


def test_posed_geometry_is_cached_and_consistent(body_lowres):
    seq = make_sequence("walk", 20, seed=0, betas=torch.linspace(-1, 1, 10))
    v = seq.vertices(body_lowres)
    assert v.shape == (seq.n_frames, body_lowres.n_vertices, 3) and v.dtype == torch.float32
    assert seq.vertices(body_lowres) is v
    direct = body_lowres.forward(seq.betas[None], seq.poses, seq.trans)
    assert torch.allclose(v, direct.vertices) and torch.allclose(seq.joints(body_lowres), direct.joints)
    assert torch.allclose(seq.transforms(body_lowres), direct.transforms)
    n = seq.vertex_normals(body_lowres)
    assert n.shape == v.shape and torch.allclose(n.norm(dim=-1), torch.ones(()), atol=1e-4)
    # normals point outwards: away from the bone of each vertex's main joint (joint -> child segment)
    b = body_lowres
    j = seq.joints(b)[0]
    child = {p: c for c, p in reversed(list(enumerate(b.parents))) if p >= 0}
    main = b.weights.argmax(1)
    a, e = j[main], j[torch.tensor([child.get(int(m), int(m)) for m in main])]
    seg = e - a
    u = ((v[0] - a) * seg).sum(-1, keepdim=True) / (seg * seg).sum(-1, keepdim=True).clamp_min(1e-12)
    axis_point = a + u.clamp(0, 1) * seg
    assert (((v[0] - axis_point) * n[0]).sum(-1) > 0).float().mean() > 0.9
    part = seq.slice(5, 15)
    assert part.n_frames == 10 and part.n_transition == 10  # all 10 frames lie in the 15-frame transition
    assert torch.allclose(part.vertices(body_lowres), v[5:15], atol=1e-6)


def test_posed_frames_pose_a_chunk_without_caching_the_whole_sequence(body_lowres):
    seq = make_sequence("walk", 12, seed=0, transition=0)
    v, n = seq.posed_frames(body_lowres, 4, 9)
    assert not seq._cache  # nothing held for the whole sequence
    whole_v, whole_n = seq.vertices(body_lowres), seq.vertex_normals(body_lowres)
    assert torch.allclose(v, whole_v[4:9], atol=1e-6) and torch.allclose(n, whole_n[4:9], atol=1e-5)
    cached_v, _ = seq.posed_frames(body_lowres, 4, 9)  # now slices of the cached geometry
    assert cached_v.data_ptr() == whole_v[4:9].data_ptr()
    local, _ = seq.posed_frames(body_lowres, 4, 9, local=True)  # the root translation left out
    assert seq.trans[4:9].norm(dim=-1).min() > 0.1 and torch.allclose(local + seq.trans[4:9, None], whole_v[4:9], atol=1e-6)
    far = BodySequence("far", "walk", seq.betas, seq.poses, seq.trans + 1.0e4)  # posed without the translation
    assert torch.allclose(far.posed_frames(body_lowres, 4, 9, local=True)[0], local, atol=1e-6)


def test_cache_is_per_body_and_dtype(body_lowres):
    seq = make_sequence("squat", 10, seed=0, transition=0)
    v32 = seq.vertices(body_lowres)
    body64 = load_body("anny_lowres", dtype=torch.float64)
    v64 = seq.vertices(body64)
    assert v64.dtype == torch.float64 and torch.allclose(v64.float(), v32, atol=1e-5)
    assert seq.vertices(body_lowres) is v32 and seq.vertices(body64) is v64


def test_sequence_input_errors(body_lowres):
    with pytest.raises(ValueError, match=r"betas must be \(S,\)"):
        make_sequence("walk", 5, betas=torch.zeros(2, 10))
    with pytest.raises(ValueError, match="NaN"):
        make_sequence("walk", 5, betas=torch.full((10,), float("nan")))
    seq = BodySequence("x", "walk", torch.zeros(10), torch.zeros(3, 24, 3), torch.zeros(3, 3))
    with pytest.raises(ValueError, match="poses have 24 joints, body anny_lowres has 22"):
        seq.vertices(body_lowres)
    with pytest.raises(ValueError, match="n_transition"):
        BodySequence("x", "walk", torch.zeros(10), torch.zeros(3, 22, 3), torch.zeros(3, 3), n_transition=4)


def test_a_held_pose_is_posed_once_and_every_frame_matches_posing_it_afresh(body_lowres):
    seq = make_sequence("static", 20, seed=0, transition=5)
    held = seq.held_frames()
    assert held[-1] == held[10] and len(torch.unique(held)) < seq.n_frames  # the stance is held after the transition
    out = body_lowres.forward(body_lowres.full_betas(seq.betas)[None], seq.poses, seq.trans)
    assert torch.equal(seq.vertices(body_lowres), out.vertices) and torch.equal(seq.transforms(body_lowres), out.transforms)
    walk = make_sequence("walk", 8, seed=0, transition=0)
    assert torch.equal(walk.held_frames(), torch.arange(walk.n_frames))  # a moving body: every frame its own


def test_a_held_pose_on_a_moving_root_is_posed_at_every_frame(body_lowres):
    trans = torch.tensor([[0.0, 0.0, 0.0], [0.0, -0.1, 0.0], [0.0, -0.2, 0.0], [0.0, -0.2, 0.0]])
    seq = BodySequence("glide", "static", torch.zeros(10), torch.zeros(4, 22, 3), trans)
    assert seq.held_frames().tolist() == [0, 1, 2, 2]
    v = seq.vertices(body_lowres)
    assert torch.allclose(v - v[:1], (trans - trans[0])[:, None].expand_as(v), atol=1e-5)


def test_a_slice_keeps_only_the_transition_frames_it_holds():
    seq = make_sequence("walk", 10, seed=0, transition=6)
    assert seq.slice(0, 3).n_transition == 3 and seq.slice(4, 12).n_transition == 2
    assert seq.slice(6).n_transition == 0 and seq.slice(10, 16).n_transition == 0
