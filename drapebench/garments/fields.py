"""Implicit fields on a voxel grid around the canonical body: signed distance, morphological
closing (fills armpits/crotch), and the convex-hull loft that loose garments hang as.

Recipe measured in ``../shared/notes/garment_construction.md``; all heights come from the body's joints.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter1d
from scipy.spatial import ConvexHull

from drapebench.cache import atomic_write, cache_dir, content_hash


@dataclass
class Grid:
    """Regular grid: ``lo`` (3,) corner (m), ``h`` spacing (m), ``shape`` (nx, ny, nz)."""

    lo: np.ndarray
    h: float
    shape: tuple

    def points(self) -> np.ndarray:
        axes = [self.lo[i] + self.h * np.arange(self.shape[i]) for i in range(3)]
        return np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)


def body_grid(vertices: np.ndarray, h: float, margin: float = 0.08) -> Grid:
    """A grid of spacing ``h`` covering the body's bounding box plus ``margin``."""
    lo = vertices.min(0) - margin
    hi = vertices.max(0) + margin
    shape = tuple(int(np.ceil((hi[i] - lo[i]) / h)) + 1 for i in range(3))
    return Grid(lo, h, shape)


def signed_distance_grid(vertices: np.ndarray, faces: np.ndarray, h: float) -> tuple[Grid, np.ndarray]:
    """Signed distance (m, negative inside; winding-number sign) of the body on a grid, cached by content hash."""
    import igl

    grid = body_grid(vertices, h)
    key = content_hash(vertices.astype(np.float32), faces.astype(np.int64), h)
    path = cache_dir("garments") / f"sdf_{key}.npz"
    if path.exists():
        try:
            with np.load(path) as z:
                return grid, z["sdf"].astype(np.float64)
        except (OSError, ValueError, KeyError):
            pass  # corrupt cache entry: recompute
    P = grid.points()
    d = igl.signed_distance(P, vertices.astype(np.float64), faces.astype(np.int64),
                            sign_type=igl.SIGNED_DISTANCE_TYPE_FAST_WINDING_NUMBER)[0]  # fmt: skip
    sdf = np.asarray(d).reshape(grid.shape)
    with atomic_write(path) as f:
        np.savez_compressed(f, sdf=sdf.astype(np.float32))
    return grid, sdf


def marching_cubes(field: np.ndarray, grid: Grid, level: float) -> tuple[np.ndarray, np.ndarray]:
    """Level set {field = level} as (V, 3) vertices and (F, 3) faces, normals pointing to increasing field."""
    from skimage.measure import marching_cubes as mc

    v, f, _, _ = mc(field, level, spacing=(grid.h,) * 3)
    return v + grid.lo, f.astype(np.int64)


def closed_field(sdf: np.ndarray, grid: Grid, radius: float) -> np.ndarray:
    """Signed distance to the body morphologically closed by ``radius`` (fills concave creases
    narrower than ~2 x radius, e.g. armpits); equals ``sdf`` away from the closing band."""
    import igl

    if radius <= 0:
        return sdf
    V, F = marching_cubes(sdf, grid, radius)
    band = (sdf > -0.03) & (sdf < radius)
    P = grid.points().reshape(*grid.shape, 3)[band]
    e2 = igl.point_mesh_squared_distance(P, V, F)[0]
    out = sdf.copy()
    out[band] = np.minimum(sdf[band], radius - np.sqrt(np.asarray(e2)))
    # points inside the dilated shell but not reached by the band keep their (larger) body distance
    return out


def loft_field(
    grid: Grid,
    body_vertices: np.ndarray,
    keep: np.ndarray,
    centre_xy: np.ndarray,
    z_top: float,
    z_widest_search: tuple[float, float],
    offset: float,
    flare: float,
    n_theta: int = 180,
    dz: float = 0.01,
) -> np.ndarray:
    """Field r_xy - R(theta, z) of a skirt-like loft around the body (negative inside the loft).

    R is the radius of per-slice 2D convex hulls of the ``keep`` body vertices (legs and torso, not
    arms) plus ``offset``; below the widest slice in ``z_widest_search`` it takes a running maximum
    going down plus ``flare`` metres per metre, so the surface hangs as one piece past both legs.
    """
    pts = body_vertices[keep]
    z_levels = np.arange(z_top + 0.05, grid.lo[2] - dz, -dz)  # top to bottom
    theta = np.linspace(-np.pi, np.pi, n_theta, endpoint=False)
    dirs = np.stack([np.cos(theta), np.sin(theta)], 1)
    R = np.full((len(z_levels), n_theta), np.nan)
    for k, z in enumerate(z_levels):
        sl = pts[np.abs(pts[:, 2] - z) < dz]
        if len(sl) < 8:
            continue
        try:
            hull = ConvexHull(sl[:, :2] - centre_xy)
        except Exception:  # degenerate slice (collinear points)
            continue
        n, off = hull.equations[:, :2], hull.equations[:, 2]
        if (off > 0).any():  # centre outside this slice's hull: leave it to the running maximum
            continue
        nd = dirs @ n.T
        with np.errstate(divide="ignore"):
            r = np.where(nd > 1e-9, -off / nd, np.inf).min(1)
        R[k] = r + offset
    lo_w, hi_w = z_widest_search
    in_win = (z_levels <= hi_w) & (z_levels >= lo_w) & np.isfinite(R).all(1)
    if not in_win.any():
        raise ValueError("no valid body slice in the hip window; is the body in its rest pose?")
    widest = np.flatnonzero(in_win)[np.argmax(np.nanmean(R[in_win], 1))]
    # above the widest slice: follow the body; below: running max downwards plus flare
    for k in range(1, len(z_levels)):
        if k > widest:
            base = R[k - 1] if np.isfinite(R[k - 1]).all() else R[widest]
            cur = R[k] if np.isfinite(R[k]).all() else base
            R[k] = np.maximum(base, cur) + flare * dz
        elif not np.isfinite(R[k]).all():
            R[k] = R[k - 1]
    R[0] = np.where(np.isfinite(R[0]), R[0], R[np.isfinite(R).all(1)][0])
    R = gaussian_filter1d(gaussian_filter1d(R, 2.0, axis=1, mode="wrap"), 1.5, axis=0, mode="nearest")
    P = grid.points()
    rel = P[:, :2] - centre_xy
    r = np.linalg.norm(rel, axis=1)
    th = np.arctan2(rel[:, 1], rel[:, 0])
    ti = (th + np.pi) / (2 * np.pi) * n_theta
    t0 = np.floor(ti).astype(int) % n_theta
    t1 = (t0 + 1) % n_theta
    wt = ti - np.floor(ti)
    zi = np.clip((z_levels[0] - P[:, 2]) / dz, 0, len(z_levels) - 1.0001)
    z0 = np.floor(zi).astype(int)
    wz = zi - z0
    Rz0 = R[z0, t0] * (1 - wt) + R[z0, t1] * wt
    Rz1 = R[z0 + 1, t0] * (1 - wt) + R[z0 + 1, t1] * wt
    return (r - (Rz0 * (1 - wz) + Rz1 * wz)).reshape(grid.shape)
