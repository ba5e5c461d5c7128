"""The body's outer surface: the faces of a closed body mesh that are not buried inside another part.

A body mesh can hold surface that lies inside the body: a second closed part sunk into another (the
back of an eyeball inside the head) and the surface that part covers (the eye socket's skin behind
the eyeball). Such a face bounds no volume a garment can reach from outside. A face is on the outer surface when some point of it, moved
``OFFSET`` m off the face along its outward normal, lies outside every part of the mesh (winding
number <= 0.5, the rule of :func:`drapebench.geometry.sdf.inside_body`). The points tested per face
are ``SAMPLES`` (barycentric: the centroid, points near each corner and between two corners), so a
face crossed by the line where two parts meet counts as outer when any tested point of it is outside;
a sliver of it smaller than the spacing of the samples can be missed.

The set is computed once per mesh in its rest pose and cached by content hash; the signed distance
then measures depth and the nearest vertex against the outer faces only (``outer_faces=`` of
:mod:`drapebench.geometry.sdf`).
"""

from __future__ import annotations

import numpy as np
import torch

from drapebench.cache import Cache

OUTER_SURFACES = Cache("outer_surface", 1)  # bump when the rule or the samples change
OFFSET = 1e-5  # m off the face along its outward normal: far below any gap between body parts that is air
SAMPLES = (
    (1 / 3, 1 / 3, 1 / 3),
    (0.8, 0.1, 0.1), (0.1, 0.8, 0.1), (0.1, 0.1, 0.8),
    (0.45, 0.45, 0.1), (0.1, 0.45, 0.45), (0.45, 0.1, 0.45),
    (0.96, 0.02, 0.02), (0.02, 0.96, 0.02), (0.02, 0.02, 0.96),
)  # fmt: skip


def _build(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(F,) bool outer-face mask of vertices (V,3) float64, faces (F,3) int64 (module docstring)."""
    from drapebench.geometry.sdf import inside_body

    tri = vertices[faces]  # (F,3,3)
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(normal, axis=1, keepdims=True)
    if (length <= 0).any():
        raise ValueError(f"body mesh has {int((length <= 0).sum())} zero-area faces (first {int(np.argmax(length[:, 0] <= 0))}); "
                         "its outer surface needs every face's normal")  # fmt: skip
    points = np.einsum("sk,fkd->fsd", np.asarray(SAMPLES), tri) + OFFSET * (normal / length)[:, None]
    inside = inside_body(torch.from_numpy(points.reshape(1, -1, 3)), torch.from_numpy(vertices[None]), torch.from_numpy(faces))
    return ~inside[0].reshape(len(faces), len(SAMPLES)).all(1).numpy()


def _write(mask: np.ndarray, path) -> None:
    with open(path, "wb") as f:
        np.save(f, mask)


def outer_faces(vertices: torch.Tensor, faces: torch.Tensor) -> torch.Tensor:
    """(F,) bool: the faces of the closed body mesh (vertices (V,3) m in its rest pose, faces (F,3))
    on its outer surface (module docstring), on the device of ``faces``; cached by content hash."""
    v = vertices.detach().cpu().double().numpy()
    f = torch.as_tensor(faces).detach().cpu().long().numpy()
    path = OUTER_SURFACES.path(v, f, OFFSET, SAMPLES, suffix=".npy")
    mask = OUTER_SURFACES.get_or_build(path, lambda: _build(v, f), _write, np.load)
    return torch.from_numpy(np.asarray(mask, dtype=bool)).to(torch.as_tensor(faces).device)

