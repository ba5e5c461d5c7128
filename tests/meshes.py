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
