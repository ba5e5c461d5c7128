"""As-rigid-as-possible deformation (Sorkine & Alexa 2007) through libigl, with handle constraints.

:class:`ArapSolver` factorizes once per (rest mesh, handle set) and then solves for any handle positions;
:func:`arap_solver` keeps the last few factorizations, keyed by content, so a handle set that comes
back (a static scene, a repeated frame) is not factorized again.
"""

from __future__ import annotations

from collections import OrderedDict

import numpy as np
import torch

from drapebench.cache import content_hash


class ArapSolver:
    """ARAP of a rest mesh with a fixed handle set.

    rest_vertices (V, 3) m and faces (F, 3) define the rest shape; handles (H,) are the constrained
    vertex indices (at least one); ``iterations`` local-global iterations per :meth:`solve`.
    """

    def __init__(self, rest_vertices, faces, handles, iterations: int = 2):
        import igl

        V = np.ascontiguousarray(_numpy(rest_vertices), dtype=np.float64)
        F = np.ascontiguousarray(_numpy(faces), dtype=np.int64)
        b = np.ascontiguousarray(_numpy(handles), dtype=np.int32).reshape(-1)
        if len(b) == 0:
            raise ValueError("ARAP needs at least one handle vertex; without handles the solution is only defined up to a rigid motion")
        if b.min() < 0 or b.max() >= len(V):
            raise ValueError(f"handle indices must be in [0, {len(V)}), got [{b.min()}, {b.max()}]")
        if iterations < 1:
            raise ValueError(f"iterations must be >= 1, got {iterations}")
        self.n_vertices, self.handles = len(V), b
        self.data = igl.ARAPData()
        self.data.max_iter = int(iterations)
        igl.arap_precomputation(V, F, 3, b, self.data)

    def solve(self, handle_positions, initial):
        """(V, 3) float64 positions: handles at ``handle_positions`` (H, 3), the rest as rigid as possible,
        starting from ``initial`` (V, 3)."""
        import igl

        bc = np.ascontiguousarray(_numpy(handle_positions), dtype=np.float64).reshape(len(self.handles), 3)
        U = np.ascontiguousarray(_numpy(initial), dtype=np.float64).reshape(self.n_vertices, 3)
        return igl.arap_solve(bc, self.data, U)


_SOLVERS: OrderedDict[str, ArapSolver] = OrderedDict()
_MAX_SOLVERS = 8


def arap_solver(rest_vertices, faces, handles, iterations: int = 2) -> ArapSolver:
    """An :class:`ArapSolver`, reused when the same rest mesh, handle set and iterations come back."""
    key = content_hash(_numpy(rest_vertices), _numpy(faces), _numpy(handles).astype(np.int64), iterations)
    solver = _SOLVERS.pop(key, None) or ArapSolver(rest_vertices, faces, handles, iterations)
    _SOLVERS[key] = solver
    while len(_SOLVERS) > _MAX_SOLVERS:
        _SOLVERS.popitem(last=False)
    return solver


def _numpy(x) -> np.ndarray:
    return x.detach().cpu().numpy() if isinstance(x, torch.Tensor) else np.asarray(x)
