"""The closed-form best rotations of :func:`drapebench.geometry.arap.best_rotations` as one warp kernel (float64,
compiled C++ on the CPU): the same arithmetic per matrix (Horn's quaternion, Newton's method on the
characteristic polynomial from the upper bound of ``best_rotations``, the eigenvector a column of the adjugate), in one loop instead of
a few hundred numpy passes over the whole array: about a third of numpy's time on a 2.8k-vertex garment (0.22
against 0.64 ms), equal to rounding. Imported on first use by :mod:`drapebench.geometry.arap` (it needs warp, the ``sim`` extra).
"""

from __future__ import annotations

import threading

import numpy as np

from drapebench.warp_env import wp

_LOAD_LOCK = threading.Lock()  # a module compiles or loads once, whichever thread asks first


@wp.func
def _others(k: int):
    """The three indices of 0..3 other than k, in order."""
    i0, i1, i2 = 1, 2, 3
    if k > 0:
        i0 = 0
    if k > 1:
        i1 = 1
    if k > 2:
        i2 = 2
    return i0, i1, i2


@wp.func
def _minor(a: wp.mat44d, r: int, c: int) -> wp.float64:
    """Determinant of the 3x3 matrix of ``a`` without row r and column c."""
    r0, r1, r2 = _others(r)
    c0, c1, c2 = _others(c)
    return (a[r0, c0] * (a[r1, c1] * a[r2, c2] - a[r1, c2] * a[r2, c1])
            - a[r0, c1] * (a[r1, c0] * a[r2, c2] - a[r1, c2] * a[r2, c0])
            + a[r0, c2] * (a[r1, c0] * a[r2, c1] - a[r1, c1] * a[r2, c0]))  # fmt: skip


@wp.kernel
def _best_rotations(M: wp.array(dtype=wp.mat33d), max_newton: int, R: wp.array(dtype=wp.mat33d)):
    k = wp.tid()
    s = wp.transpose(M[k])  # s[i, j] = M[k][j, i]: the rest edges' covariance with the deformed ones
    xx, xy, xz = s[0, 0], s[0, 1], s[0, 2]
    yx, yy, yz = s[1, 0], s[1, 1], s[1, 2]
    zx, zy, zz = s[2, 0], s[2, 1], s[2, 2]
    n = wp.mat44d(xx + yy + zz, yz - zy, zx - xz, xy - yx,
                  yz - zy, xx - yy - zz, xy + yx, zx + xz,
                  zx - xz, xy + yx, -xx + yy - zz, yz + zy,
                  xy - yx, zx + xz, yz + zy, -xx - yy + zz)  # fmt: skip
    f2 = wp.float64(0.0)
    for i in range(3):
        for j in range(3):
            f2 += s[i, j] * s[i, j]
    kk = wp.transpose(s) * s
    sum_k2 = wp.float64(0.0)
    for i in range(3):
        for j in range(3):
            sum_k2 += kk[i, j] * kk[i, j]
    c2 = wp.float64(-2.0) * f2  # characteristic polynomial lambda^4 + c2 lambda^2 + c1 lambda + c0
    c1 = wp.float64(-8.0) * (xx * (yy * zz - yz * zy) - xy * (yx * zz - yz * zx) + xz * (yx * zy - yy * zx))
    c0 = wp.float64(2.0) * sum_k2 - f2 * f2
    e2 = wp.max((f2 * f2 - sum_k2) * wp.float64(0.5), wp.float64(0.0))  # sum_{i<j} s_i^2 s_j^2
    lam = wp.sqrt(f2 + wp.float64(2.0) * wp.sqrt(e2 + wp.float64(0.25) * wp.abs(c1) * wp.sqrt(wp.float64(3.0) * f2)))  # >= the top root (arap.py)
    tol = wp.float64(1e-15) * wp.sqrt(f2)
    for _ in range(max_newton):
        l2 = lam * lam
        slope = (wp.float64(4.0) * l2 + wp.float64(2.0) * c2) * lam + c1
        step = wp.float64(0.0)
        if slope > wp.float64(0.0):
            step = ((l2 + c2) * l2 + c1 * lam + c0) / slope
        lam = lam - step
        if not (wp.abs(step) > tol):
            break
    for i in range(4):
        n[i, i] = n[i, i] - lam
    # rank one at the eigenvalue: every column of the adjugate is a multiple of the eigenvector; take the one of the largest diagonal entry
    col = int(0)
    best = wp.abs(_minor(n, 0, 0))
    for i in range(1, 4):
        d = wp.abs(_minor(n, i, i))
        if d > best:
            best = d
            col = i
    q = wp.vec4d()
    for i in range(4):
        sign = wp.float64(1.0)
        if (i + col) % 2 == 1:
            sign = wp.float64(-1.0)
        q[i] = sign * _minor(n, col, i)
    q = q / wp.max(wp.length(q), wp.float64(1e-300))
    w, x, y, z = q[0], q[1], q[2], q[3]
    one, two = wp.float64(1.0), wp.float64(2.0)
    R[k] = wp.mat33d(one - two * (y * y + z * z), two * (x * y - w * z), two * (x * z + w * y),
                     two * (x * y + w * z), one - two * (x * x + z * z), two * (y * z - w * x),
                     two * (x * z - w * y), two * (y * z + w * x), one - two * (x * x + y * y))  # fmt: skip


def best_rotations(M: np.ndarray, max_newton: int = 50) -> np.ndarray:
    """(N, 3, 3) float64 rotations for covariances M (N, 3, 3): :func:`drapebench.geometry.arap.best_rotations`
    computed by the warp kernel on the CPU (the kernel runs without the GIL)."""
    M = np.ascontiguousarray(M, dtype=np.float64)
    R = np.empty_like(M)
    if len(M) == 0:
        return R
    with _LOAD_LOCK:
        _best_rotations.module.load(wp.get_device("cpu"))
    wp.launch(_best_rotations, dim=len(M), inputs=[wp.array(M, dtype=wp.mat33d, device="cpu", copy=False), int(max_newton)],
              outputs=[wp.array(R, dtype=wp.mat33d, device="cpu", copy=False)], device="cpu")  # fmt: skip
    return R
