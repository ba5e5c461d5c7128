"""As-rigid-as-possible deformation (Sorkine & Alexa 2007) of a triangle mesh with handle constraints.

Two solvers of the same energy, libigl's default for triangle meshes in 3-D ("spokes and rims": vertex i's
rotation fits every edge of the triangles around it, cotangent weights), same interface:

- :class:`SparseArapSolver` (backend ``"sparse"``): scipy. The covariance of every vertex and the global
  step's right-hand side are fixed sparse maps of the positions and of the rotations (built once per rest
  mesh, :class:`ArapMesh`), the rotations come from a closed form (:func:`best_rotations`, exact in float64;
  one warp kernel where warp is installed, vectorised numpy otherwise), and the global step is a sparse LU of the free block of the cotangent Laplacian, factorized
  once per handle set.
- :class:`ArapSolver` (backend ``"libigl"``): ``igl.arap_precomputation`` / ``igl.arap_solve``. Its
  rotations come from a single-precision 3x3 SVD (McAdams et al.), so the two differ by that SVD's error:
  a few micrometres on average on a garment, up to tens at vertices of near-planar 1-rings
  (``tests/geometry/test_arap.py``).

:func:`arap_solver` keeps the last few factorizations, keyed by content, so a handle set that comes back
(a static scene, a repeated frame) is not factorized again.
"""

from __future__ import annotations

from collections import OrderedDict
from functools import cache

import numpy as np
import scipy.sparse as sp
import torch
from scipy.sparse.linalg import splu

from drapebench.cache import content_hash
from drapebench.extras import MissingExtra

BACKENDS = ("sparse", "libigl")


def _checked(rest_vertices, faces, handles, iterations) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rest vertices (V, 3) float64, faces (F, 3) int64, handles (H,) int64, or a ValueError naming the problem."""
    V = np.ascontiguousarray(_numpy(rest_vertices), dtype=np.float64)
    F = np.ascontiguousarray(_numpy(faces), dtype=np.int64)
    b = np.ascontiguousarray(_numpy(handles), dtype=np.int64).reshape(-1)
    if len(b) == 0:
        raise ValueError("ARAP needs at least one handle vertex; without handles the solution is only defined up to a rigid motion")
    if b.min() < 0 or b.max() >= len(V):
        raise ValueError(f"handle indices must be in [0, {len(V)}), got [{b.min()}, {b.max()}]")
    if iterations < 1:
        raise ValueError(f"iterations must be >= 1, got {iterations}")
    return V, F, b


class ArapSolver:
    """ARAP of a rest mesh with a fixed handle set, by libigl.

    rest_vertices (V, 3) m and faces (F, 3) define the rest shape; handles (H,) are the constrained
    vertex indices (at least one); ``iterations`` local-global iterations per :meth:`solve`.
    """

    def __init__(self, rest_vertices, faces, handles, iterations: int = 2):
        import igl

        V, F, b = _checked(rest_vertices, faces, handles, iterations)
        self.n_vertices, self.handles = len(V), b.astype(np.int32)
        self.data = igl.ARAPData()
        self.data.max_iter = int(iterations)
        igl.arap_precomputation(V, F, 3, self.handles, self.data)

    def solve(self, handle_positions, initial):
        """(V, 3) float64 positions: handles at ``handle_positions`` (H, 3), the rest as rigid as possible,
        starting from ``initial`` (V, 3)."""
        import igl

        bc = np.ascontiguousarray(_numpy(handle_positions), dtype=np.float64).reshape(len(self.handles), 3)
        U = np.ascontiguousarray(_numpy(initial), dtype=np.float64).reshape(self.n_vertices, 3)
        return igl.arap_solve(bc, self.data, U)


class ArapMesh:
    """What the sparse solver needs of a rest mesh, whatever the handles: the cotangent Laplacian's negative
    A (V, V) (the global step's matrix), ``scatter`` (3V, V): the covariance of vertex i,
    M_i = sum w_e (U_e0 - U_e1) (V_e0 - V_e1)^T over the edges e of its triangles, is column c of
    ``(scatter @ U).reshape(3, V, 3)[c]``; ``rhs`` (V, 3V): the global step's right-hand side B = rhs @ X
    with X[3i + c, a] = R_i[a, c], each triangle's edges fitted by the mean rotation of its corners."""

    def __init__(self, rest_vertices: np.ndarray, faces: np.ndarray):
        import igl

        V, F = rest_vertices, faces
        n, nf = len(V), len(F)
        w = igl.cotmatrix_entries(V, F)  # (F, 3): half the cotangent opposite edges (1, 2), (2, 0), (0, 1)
        e0, e1 = F[:, [1, 2, 0]], F[:, [2, 0, 1]]  # (F, 3) the edges' ends
        dv = V[e0] - V[e1]  # (F, 3, 3) rest edge vectors
        self.A = (-igl.cotmatrix(V, F)).tocsc()
        # every (triangle corner i, edge e of that triangle) pair: rows i, columns e0 (+) and e1 (-)
        corner = np.repeat(F[:, :, None], 3, axis=2)  # (F, 3 corners, 3 edges)
        wd = w[:, None, :, None] * dv[:, None, :, :]  # (F, 1, 3 edges, 3 c)
        wd = np.broadcast_to(wd, (nf, 3, 3, 3))
        rows = np.concatenate([c * n + corner for c in range(3)], axis=None)
        rows = np.concatenate([rows, rows])
        cols = np.concatenate([np.broadcast_to(e0[:, None, :], (nf, 3, 3)).ravel()] * 3 + [np.broadcast_to(e1[:, None, :], (nf, 3, 3)).ravel()] * 3)
        vals = np.concatenate([wd[..., c].ravel() for c in range(3)])
        self.scatter = sp.csr_matrix((np.concatenate([vals, -vals]), (rows, cols)), shape=(3 * n, n))
        # right-hand side: B[e0] += w R_f dv / 3 summed over the triangle's corners (R_f their mean), B[e1] -= it
        r_rows = np.broadcast_to(np.stack([e0, e1], -1)[:, None, :, :, None], (nf, 3, 3, 2, 3))  # (F, corner, edge, end, c)
        r_cols = 3 * corner[:, :, :, None, None] + np.arange(3)[None, None, None, None, :]
        r_cols = np.broadcast_to(r_cols, (nf, 3, 3, 2, 3))
        r_vals = (w[:, None, :, None, None] * dv[:, None, :, None, :] / 3.0) * np.array([1.0, -1.0])[None, None, None, :, None]
        r_vals = np.broadcast_to(r_vals, (nf, 3, 3, 2, 3))
        self.rhs = sp.csr_matrix((r_vals.ravel(), (r_rows.ravel(), r_cols.ravel())), shape=(n, 3 * n))
        self.n_vertices = n


# The adjugate of a 4x4 matrix from its 2x2 minors: minors 0-5 of rows (0, 1), 6-11 of rows (2, 3), both over the
# column pairs _PAIRS; adj[i][j] (row-major entry e = 4 i + j) = sum of sign x a[r][c] x minor[k] over its three terms.
_PAIRS = np.array(((0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)))
_ADJUGATE = np.array((
    ((1, 1, 1, 11), (-1, 1, 2, 10), (1, 1, 3, 9)), ((-1, 0, 1, 11), (1, 0, 2, 10), (-1, 0, 3, 9)),
    ((1, 3, 1, 5), (-1, 3, 2, 4), (1, 3, 3, 3)), ((-1, 2, 1, 5), (1, 2, 2, 4), (-1, 2, 3, 3)),
    ((-1, 1, 0, 11), (1, 1, 2, 8), (-1, 1, 3, 7)), ((1, 0, 0, 11), (-1, 0, 2, 8), (1, 0, 3, 7)),
    ((-1, 3, 0, 5), (1, 3, 2, 2), (-1, 3, 3, 1)), ((1, 2, 0, 5), (-1, 2, 2, 2), (1, 2, 3, 1)),
    ((1, 1, 0, 10), (-1, 1, 1, 8), (1, 1, 3, 6)), ((-1, 0, 0, 10), (1, 0, 1, 8), (-1, 0, 3, 6)),
    ((1, 3, 0, 4), (-1, 3, 1, 2), (1, 3, 3, 0)), ((-1, 2, 0, 4), (1, 2, 1, 2), (-1, 2, 3, 0)),
    ((-1, 1, 0, 9), (1, 1, 1, 7), (-1, 1, 2, 6)), ((1, 0, 0, 9), (-1, 0, 1, 7), (1, 0, 2, 6)),
    ((-1, 3, 0, 3), (1, 3, 1, 1), (-1, 3, 2, 0)), ((1, 2, 0, 3), (-1, 2, 1, 1), (1, 2, 2, 0)),
))  # fmt: skip


def _adjugate(a: np.ndarray) -> np.ndarray:
    """Adjugates (16, n) (row-major entries) of n 4x4 matrices stored entry-major, a (4, 4, n)."""
    i, j = _PAIRS[:, 0], _PAIRS[:, 1]
    minors = np.concatenate([a[0, i] * a[1, j] - a[1, i] * a[0, j], a[2, i] * a[3, j] - a[3, i] * a[2, j]])  # (12, n)
    sign, r, c, k = _ADJUGATE.transpose(2, 1, 0)[..., None]  # (3 terms, 16, 1) each
    out = a[r[0, :, 0], c[0, :, 0]] * minors[k[0, :, 0]] * sign[0]
    for t in (1, 2):  # term by term: (16, n) temporaries, not one (16, 3, n)
        term = a[r[t, :, 0], c[t, :, 0]]
        term *= minors[k[t, :, 0]]
        term *= sign[t]
        out += term
    return out


def best_rotations(M: np.ndarray, max_newton: int = 50) -> np.ndarray:
    """(N, 3, 3) rotations R maximising trace(R^T M_k) for covariances M (N, 3, 3): the polar factor of M with
    det(R) = +1, i.e. U diag(1, 1, det(U V^T)) V^T of M's SVD, in closed form for all N at once (Horn's
    quaternion as the top eigenvector of a traceless symmetric 4x4 matrix; its eigenvalue by Newton's method
    on the characteristic polynomial from an upper bound (M's nuclear norm bounded above), where it converges monotonically
    (Theobald 2005), at most ``max_newton`` steps; the eigenvector a column of the adjugate). Agrees with the
    SVD to float64 rounding unless the top eigenvalue is (nearly) double, where the rotation is itself
    (nearly) undetermined (M of rank <= 1, or a reflection with sigma_2 = sigma_3)."""
    S = M.transpose(2, 1, 0)  # S[i, j] = M[:, j, i], (3, 3, N): the rest edges' covariance with the deformed ones
    (xx, xy, xz), (yx, yy, yz), (zx, zy, zz) = S
    N = np.empty((4, 4, len(M)))
    N[0, 0], N[1, 1], N[2, 2], N[3, 3] = xx + yy + zz, xx - yy - zz, -xx + yy - zz, -xx - yy + zz
    N[0, 1], N[0, 2], N[0, 3] = yz - zy, zx - xz, xy - yx
    N[1, 2], N[1, 3], N[2, 3] = xy + yx, zx + xz, yz + zy
    N[1, 0], N[2, 0], N[3, 0], N[2, 1], N[3, 1], N[3, 2] = N[0, 1], N[0, 2], N[0, 3], N[1, 2], N[1, 3], N[2, 3]
    f2 = (S * S).sum((0, 1))
    c2 = -2.0 * f2  # characteristic polynomial lambda^4 + c2 lambda^2 + c1 lambda + c0
    c1 = -8.0 * (xx * (yy * zz - yz * zy) - xy * (yx * zz - yz * zx) + xz * (yx * zy - yy * zx))
    K = [[sum(S[i, a] * S[i, b] for i in range(3)) for b in range(3)] for a in range(3)]  # S^T S
    c0 = 2.0 * sum(K[a][b] * K[a][b] for a in range(3) for b in range(3)) - f2 * f2  # det N = sum s^4 - 2 sum_{i<j} s_i^2 s_j^2
    # start: the nuclear norm s1 + s2 + s3 = sqrt(f2 + 2 p) >= lambda (= s1 + s2 + sign(det M) s3), with
    # p = sum_{i<j} s_i s_j = sqrt(e2 + 2 |det M| (s1 + s2 + s3)) bounded by s1 + s2 + s3 <= sqrt(3 f2):
    # exact for a flat 1-ring (det M = 0) and for a scaled rotation, where sqrt(3 f2) alone is 22-73 % and 0 % high
    e2 = np.maximum(0.5 * (f2 * f2 - (c0 + f2 * f2) / 2.0), 0.0)  # sum_{i<j} s_i^2 s_j^2 (sum K^2 = (c0 + f2^2) / 2)
    lam = np.sqrt(f2 + 2.0 * np.sqrt(e2 + 0.25 * np.abs(c1) * np.sqrt(3.0 * f2)))
    tol = 1e-15 * np.sqrt(f2)
    for _ in range(max_newton):
        l2 = lam * lam
        slope = (4.0 * l2 + 2.0 * c2) * lam + c1
        step = np.where(slope > 0, ((l2 + c2) * l2 + c1 * lam + c0) / np.where(slope > 0, slope, 1.0), 0.0)
        lam = lam - step
        if not (np.abs(step) > tol).any():
            break
    for i in range(4):
        N[i, i] -= lam
    adj = _adjugate(N)  # rank one at the eigenvalue: every column is a multiple of the eigenvector
    k = np.argmax(np.abs(adj[[0, 5, 10, 15]]), axis=0)
    q = np.take_along_axis(adj.reshape(4, 4, -1), k[None, None], axis=1)[:, 0]
    w, x, y, z = q / np.maximum(np.sqrt((q * q).sum(0)), 1e-300)
    R = np.empty((len(M), 3, 3))
    R[:, 0, 0], R[:, 0, 1], R[:, 0, 2] = 1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)
    R[:, 1, 0], R[:, 1, 1], R[:, 1, 2] = 2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)
    R[:, 2, 0], R[:, 2, 1], R[:, 2, 2] = 2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)
    return R


@cache
def _rotation_kernels():
    """:mod:`drapebench.geometry.rotation_kernels` (warp, the ``sim`` extra), imported on first use; None without warp."""
    try:
        from drapebench.geometry import rotation_kernels
    except MissingExtra:
        return None
    return rotation_kernels


def _rotations(M: np.ndarray) -> np.ndarray:
    """:func:`best_rotations` of M (N, 3, 3), by its warp kernel where warp is installed (the same values to
    rounding, a third of the time on a garment), else by numpy."""
    kernels = _rotation_kernels()
    return best_rotations(M) if kernels is None else kernels.best_rotations(M)


class SparseArapSolver:
    """ARAP of a rest mesh with a fixed handle set, by sparse matrices (the module docstring); the same
    interface and result as :class:`ArapSolver` (libigl) up to libigl's single-precision SVD."""

    def __init__(self, rest_vertices, faces, handles, iterations: int = 2, mesh: ArapMesh | None = None):
        V, F, b = _checked(rest_vertices, faces, handles, iterations)
        self.mesh = mesh if mesh is not None else ArapMesh(V, F)
        self._order = np.argsort(b, kind="stable")  # handle rows as given -> sorted
        self.n_vertices, self.handles, self.iterations = len(V), b[self._order], int(iterations)
        if (np.diff(self.handles) == 0).any():
            raise ValueError("ARAP handle indices must be distinct")
        free = np.ones(len(V), dtype=bool)
        free[self.handles] = False
        self.free = np.nonzero(free)[0]
        A = self.mesh.A
        self.A_fb = A[self.free][:, self.handles].tocsr()
        self.lu = splu(A[self.free][:, self.free].tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                       options=dict(SymmetricMode=True)) if len(self.free) else None  # fmt: skip

    def solve(self, handle_positions, initial):
        """(V, 3) float64 positions: handles at ``handle_positions`` (H, 3), the rest as rigid as possible,
        starting from ``initial`` (V, 3); ``iterations`` local-global iterations, as libigl's ``arap_solve``."""
        n = self.n_vertices
        bc = np.asarray(_numpy(handle_positions), dtype=np.float64).reshape(-1, 3)[self._order]
        U = np.array(_numpy(initial), dtype=np.float64).reshape(n, 3)
        U[self.handles] = bc
        if self.lu is None:
            return U
        fixed = self.A_fb @ bc
        for _ in range(self.iterations):
            M = np.ascontiguousarray((self.mesh.scatter @ U).reshape(3, n, 3).transpose(1, 2, 0))  # (V, 3 a, 3 c)
            R = _rotations(M)
            B = self.mesh.rhs @ R.transpose(0, 2, 1).reshape(3 * n, 3)
            U[self.free] = self.lu.solve(np.ascontiguousarray(B[self.free] - fixed))
        return U


_SOLVERS: OrderedDict[str, ArapSolver | SparseArapSolver] = OrderedDict()
_MESHES: OrderedDict[str, ArapMesh] = OrderedDict()
_MAX_SOLVERS = 8


def arap_solver(rest_vertices, faces, handles, iterations: int = 2, backend: str = "sparse") -> ArapSolver | SparseArapSolver:
    """A :class:`SparseArapSolver` (``backend`` "sparse") or :class:`ArapSolver` ("libigl"), reused when the
    same rest mesh, handle set, iterations and backend come back (the sparse backend also keeps each rest
    mesh's :class:`ArapMesh`)."""
    if backend not in BACKENDS:
        raise ValueError(f"ARAP backend must be one of {BACKENDS}, not {backend!r}")
    mesh_key = content_hash(_numpy(rest_vertices), _numpy(faces))
    key = content_hash(mesh_key, _numpy(handles).astype(np.int64), iterations, backend)
    solver = _SOLVERS.pop(key, None)
    if solver is None and backend == "libigl":
        solver = ArapSolver(rest_vertices, faces, handles, iterations)
    elif solver is None:
        mesh = _MESHES.pop(mesh_key, None)
        if mesh is None:
            V, F, _ = _checked(rest_vertices, faces, handles, iterations)
            mesh = ArapMesh(V, F)
        _MESHES[mesh_key] = mesh
        while len(_MESHES) > _MAX_SOLVERS:
            _MESHES.popitem(last=False)
        solver = SparseArapSolver(rest_vertices, faces, handles, iterations, mesh)
    _SOLVERS[key] = solver
    while len(_SOLVERS) > _MAX_SOLVERS:
        _SOLVERS.popitem(last=False)
    return solver


def _numpy(x) -> np.ndarray:
    return x.detach().cpu().numpy() if isinstance(x, torch.Tensor) else np.asarray(x)
