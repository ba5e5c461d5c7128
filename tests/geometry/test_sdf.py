"""The one signed distance (drapebench.geometry.sdf) against independent implementations."""

import igl
import numpy as np
import pytest
import torch
import trimesh

from drapebench.geometry import body_bvh
from drapebench.geometry.sdf import closest_body_point, inside_body, signed_distance
from tests.meshes import brute_unsigned


def _winding(p, V, F):
    """Exact generalized winding number (Van Oosterom-Strackee solid angles summed), p (N,3) -> (N,)."""
    a, b, c = (V[F[:, i]][None] - p[:, None] for i in range(3))
    la, lb, lc = (np.linalg.norm(x, axis=-1) for x in (a, b, c))
    det = (a * np.cross(b, c)).sum(-1)
    den = la * lb * lc + (a * b).sum(-1) * lc + (b * c).sum(-1) * la + (c * a).sum(-1) * lb
    return (2 * np.arctan2(det, den)).sum(1) / (4 * np.pi)


def _winding_inside(p, V, F):
    """Inside test by the exact winding number (> 0.5), in chunks of points: bool (N,)."""
    return np.concatenate([_winding(c, V, F) > 0.5 for c in np.array_split(p, max(1, len(p) * len(F) // 2_000_000))])


@pytest.mark.parametrize("exact", [False, True])
@pytest.mark.parametrize("shape", ["box", "torus"])
def test_signed_distance_matches_brute_force(shape, exact):
    """Convex box (sharp edges and corners: the pseudonormal cases) and a non-convex torus, both paths."""
    mesh = trimesh.creation.box((0.4, 0.3, 0.2)) if shape == "box" else trimesh.creation.torus(0.3, 0.1, 24, 12)
    V, F = np.asarray(mesh.vertices, float), np.asarray(mesh.faces)
    rng = np.random.default_rng(0)
    p = rng.uniform(V.min(0) - 0.1, V.max(0) + 0.1, size=(600, 3))
    p = np.concatenate([p, V + rng.normal(scale=1e-3, size=V.shape)])  # just in/out of vertices
    sd = signed_distance(torch.as_tensor(p)[None], torch.as_tensor(V)[None], torch.as_tensor(F), exact=exact)[0].numpy()
    assert np.allclose(np.abs(sd), brute_unsigned(p, V, F), atol=1e-12)
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


def test_frames_split_over_threads_give_each_frame_its_own_answer(monkeypatch):
    """body_bvh.query hands frames to torch's threads, each with its own warp mesh: every frame (a sphere
    at its own place and size) gets the answer a one-thread query gives it."""
    mesh = trimesh.creation.icosphere(2, radius=0.5)
    F = torch.as_tensor(mesh.faces)
    V = torch.stack([torch.as_tensor(mesh.vertices) * (1 + 0.1 * b) + 0.05 * b for b in range(5)])
    p = torch.randn(5, 200, 3, dtype=torch.float64) * 0.6
    monkeypatch.setattr(torch, "get_num_threads", lambda: 3)
    split = body_bvh.query(p, V, F, nearest_vertex=True)
    monkeypatch.setattr(torch, "get_num_threads", lambda: 1)
    one = [body_bvh.query(p[b : b + 1], V[b : b + 1], F, nearest_vertex=True) for b in range(5)]
    for got, want in zip(split, zip(*one)):
        assert torch.equal(got, torch.cat(want))
    assert torch.equal(split.vertex, torch.cdist(p, V).argmin(-1))  # each frame's nearest vertex on its own sphere
    r = (p - 0.05 * torch.arange(5.0, dtype=torch.float64)[:, None, None]).norm(dim=-1)
    radius = 0.5 * (1 + 0.1 * torch.arange(5.0, dtype=torch.float64))[:, None]
    clear = (r - radius).abs() > 0.05 * radius  # away from the faceted sphere's surface
    assert torch.equal((split.winding > 0)[clear], (r < radius)[clear])  # each frame tested against its own sphere


def test_a_frame_queried_again_or_from_another_thread_gets_its_own_answer():
    """body_bvh refits its mesh only when the frame changes and gives each calling thread its own mesh: frames
    queried in turn, one frame again after another, a frame changed in place, and two threads querying
    different frames at once all get the answer of a first query of that frame."""
    from concurrent.futures import ThreadPoolExecutor

    mesh = trimesh.creation.icosphere(2, radius=0.5)
    F = torch.as_tensor(mesh.faces)
    V = torch.stack([torch.as_tensor(mesh.vertices) * (1 + 0.2 * b) + 0.1 * b for b in range(4)])
    p = torch.randn(4, 300, 3, dtype=torch.float64) * 0.6
    first = [body_bvh.query(p[b : b + 1], V[b : b + 1], F) for b in range(4)]
    order = [0, 0, 1, 1, 0, 3, 2, 3, 3]
    for b in order:
        assert torch.equal(body_bvh.query(p[b : b + 1], V[b : b + 1], F).winding, first[b].winding)
    moved = V[0:1].clone()
    body_bvh.query(p[:1], moved, F)
    moved.copy_(V[2:3])  # the same tensor, another frame
    assert torch.equal(body_bvh.query(p[2:3], moved, F).closest, first[2].closest)
    with ThreadPoolExecutor(2) as pool:
        got = list(pool.map(lambda b: [body_bvh.query(p[b : b + 1], V[b : b + 1], F) for _ in range(20)], [1, 3]))
    for b, answers in zip([1, 3], got):
        # a thread's own mesh is built on its own first frame: of two faces tied at an edge it may find the other
        assert all(torch.allclose(a.closest, first[b].closest, rtol=0, atol=1e-12) and torch.equal(a.winding, first[b].winding) for a in answers)


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


def test_bad_faces_are_named():
    with pytest.raises(ValueError, match="body_faces"):
        signed_distance(torch.zeros(1, 4, 3), torch.randn(1, 10, 3), torch.tensor([[0, 1, 10]]))


def _two_overlapping_boxes():
    a, b = trimesh.creation.box((0.4, 0.2, 0.2)), trimesh.creation.box((0.2, 0.2, 0.4))
    b.apply_translation((0.15, 0.0, 0.0))
    V = np.concatenate([a.vertices, b.vertices])
    F = np.concatenate([a.faces, b.faces + len(a.vertices)])
    return V, F


def test_ray_crossings_count_overlapping_parts_and_open_meshes_take_the_exact_path():
    """The winding number is 2 inside both boxes, 1 inside one, 0 outside; a box with a face
    removed is not closed and is measured by the libigl path."""
    V, F = _two_overlapping_boxes()
    p = torch.tensor([[[0.15, 0.0, 0.0], [-0.15, 0.0, 0.0], [0.15, 0.0, 0.15], [0.5, 0.5, 0.5]]], dtype=torch.float64)
    found = body_bvh.query(p, torch.as_tensor(V)[None], torch.as_tensor(F))
    assert found.winding.tolist() == [[2, 1, 1, 0]] and found.face.shape == (1, 4) and found.closest.shape == (1, 4, 3)
    assert found.vertex is None
    box = trimesh.creation.box((0.4, 0.3, 0.2))
    V1, F1 = torch.as_tensor(box.vertices)[None], torch.as_tensor(box.faces)
    flipped = F1.clone()
    flipped[0] = flipped[0, [0, 2, 1]]  # closed but not consistently oriented
    assert body_bvh.is_closed(F1) and not body_bvh.is_closed(F1[1:]) and not body_bvh.is_closed(flipped)
    q = torch.rand(1, 200, 3, dtype=torch.float64) * 0.6 - 0.3
    assert torch.equal(signed_distance(q, V1, F1[1:]), signed_distance(q, V1, F1[1:], exact=True))


def test_inside_any_part_counts_as_inside_where_parts_overlap():
    """A point inside box A whose nearest surface is a face of box B (inside A, outside B near it)
    is inside; the closest-feature pseudonormal would read it as outside."""
    V, F = _two_overlapping_boxes()
    p = np.array([[0.06, 0.0, 0.0], [0.15, 0.0, 0.15], [0.22, 0.0, 0.0], [0.0, 0.0, 0.15]])
    sd = signed_distance(torch.as_tensor(p)[None], torch.as_tensor(V)[None], torch.as_tensor(F))[0].numpy()
    assert np.array_equal(sd < 0, [True, True, True, False])
    assert np.allclose(np.abs(sd), np.sqrt(igl.point_mesh_squared_distance(p, V, F)[0]), atol=1e-12)
    rng = np.random.default_rng(1)
    q = rng.uniform(V.min(0) - 0.05, V.max(0) + 0.05, size=(800, 3))
    inside = inside_body(torch.as_tensor(q)[None], torch.as_tensor(V)[None], torch.as_tensor(F))[0].numpy()
    assert np.array_equal(inside, _winding_inside(q, V, F)) and 0 < inside.sum() < len(q)


def test_normal_gives_a_differentiable_signed_distance():
    mesh = trimesh.creation.torus(0.3, 0.1, 24, 12)
    V, F = torch.as_tensor(mesh.vertices)[None], torch.as_tensor(mesh.faces)
    x = (torch.randn(1, 200, 3, dtype=torch.float64) * 0.3).requires_grad_()
    sp = closest_body_point(x, V, F)
    assert torch.allclose(((x - sp.point) * sp.normal).sum(-1), sp.distance, atol=1e-12)
    assert torch.allclose(sp.normal.norm(dim=-1), torch.ones(1, 200, dtype=torch.float64))
    ((x - sp.point.detach()) * sp.normal.detach()).sum().backward()
    h, e = 1e-6, torch.zeros(1, 200, 3, dtype=torch.float64)
    e[..., 0] = h  # finite difference of the exact signed distance along x
    fd = (signed_distance(x.detach() + e, V, F) - signed_distance(x.detach() - e, V, F)) / (2 * h)
    assert torch.allclose(x.grad[..., 0], fd, atol=1e-5)


def _squat_points(body, n_frames=20):
    """Body frames of a deep squat (the last frames press thighs into belly) and per frame the body
    vertices 5 mm inside along their normals (where parts overlap, inside two parts) plus points
    within 3 cm of the surface: (T,Vb,3) and (T,Vb+2000,3) float64."""
    from drapebench.body import make_sequence

    seq = make_sequence("squat", n_frames, seed=0)
    bv, bn = seq.vertices(body).double(), seq.vertex_normals(body).double()
    g = torch.Generator().manual_seed(0)
    idx = torch.randint(0, body.n_vertices, (2000,), generator=g)
    near = bv[:, idx] + 0.03 * (torch.rand(bv.shape[0], 2000, 3, generator=g, dtype=torch.float64) * 2 - 1)
    return bv, torch.cat([bv - 0.005 * bn, near], 1)


@pytest.mark.parametrize("exact", [False, True])
def test_inside_matches_an_exact_winding_number_where_the_body_intersects_itself(body_lowres, exact):
    body = body_lowres
    bv, x = _squat_points(body, 30)
    F = body.faces.numpy()
    frame = bv.shape[0] - 1
    V, p = bv[frame].numpy(), x[frame].numpy()
    w = np.concatenate([_winding(c, V, F) for c in np.array_split(p, 40)])
    assert (w > 1.5).sum() >= 10  # the posed body overlaps itself here
    inside = inside_body(x[frame][None], bv[frame][None], body.faces, exact=exact)[0].numpy()
    clear = np.abs(w - 0.5) > 0.05  # the fast winding number's approximation band
    assert clear.mean() > 0.99 and np.array_equal(inside[clear], w[clear] > 0.5)
    sd = signed_distance(x[frame][None], bv[frame][None], body.faces, exact=exact)[0].numpy()
    assert np.array_equal((sd < 0)[clear], w[clear] > 0.5)
    assert np.allclose(np.abs(sd), np.sqrt(igl.point_mesh_squared_distance(p, V, F.astype(np.int64))[0]), atol=1e-9)


@pytest.mark.parametrize("shift", [(0.0, -2.5, 0.0), (1.5, 0.0, 0.3), (0.0, 0.0, 0.0)])
def test_closest_point_search_is_exact_anywhere(body_lowres, shift):
    """Points far from the body (below the feet, beside it) and near it: the distance equals libigl's
    over the whole body and the sign its winding number."""
    body = body_lowres
    bv, x = _squat_points(body, 6)
    x = x[-2:] + torch.tensor(shift, dtype=torch.float64)
    sp = closest_body_point(x, bv[-2:], body.faces)
    for b in range(2):
        V, F = bv[-2 + b].numpy(), body.faces.numpy().astype(np.int64)
        d = np.sqrt(igl.point_mesh_squared_distance(x[b].numpy(), V, F)[0])
        assert np.allclose(sp.distance[b].abs().numpy(), d, atol=1e-9)
        w = igl.winding_number(V, F, x[b].numpy())
        clear = np.abs(w - 0.5) > 0.05
        assert np.array_equal((sp.distance[b] < 0).numpy()[clear], (w > 0.5)[clear])
    if shift[1] < 0:
        assert (sp.distance > 0.5).all()


@pytest.mark.parametrize("scale", [0.01, 0.3])
def test_the_body_bvh_finds_the_nearest_vertex_of_the_whole_body(body_lowres, scale):
    """body_proximity's nearest vertex comes from the posed body's BVH: the same nearest distance as
    brute force over every body vertex, for points near the skin (inside and out) and far from it, and
    broadcast (1,Vb,3) bodies; differentiable as the KD-tree path."""
    from drapebench.body import make_sequence
    from drapebench.geometry.sdf import body_proximity

    body = body_lowres
    seq = make_sequence("squat", 3, seed=2, transition=0)
    bv, bn = seq.vertices(body), seq.vertex_normals(body)
    g = torch.Generator().manual_seed(3)
    pick = torch.randint(0, body.n_vertices, (3, 400), generator=g)
    x = (bv.gather(1, pick[..., None].expand(-1, -1, 3)) + scale * torch.randn(3, 400, 3, generator=g)).requires_grad_(True)
    nn = body_proximity(x, bv, bn, body.faces)[1]
    brute = torch.cdist(x.detach().double(), bv.double()).min(-1).values
    assert torch.allclose((x.detach() - nn.point).norm(dim=-1).double(), brute, atol=1e-6)
    assert (nn.index == torch.cdist(x.detach().double(), bv.double()).argmin(-1)).float().mean() > 0.99  # float32 near-ties aside
    nn.distance.sum().backward()
    assert torch.allclose(x.grad, nn.normal)
    one = body_proximity(x.detach(), bv[:1], bn[:1], body.faces)[1]
    assert torch.allclose((x.detach() - one.point).norm(dim=-1).double(), torch.cdist(x.detach().double(), bv[:1].double()).min(-1).values, atol=1e-6)


@pytest.mark.parametrize("shift", [(0.0, -2.5, 0.0), (0.0, 0.0, 0.0)])
def test_body_proximity_finds_both_answers_in_one_pass(body_lowres, shift):
    """body_proximity's one BVH pass gives the signed distance of closest_body_point and the whole
    body's nearest vertex (brute force), on both paths, near the body and far below it."""
    from drapebench.geometry.sdf import body_proximity

    body = body_lowres
    bv, x = _squat_points(body, 6)
    bv, x = bv[-2:], x[-2:] + torch.tensor(shift, dtype=torch.float64)
    bn = torch.nn.functional.normalize(torch.randn_like(bv), dim=-1)
    brute = torch.cdist(x, bv).min(-1).values
    for exact in (False, True):
        surface, nn = body_proximity(x, bv, bn, body.faces, exact=exact)
        assert torch.allclose(surface.distance, signed_distance(x, bv, body.faces, exact=exact), atol=1e-9)
        assert torch.allclose((x - nn.point).norm(dim=-1), brute, atol=1e-6)
        assert torch.allclose(nn.distance, ((x - nn.point) * nn.normal).sum(-1))
        assert torch.equal(nn.normal, bn.gather(1, nn.index[..., None].expand(-1, -1, 3)))


def test_inside_where_the_ray_runs_along_a_box_face():
    """Points just off the faces of a sphere inside another: the first ray (the face normal) of a face
    cut by the symmetry plane z = 0 runs in that plane, where warp's BVH slab test drops boxes that end
    on it; every point must still read inside (winding 1)."""
    head, part = trimesh.creation.icosphere(3, radius=0.2), trimesh.creation.icosphere(3, radius=0.04)
    V = np.concatenate([head.vertices, part.vertices + (0.08, 0.0, 0.0)])
    F = np.concatenate([head.faces, part.faces + len(head.vertices)])
    tri = V[part.faces + len(head.vertices)]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    p = tri.mean(1) + 1e-5 * n / np.linalg.norm(n, axis=1, keepdims=True)
    assert (np.abs(n[:, 2]) < 1e-12).any()  # some first rays do run in the plane
    assert inside_body(torch.as_tensor(p)[None], torch.as_tensor(V)[None], torch.as_tensor(F))[0].all()


def test_the_exact_path_is_exact_for_points_on_and_off_the_body_queried_together(body_lowres):
    """Its face culling must keep every face a point of the batch may be closest to, whatever the other points."""
    v, faces = body_lowres.v_template.double(), body_lowres.faces
    g = torch.Generator().manual_seed(0)
    on = v[torch.randint(len(v), (10,), generator=g)]
    off = on + 0.3 * torch.randn(10, 3, generator=g, dtype=torch.float64)
    for a, b in zip(on, off):
        together = signed_distance(torch.stack([a, b])[None], v[None], faces, exact=True)[0, 1]
        torch.testing.assert_close(together, signed_distance(b[None, None], v[None], faces, exact=True)[0, 0])
