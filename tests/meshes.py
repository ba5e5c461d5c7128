"""Small synthetic meshes shared by the tests."""

import numpy as np


def grid_mesh(n: int = 6, size: float = 0.5, noise: float = 0.0, seed: int = 0):
    """An n x n vertex grid of side ``size`` (m) in the xy plane, z jittered by ``noise`` (m); (V,3), (F,3)."""
    xs, ys = np.meshgrid(np.linspace(0, size, n), np.linspace(0, size, n))
    z = noise * np.random.default_rng(seed).normal(size=n * n)
    V = np.stack([xs.ravel(), ys.ravel(), z], 1)
    F = []
    for i in range(n - 1):
        for j in range(n - 1):
            a, b, c, d = i * n + j, i * n + j + 1, (i + 1) * n + j, (i + 1) * n + j + 1
            F += [[a, b, d], [a, d, c]]
    return V, np.array(F)


def segment_distance(p, a, b):
    """Distance from points p (N,3) to segments a-b (F,3): (N,F)."""
    ab = b - a
    t = np.clip(((p[:, None] - a) * ab).sum(-1) / np.maximum((ab * ab).sum(-1), 1e-300), 0, 1)
    return np.linalg.norm(p[:, None] - (a + t[..., None] * ab), axis=-1)


def brute_unsigned(p, V, F):
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
    edges = np.minimum.reduce([segment_distance(p, a, b), segment_distance(p, b, c), segment_distance(p, c, a)])
    return np.where(inside, np.abs(h), edges).min(1)
