"""Tape-measure figures of a rest-pose body: height and waist girth, to say what a body shape means."""

from __future__ import annotations

import numpy as np
import trimesh


def body_height(vertices: np.ndarray) -> float:
    """Standing height (m): the vertical (Z) extent of rest-pose ``vertices`` (V, 3)."""
    v = np.asarray(vertices)
    return float(v[:, 2].max() - v[:, 2].min())


def girth(vertices: np.ndarray, faces: np.ndarray, z: float) -> float:
    """Circumference (m) of the torso at height ``z``: the convex hull (a tape measure's path) of the
    horizontal cross-section loop that encloses the body's vertical axis (x = y = 0); arm loops beside
    it are left out. Raises ValueError if no loop at that height encloses the axis."""
    mesh = trimesh.Trimesh(np.asarray(vertices, dtype=np.float64), np.asarray(faces), process=False)
    section = mesh.section(plane_origin=(0.0, 0.0, z), plane_normal=(0.0, 0.0, 1.0))
    if section is not None:
        for loop in section.discrete:
            xy = loop[:, :2]
            if _encloses_origin(xy):
                hull = _hull(xy)
                return float(np.linalg.norm(np.roll(hull, -1, 0) - hull, axis=1).sum())
    raise ValueError(f"no cross-section loop at z = {z:.3f} m encloses the body's axis; is the body in its rest pose?")


def _encloses_origin(xy: np.ndarray) -> bool:
    """Even-odd test: does the closed polygon ``xy`` (n, 2) contain (0, 0)?"""
    a, b = xy, np.roll(xy, -1, 0)
    crosses = (a[:, 1] > 0) != (b[:, 1] > 0)
    x_at = a[:, 0] + (0.0 - a[:, 1]) * (b[:, 0] - a[:, 0]) / np.where(crosses, b[:, 1] - a[:, 1], 1.0)
    return bool(np.count_nonzero(crosses & (x_at > 0)) % 2)


def _hull(xy: np.ndarray) -> np.ndarray:
    """Convex hull vertices of 2-D points (n, 2) in order."""
    from scipy.spatial import ConvexHull

    return xy[ConvexHull(xy).vertices]


def waist_girth(vertices: np.ndarray, faces: np.ndarray, joints: np.ndarray, joint_names: list[str]) -> float:
    """Waist circumference (m): :func:`girth` at the height of the ``spine1`` joint (rest pose)."""
    return girth(vertices, faces, float(np.asarray(joints)[list(joint_names).index("spine1"), 2]))
