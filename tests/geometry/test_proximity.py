import numpy as np
import pytest
import torch
import trimesh
from scipy.spatial import cKDTree

from drapebench.geometry.proximity import (
    closest_body_point,
    culled_body_faces,
    culled_body_vertices,
    nearest_body_vertex,
    signed_distance,
)


def _segment_distance(p, a, b):
    """Distance from points p (N,3) to segments a-b (F,3): (N,F)."""
    ab = b - a
    t = np.clip(((p[:, None] - a) * ab).sum(-1) / np.maximum((ab * ab).sum(-1), 1e-300), 0, 1)
    return np.linalg.norm(p[:, None] - (a + t[..., None] * ab), axis=-1)


def _brute_unsigned(p, V, F):
    """Independent point-triangle distance: plane distance when the projection is inside the triangle,
    else the nearest of the three edges; min over all faces. p (N,3) -> (N,)."""
    a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    n = np.cross(b - a, c - a)
    n = n / np.linalg.norm(n, axis=-1, keepdims=True)
    h = ((p[:, None] - a) * n).sum(-1)
    proj = p[:, None] - h[..., None] * n
    inside = np.ones(h.shape, bool)
    for u, v in ((a, b), (b, c), (c, a)):
        inside &= (np.cross(v - u, proj - u) * n).sum(-1) >= 0
    edges = np.minimum.reduce([_segment_distance(p, a, b), _segment_distance(p, b, c), _segment_distance(p, c, a)])
    return np.where(inside, np.abs(h), edges).min(1)


def _winding_inside(p, V, F):
    """Exact inside test by the solid-angle winding number (Van Oosterom-Strackee), p (N,3) -> bool (N,)."""
    a, b, c = (V[F[:, i]][None] - p[:, None] for i in range(3))
    la, lb, lc = (np.linalg.norm(x, axis=-1) for x in (a, b, c))
    det = (a * np.cross(b, c)).sum(-1)
    den = la * lb * lc + (a * b).sum(-1) * lc + (b * c).sum(-1) * la + (c * a).sum(-1) * lb
    return np.abs((2 * np.arctan2(det, den)).sum(1) / (4 * np.pi)) > 0.5


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


def test_bad_inputs_are_named():
    body, normals = torch.randn(1, 10, 3), torch.randn(1, 10, 3)
    with pytest.raises(ValueError, match="NaN/Inf"):
        nearest_body_vertex(torch.full((1, 4, 3), float("nan")), body, normals)
    with pytest.raises(ValueError, match="body_vertices"):
        nearest_body_vertex(torch.zeros(2, 4, 3), torch.randn(3, 10, 3), torch.randn(3, 10, 3))
    with pytest.raises(ValueError, match="candidates"):
        nearest_body_vertex(torch.zeros(1, 4, 3), body, normals, torch.tensor([3, 12]))
    with pytest.raises(ValueError, match="body_faces"):
        signed_distance(torch.zeros(1, 4, 3), body, torch.tensor([[0, 1, 10]]))


@pytest.mark.parametrize("shape", ["box", "torus"])
def test_signed_distance_matches_brute_force(shape):
    """Convex box (sharp edges and corners: the pseudonormal cases) and a non-convex torus."""
    mesh = trimesh.creation.box((0.4, 0.3, 0.2)) if shape == "box" else trimesh.creation.torus(0.3, 0.1, 24, 12)
    V, F = np.asarray(mesh.vertices, float), np.asarray(mesh.faces)
    rng = np.random.default_rng(0)
    p = rng.uniform(V.min(0) - 0.1, V.max(0) + 0.1, size=(600, 3))
    p = np.concatenate([p, V + rng.normal(scale=1e-3, size=V.shape)])  # just in/out of vertices
    sd = signed_distance(torch.as_tensor(p)[None], torch.as_tensor(V)[None], torch.as_tensor(F))[0].numpy()
    assert np.allclose(np.abs(sd), _brute_unsigned(p, V, F), atol=1e-12)
    inside = _winding_inside(p, V, F)
    assert 0 < inside.sum() < len(p) and np.array_equal(sd < 0, inside)


def test_closest_point_lies_on_its_face_at_the_distance():
    mesh = trimesh.creation.icosphere(2, radius=0.5)
    V, F = torch.as_tensor(mesh.vertices), torch.as_tensor(mesh.faces)
    p = torch.randn(2, 300, 3, dtype=torch.float64)
    cp = closest_body_point(p, V[None].expand(2, -1, -1), F)
    assert torch.allclose((p - cp.point).norm(dim=-1), cp.distance.abs())
    tri = V[F[cp.face]]  # the closest point is a convex combination of its face's corners
    n = torch.cross(tri[..., 1, :] - tri[..., 0, :], tri[..., 2, :] - tri[..., 0, :], dim=-1)
    assert ((cp.point - tri[..., 0, :]) * n).sum(-1).abs().max() < 1e-12
    r = p.norm(dim=-1)
    clear = (r - 0.5).abs() > 0.05  # well inside / outside the 0.5 sphere
    assert torch.equal((cp.distance < 0)[clear], (r < 0.5)[clear])
    assert signed_distance(p.float(), V.float()[None], F).dtype == torch.float32


def test_eps_c_count_is_exact_for_points_placed_in_a_box():
    """k points placed inside a box body (1 mm to 4 cm deep), the rest outside (1 mm to 4 cm away)."""
    mesh = trimesh.creation.box((0.3, 0.2, 0.5))
    V, F = torch.as_tensor(mesh.vertices)[None], torch.as_tensor(mesh.faces)
    rng = np.random.default_rng(3)
    half = np.array([0.15, 0.1, 0.25])
    direction = rng.normal(size=(400, 3))
    axis = np.abs(direction / half).argmax(1)  # push each point along the normal of the face it faces
    surface = direction / np.abs(direction / half).max(1, keepdims=True)
    depth = rng.uniform(1e-3, 0.04, size=400)
    k = 137
    offset = np.where(np.arange(400) < k, -depth, depth)
    p = surface.copy()
    p[np.arange(400), axis] += np.sign(surface[np.arange(400), axis]) * offset
    sd = signed_distance(torch.as_tensor(p)[None], V, F)[0]
    assert int((sd < 0).sum()) == k
    assert torch.allclose(sd[k:], torch.as_tensor(depth[k:]))  # outside a face's interior: the offset itself
    assert (sd[:k] < 0).all() and (-sd[:k] <= torch.as_tensor(depth[:k]) + 1e-12).all()


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
def test_culling_gives_the_same_answers_on_a_posed_sequence(body_lowres, kind, motion):
    body = body_lowres
    g, seq, x = _skinned_garment(kind, body, motion)
    bv, bn = seq.vertices(body), seq.vertex_normals(body)
    cand = culled_body_vertices(g.vertices, body.v_template, body.weights)
    assert len(cand) < 0.8 * body.n_vertices
    assert torch.equal(nearest_body_vertex(x, bv, bn, cand).index, nearest_body_vertex(x, bv, bn).index)
    full, culled = closest_body_point(x[::3], bv[::3], body.faces), closest_body_point(x[::3], bv[::3], body.faces, cand)
    assert torch.equal(full.distance, culled.distance) and torch.equal(full.point, culled.point)  # faces may tie at a vertex
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
    assert torch.allclose(signed_distance(p, V, F), signed_distance(p.cuda(), V.cuda(), F.cuda()).cpu())
