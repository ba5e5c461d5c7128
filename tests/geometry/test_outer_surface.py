"""The body's outer surface (drapebench.geometry.outer_surface) and the depth and nearest vertex measured on it."""

import numpy as np
import pytest
import torch
import trimesh
from scipy.spatial import cKDTree

from drapebench.geometry.ops import vertex_normals
from drapebench.geometry.outer_surface import outer_faces
from drapebench.geometry.sdf import body_proximity, closest_body_point, inside_body
from tests.meshes import brute_unsigned

# a head (radius 0.2 m), a part buried inside it, and an eye half in and half out of it
SPHERES = {"head": ((0.0, 0.0, 0.0), 0.2), "buried": ((0.08, 0.0, 0.0), 0.04), "eye": ((0.0, 0.2, 0.0), 0.05)}


def _scene():
    """The three closed spheres as one mesh: V (V,3), F (F,3), the part of each face (F,) str."""
    V, F, part = [], [], []
    for name, (centre, radius) in SPHERES.items():
        m = trimesh.creation.icosphere(subdivisions=3, radius=radius)
        F.append(np.asarray(m.faces) + sum(len(v) for v in V))
        V.append(np.asarray(m.vertices) + centre)
        part += [name] * len(m.faces)
    return np.concatenate(V), np.concatenate(F), np.array(part)


def _inside_other(points, part):
    """(N,) bool: points lie inside a sphere other than ``part`` (analytic, with a 1 mm margin)."""
    return np.any([np.linalg.norm(points - c, axis=-1) < r - 1e-3 for name, (c, r) in SPHERES.items() if name != part], axis=0)


def _outside_others(points, part):
    return np.all([np.linalg.norm(points - c, axis=-1) > r + 1e-3 for name, (c, r) in SPHERES.items() if name != part], axis=0)


def test_outer_faces_drop_what_another_part_encloses():
    V, F, part = _scene()
    outer = outer_faces(torch.as_tensor(V), torch.as_tensor(F)).numpy()
    corners = V[F]  # (F,3,3)
    buried = np.array([_inside_other(corners[i], part[i]).all() for i in range(len(F))])
    clear = np.array([_outside_others(corners[i], part[i]).all() for i in range(len(F))])
    assert not outer[part == "buried"].any()
    assert outer[clear].all() and not outer[buried].any()
    assert buried[part == "eye"].any() and clear[part == "eye"].any() and buried[part == "head"].any()  # the eye crosses the head


@pytest.mark.parametrize("exact", [False, True])
def test_depth_is_to_the_outer_surface(exact):
    """A point inside the head beside the buried part: its depth is to the head's skin (brute force over
    the outer faces), not to the buried part; points outside read the same either way."""
    V, F, part = _scene()
    outer = outer_faces(torch.as_tensor(V), torch.as_tensor(F))
    rng = np.random.default_rng(0)
    near_buried = np.array(SPHERES["buried"][0]) + rng.normal(scale=0.03, size=(200, 3))
    outside = rng.uniform(-0.3, 0.3, size=(400, 3))
    outside = outside[~inside_body(torch.as_tensor(outside)[None], torch.as_tensor(V)[None], torch.as_tensor(F))[0].numpy()]
    p = np.concatenate([near_buried, outside])
    sp = closest_body_point(torch.as_tensor(p)[None], torch.as_tensor(V)[None], torch.as_tensor(F), exact=exact, outer_faces=outer)
    d = sp.distance[0].numpy()
    assert np.allclose(np.abs(d), brute_unsigned(p, V, F[outer.numpy()]), atol=1e-9)
    assert outer.numpy()[sp.face[0].numpy()].all()
    whole = closest_body_point(torch.as_tensor(p)[None], torch.as_tensor(V)[None], torch.as_tensor(F), exact=exact).distance[0].numpy()
    n = len(near_buried)
    assert np.allclose(whole[n:], d[n:], atol=1e-12)  # outside: the closest point of the whole mesh is on the outer surface
    assert (np.abs(whole[:n]) < np.abs(d[:n]) - 1e-3).sum() > 20  # the buried part is closer to many points inside the head
    assert (d[:n] < 0).all()


@pytest.mark.parametrize("exact", [False, True])
def test_nearest_vertex_is_an_outer_corner(exact):
    V, F, _ = _scene()
    Vt, Ft = torch.as_tensor(V), torch.as_tensor(F)
    outer = outer_faces(Vt, Ft)
    corners = np.unique(F[outer.numpy()])
    rng = np.random.default_rng(1)
    p = np.array(SPHERES["buried"][0]) + rng.normal(scale=0.05, size=(300, 3))
    _, nn = body_proximity(torch.as_tensor(p)[None], Vt[None], vertex_normals(Vt[None], Ft), Ft, exact=exact, outer_faces=outer)
    expected = corners[cKDTree(V[corners]).query(p)[1]]
    assert np.array_equal(nn.index[0].numpy(), expected)
    assert not np.isin(expected, corners, invert=True).any()
    assert not np.array_equal(expected, cKDTree(V).query(p)[1])  # the whole body's nearest vertex is often a buried one


def test_outer_faces_mask_is_checked():
    V, F, _ = _scene()
    with pytest.raises(ValueError, match="one flag per body face"):
        closest_body_point(torch.as_tensor(V[:3])[None], torch.as_tensor(V)[None], torch.as_tensor(F), outer_faces=torch.ones(5, dtype=torch.bool))
    with pytest.raises(ValueError, match="at least one"):
        closest_body_point(torch.as_tensor(V[:3])[None], torch.as_tensor(V)[None], torch.as_tensor(F), outer_faces=torch.zeros(len(F), dtype=torch.bool))


def test_full_body_outer_surface(body_full, body_lowres):
    """The full anny body's eyeballs are partly buried in the head, its mouth part is not; the
    low-resolution skin is all outer surface."""
    outer = body_full.outer_faces.numpy()
    F = body_full.faces.numpy()
    labels = trimesh.graph.connected_component_labels(trimesh.Trimesh(body_full.v_template.numpy(), F, process=False).face_adjacency, len(F))
    sizes = np.bincount(labels)
    skin = labels == sizes.argmax()
    assert outer[skin].mean() > 0.99 and not outer[skin].all()
    small = [c for c in range(len(sizes)) if c != sizes.argmax()]
    assert sum(0 < (~outer[labels == c]).sum() < (labels == c).sum() for c in small) == 2  # the two eyes
    assert body_lowres.outer_faces.all()
