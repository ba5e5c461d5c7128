import pickle

import numpy as np
import pytest
import scipy.sparse
import torch

from drapebench.body import BodyModel, load_body
from drapebench.body.bake import JOINT_NAMES, PARENTS
from drapebench.body.lbs import lbs


def _tiny_smpl_arrays(rng, V=40, J=4, S=3):
    w = rng.random((V, J))
    w /= w.sum(1, keepdims=True)
    return dict(
        v_template=rng.normal(size=(V, 3)),
        shapedirs=rng.normal(size=(V, 3, S)) * 0.01,
        posedirs=rng.normal(size=(V, 3, 9 * (J - 1))) * 0.001,
        J_regressor=np.full((J, V), 1.0 / V),
        weights=w,
        kintree_table=np.array([[2**32 - 1, 0, 1, 1], [0, 1, 2, 3]], dtype=np.int64),
        f=rng.integers(0, V, (30, 3)),
    )


@pytest.mark.parametrize("name", ["anny_lowres", "anny"])
def test_shipped_body_rest_pose_reproduces_template(name):
    body = load_body(name)
    assert body.joint_names == list(JOINT_NAMES)
    assert body.parents == list(PARENTS)
    assert body.n_betas >= 8
    out = body.forward(torch.zeros(1, body.n_betas), torch.zeros(1, body.n_joints, 3), torch.zeros(1, 3))
    assert torch.allclose(out.vertices[0], body.v_template, atol=1e-6)
    assert torch.allclose(body.weights.sum(1), torch.ones(body.n_vertices), atol=1e-5)


def test_lbs_exact_for_rigid_single_joint_weights():
    rng = np.random.default_rng(0)
    V, J = 30, 3
    weights = np.zeros((V, J))
    weights[:, 1] = 1.0
    body = BodyModel(rng.normal(size=(V, 3)), np.zeros((V, 3, 2)), np.eye(J, V), weights, [-1, 0, 1], np.array([[0, 1, 2]]))
    pose = torch.zeros(1, J, 3)
    pose[0, 0] = torch.tensor([0.0, 0.0, 0.7])
    pose[0, 1] = torch.tensor([0.3, -0.2, 0.1])
    trans = torch.tensor([[0.1, 0.2, 0.3]])
    out = body.forward(None, pose, trans)
    # all vertices follow joint 1's rigid transform: x' = G1 (x - j1) + j1_posed
    G = out.transforms[0, 1]
    expected = body.v_template @ G[:3, :3].T + G[:3, 3]
    assert torch.allclose(out.vertices[0], expected, atol=1e-6)
    # and the transform is rigid
    R = G[:3, :3]
    assert torch.allclose(R @ R.T, torch.eye(3), atol=1e-6)
    # lbs() on the same points agrees with forward
    assert torch.allclose(lbs(body.v_template, body.weights, out.transforms), out.vertices, atol=1e-6)


def test_joints_move_with_shape(body_lowres):
    betas = torch.zeros(2, body_lowres.n_betas)
    betas[1, 0] = 2.0
    _, joints = body_lowres.shaped(betas)
    moved = (joints[1] - joints[0]).norm(dim=-1)
    assert moved[1:].max() > 0.01  # the first component changes the skeleton by centimetres
    # joints stay inside the body's extent
    v, _ = body_lowres.shaped(betas)
    assert (joints[1, :, 2] < v[1, :, 2].max()).all() and (joints[1, :, 2] > v[1, :, 2].min()).all()


def test_float64_and_gradcheck():
    rng = np.random.default_rng(1)
    a = _tiny_smpl_arrays(rng, V=12, J=3, S=2)
    a["kintree_table"] = a["kintree_table"][:, :3]
    a["posedirs"] = a["posedirs"][:, :, : 9 * 2]
    body = BodyModel(a["v_template"], a["shapedirs"], a["J_regressor"][:3], a["weights"][:, :3] / a["weights"][:, :3].sum(1, keepdims=True),
                     [-1, 0, 1], a["f"] % 12, posedirs=a["posedirs"], dtype=torch.float64)  # fmt: skip
    pose = torch.randn(2, 3, 3, dtype=torch.float64, requires_grad=True)
    betas = torch.randn(2, 2, dtype=torch.float64, requires_grad=True)
    assert body.forward(betas, pose).vertices.dtype == torch.float64
    assert torch.autograd.gradcheck(lambda b, p: body.forward(b, p).vertices, (betas, pose))


def test_user_smpl_npz_and_pkl(tmp_path):
    rng = np.random.default_rng(2)
    a = _tiny_smpl_arrays(rng)
    np.savez(tmp_path / "m.npz", **a)
    pk = dict(a, J_regressor=scipy.sparse.csc_matrix(a["J_regressor"]))
    with open(tmp_path / "m.pkl", "wb") as f:
        pickle.dump(pk, f)
    for path in (tmp_path / "m.npz", tmp_path / "m.pkl"):
        body = load_body(path)
        assert body.n_joints == 4 and body.parents == [-1, 0, 1, 1] and body.posedirs is not None
        assert torch.allclose(body.forward().vertices[0], torch.as_tensor(a["v_template"], dtype=torch.float32), atol=1e-6)
    yup = load_body(tmp_path / "m.npz", up_axis="y")
    v = torch.as_tensor(a["v_template"], dtype=torch.float32)
    assert torch.allclose(yup.v_template[:, 2], v[:, 1], atol=1e-6)  # old Y is the new Z
    assert torch.allclose(yup.v_template[:, 1], -v[:, 2], atol=1e-6)


class _RunsCode:
    def __reduce__(self):
        import os

        return (os.getcwd, ())  # harmless here; a hostile file would name os.system


def test_a_pickle_with_anything_but_arrays_is_refused_before_it_runs(tmp_path):
    from drapebench.body.motion_file import read_motion_file

    for name in ("body.pkl", "motion.pkl"):
        with open(tmp_path / name, "wb") as f:
            pickle.dump({"poses": np.zeros((2, 3)), "v_template": _RunsCode()}, f)
    with pytest.raises(ValueError, match="refusing to load posix.getcwd"):
        load_body(tmp_path / "body.pkl")
    with pytest.raises(ValueError, match="refusing to load posix.getcwd"):
        read_motion_file(tmp_path / "motion.pkl")


def test_malformed_body_file_names_the_key(tmp_path):
    rng = np.random.default_rng(3)
    a = _tiny_smpl_arrays(rng)
    b = dict(a)
    del b["weights"]
    np.savez(tmp_path / "missing.npz", **b)
    with pytest.raises(ValueError, match="weights"):
        load_body(tmp_path / "missing.npz")
    c = dict(a, shapedirs=a["shapedirs"][:10])
    np.savez(tmp_path / "shape.npz", **c)
    with pytest.raises(ValueError, match=r"shapedirs has shape \(10, 3, 3\)"):
        load_body(tmp_path / "shape.npz")
    with pytest.raises(FileNotFoundError, match="neither a shipped body"):
        load_body(tmp_path / "nope.npz")


def test_bad_pose_input_is_reported(body_lowres):
    with pytest.raises(ValueError, match=r"expects \(B, 22, 3\)"):
        body_lowres.forward(None, torch.zeros(1, 24, 3))
    pose = torch.zeros(1, 22, 3)
    pose[0, 3, 1] = float("nan")
    with pytest.raises(ValueError, match="NaN"):
        body_lowres.forward(None, pose)
    with pytest.raises(ValueError, match="betas"):
        body_lowres.forward(torch.zeros(1, 50))


def test_shape_space_spans_adults_not_giants(body_lowres):
    """betas ~ N(0, I) is the adult population: +-2 on any of the first four components keeps the
    standing height inside the adult range (about 1.45-2.0 m) and the mean body near 1.7 m."""
    from drapebench.body.measure import body_height

    assert 1.6 < body_height(body_lowres.v_template.numpy()) < 1.8
    for k in range(4):
        for value in (-2.0, 2.0):
            betas = torch.zeros(1, body_lowres.n_betas)
            betas[0, k] = value
            h = body_height(body_lowres.shaped(betas)[0][0].numpy())
            assert 1.45 < h < 2.0, f"beta{k} = {value:+g} gives a {h:.2f} m tall body"


def test_waist_girth_grows_with_the_body(body_lowres):
    from drapebench.body.measure import waist_girth

    def girth_at(value):
        betas = torch.zeros(1, body_lowres.n_betas)
        betas[0, 1] = value
        v, j = body_lowres.shaped(betas)
        return waist_girth(v[0].numpy(), body_lowres.faces.numpy(), j[0].numpy(), body_lowres.joint_names)

    g = [girth_at(v) for v in (-2.0, 0.0, 2.0)]
    assert 0.6 < g[0] < g[1] < g[2] < 1.3  # beta1 is body weight: a larger waist, in metres


@pytest.mark.parametrize("damage", ["truncate", "flip"])
def test_a_damaged_body_file_fails_naming_the_file_and_the_fix(damage, tmp_path):
    from drapebench.body.model import BODY_DIR

    data = bytearray((BODY_DIR / "anny_lowres.npz").read_bytes())
    if damage == "truncate":
        data = data[: len(data) // 2]
    else:
        data[len(data) // 2] ^= 0x01
    path = tmp_path / "body.npz"
    path.write_bytes(bytes(data))
    with pytest.raises(ValueError, match="body.npz is truncated or corrupt.*drapebench.body.bake"):
        load_body(path)


def test_a_missing_user_body_names_the_file_it_looked_for():
    from drapebench.body.model import BODY_DIR

    with pytest.raises(FileNotFoundError, match=f"{BODY_DIR / 'smpl.npz'} does not exist.*body.name=/path/to/model.npz"):
        load_body("smpl")


@pytest.mark.parametrize("per_frame", [False, True])
def test_lbs_in_chunks_equals_one_pass(monkeypatch, per_frame):
    """lbs() skins long sequences in chunks of frames; shared and per-frame points/weights alike."""
    import importlib

    lbs_module = importlib.import_module("drapebench.body.lbs")  # the module (drapebench.body.lbs is also the function)

    g = torch.Generator().manual_seed(0)
    B, N, J = 11, 7, 4
    transforms = torch.randn(B, J, 4, 4, generator=g, dtype=torch.float64)
    points = torch.randn(B, N, 3, generator=g, dtype=torch.float64) if per_frame else torch.randn(N, 3, generator=g, dtype=torch.float64)
    weights = torch.rand(B, N, J, generator=g, dtype=torch.float64) if per_frame else torch.rand(N, J, generator=g, dtype=torch.float64)
    whole = lbs_module.lbs(points, weights, transforms)
    monkeypatch.setattr(lbs_module, "LBS_CHUNK", 3)
    chunked = lbs_module.lbs(points, weights, transforms)
    assert chunked.shape == (B, N, 3) and torch.allclose(chunked, whole, rtol=0, atol=1e-12)


def test_transforms_without_the_vertices_equal_the_skinned_ones(body_lowres):
    from drapebench.body import make_sequence

    seq = make_sequence("walk", 6, seed=0, transition=0)
    assert seq.trans[:, :2].abs().max() > 0.05  # the root travels
    posed = body_lowres.forward(seq.betas[None], seq.poses, seq.trans)
    bare = body_lowres.forward(seq.betas[None], seq.poses, seq.trans, skin=False)
    assert bare.vertices is None
    assert torch.allclose(bare.transforms, posed.transforms, atol=1e-5) and torch.allclose(bare.joints, posed.joints, atol=1e-5)
    assert torch.allclose(seq.transforms(body_lowres), posed.transforms, atol=1e-5)  # the sequence's, without posing vertices
