"""Implicit fields on a voxel grid around the canonical body: signed distance, morphological
closing (fills armpits/crotch), and the convex-hull loft that loose garments hang as.

Recipe measured in ``docs/references.md``; all heights come from the body's joints.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter1d
from scipy.spatial import ConvexHull

from drapebench.cache import Cache

SDF_BAND = (-0.015, 0.055)  # (m) where the grid SDF is exact; elsewhere it is a bound-respecting estimate
SDF_GRIDS = Cache("sdf", 2)  # bump when the grid construction changes


@dataclass
class Grid:
    """Regular grid: ``lo`` (3,) corner (m), ``h`` spacing (m), ``shape`` (nx, ny, nz)."""

    lo: np.ndarray
    h: float
    shape: tuple

    def axes(self) -> list[np.ndarray]:
        """Node coordinates (m) along x, y and z."""
        return [self.lo[i] + self.h * np.arange(self.shape[i]) for i in range(3)]

    def points(self, index: tuple | None = None) -> np.ndarray:
        """(N, 3) node positions (m), all in C order, or those of ``index`` (a tuple of index arrays as
        from ``np.nonzero``)."""
        if index is not None:
            return self.lo + self.h * np.stack(index, 1).astype(np.float64)
        return np.stack(np.meshgrid(*self.axes(), indexing="ij"), -1).reshape(-1, 3)


def body_grid(vertices: np.ndarray, h: float, margin: float = 0.08, multiple: int = 1) -> Grid:
    """A grid of spacing ``h`` covering the body's bounding box plus ``margin``; each dimension has
    ``k * multiple + 1`` nodes so a grid ``multiple`` times coarser shares its corner nodes."""
    lo = vertices.min(0) - margin
    hi = vertices.max(0) + margin
    shape = tuple(int(np.ceil((hi[i] - lo[i]) / (h * multiple))) * multiple + 1 for i in range(3))
    return Grid(lo, h, shape)


def _exact_sdf(P: np.ndarray, vertices: np.ndarray, faces: np.ndarray, sign: np.ndarray | None = None) -> np.ndarray:
    """Exact signed distance (m) of points P (N, 3) to the mesh; ``sign`` (N,) +-1 where already known
    (then only the unsigned distance is computed), 0 where the winding number must decide."""
    import igl

    if len(P) == 0:
        return np.zeros(0)
    if sign is None:
        sign = np.zeros(len(P))
    sign = sign.copy()
    open_ = sign == 0
    if open_.any():
        sign[open_] = np.where(igl.fast_winding_number(vertices, faces, np.ascontiguousarray(P[open_])) > 0.5, -1.0, 1.0)
    out = np.sqrt(np.asarray(igl.point_mesh_squared_distance(P, vertices, faces)[0])) * sign
    return out


def _refine(lower_c, upper_c, estimate_c, grid: Grid, vertices, faces, band):
    """One level of narrow-band refinement. The coarse arrays hold, on every second node of
    ``grid``, bounds and an estimate of the SDF (all equal where it was computed exactly). Each fine
    node gets bounds from its cell's 8 corners by the 1-Lipschitz property (d(p) in
    [lower_i - |p - x_i|, upper_i + |p - x_i|]); nodes whose bounds reach ``band`` are computed
    exactly, the rest take the trilinear estimate clipped to their bounds. Returns fine (lower, upper, estimate)."""
    nc = estimate_c.shape
    H = 2 * grid.h
    idx = [np.arange(n) for n in grid.shape]
    cell = [np.minimum(i // 2, m - 2) for i, m in zip(idx, nc)]
    t = [((i - 2 * c) / 2.0).astype(np.float32) for i, c in zip(idx, cell)]
    lower = np.full(grid.shape, -np.inf, dtype=np.float32)
    upper = np.full(grid.shape, np.inf, dtype=np.float32)
    estimate = np.zeros(grid.shape, dtype=np.float32)
    for a in (0, 1):
        for b in (0, 1):
            for c in (0, 1):
                corner = np.ix_(cell[0] + a, cell[1] + b, cell[2] + c)
                dx, dy, dz = np.ix_((t[0] - a) ** 2, (t[1] - b) ** 2, (t[2] - c) ** 2)
                dist = np.float32(H) * np.sqrt(dx + dy + dz)
                np.maximum(lower, lower_c[corner] - dist, out=lower)
                np.minimum(upper, upper_c[corner] + dist, out=upper)
                wx, wy, wz = np.ix_(np.abs(1 - a - t[0]), np.abs(1 - b - t[1]), np.abs(1 - c - t[2]))
                estimate += (wx * wy * wz) * estimate_c[corner]
    np.clip(estimate, lower, upper, out=estimate)
    where = np.nonzero((upper >= band[0]) & (lower <= band[1]))
    sign = np.where(lower[where] > 0, 1.0, np.where(upper[where] < 0, -1.0, 0.0))
    exact = _exact_sdf(grid.points(where), vertices, faces, sign)
    lower[where] = upper[where] = estimate[where] = exact
    return lower, upper, estimate


def signed_distance_grid(vertices: np.ndarray, faces: np.ndarray, h: float, levels: int | None = None) -> tuple[Grid, np.ndarray]:
    """Signed distance (m, negative inside; winding-number sign) of the body on a grid of spacing
    ``h`` (m), cached by content hash.

    Exact within ``SDF_BAND`` of the surface (the offsets and closings the factory uses); farther away
    a trilinear estimate kept within the distance function's Lipschitz bounds, so its sign and its
    side of the band are right. Computed coarse-to-fine over ``levels`` halvings of the spacing,
    evaluating exactly only the nodes that may lie in the band (default: the coarsest spacing ~4 cm).
    """
    if levels is None:
        levels = max(2, int(round(np.log2(0.04 / h))) + 1)
    grid = body_grid(vertices, h, multiple=2 ** (levels - 1))
    V, F = vertices.astype(np.float64), faces.astype(np.int64)
    path = SDF_GRIDS.path(V.astype(np.float32), F, h, levels, SDF_BAND, suffix=".npy")

    def build() -> np.ndarray:
        step = 2 ** (levels - 1)
        coarse = Grid(grid.lo, h * step, tuple((n - 1) // step + 1 for n in grid.shape))
        sdf = _exact_sdf(coarse.points(), V, F).reshape(coarse.shape).astype(np.float32)
        lower = upper = sdf
        for level in range(levels - 2, -1, -1):
            s = 2**level
            fine = Grid(grid.lo, h * s, tuple((n - 1) // s + 1 for n in grid.shape))
            lower, upper, sdf = _refine(lower, upper, sdf, fine, V, F, SDF_BAND)
        return sdf

    def read(p) -> np.ndarray | None:
        sdf = np.load(p, allow_pickle=False)
        return sdf if sdf.shape == grid.shape else None

    def write(sdf: np.ndarray, p) -> None:
        with open(p, "wb") as f:
            np.save(f, sdf)

    sdf = SDF_GRIDS.get_or_build(path, build, write, read)
    return grid, sdf.astype(np.float64)


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
    band = (sdf > SDF_BAND[0]) & (sdf < radius)
    P = grid.points(np.nonzero(band))
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
    R[0] = np.where(np.isfinite(R[0]), R[0], R[np.isfinite(R).all(1)][0])  # slices without a hull copy the one above
    # above the widest slice: follow the body; below: running max downwards plus flare
    for k in range(1, len(z_levels)):
        if k > widest:
            base = R[k - 1] if np.isfinite(R[k - 1]).all() else R[widest]
            cur = R[k] if np.isfinite(R[k]).all() else base
            R[k] = np.maximum(base, cur) + flare * dz
        elif not np.isfinite(R[k]).all():
            R[k] = R[k - 1]
    R = gaussian_filter1d(gaussian_filter1d(R, 2.0, axis=1, mode="wrap"), 1.5, axis=0, mode="nearest")
    xs, ys, zs = grid.axes()
    rx, ry = np.meshgrid(xs - centre_xy[0], ys - centre_xy[1], indexing="ij")  # (nx, ny) columns
    r = np.hypot(rx, ry)
    ti = (np.arctan2(ry, rx) + np.pi) / (2 * np.pi) * n_theta
    t0 = np.floor(ti).astype(int) % n_theta
    t1 = (t0 + 1) % n_theta
    wt = ti - np.floor(ti)
    zi = np.clip((z_levels[0] - zs) / dz, 0, len(z_levels) - 1.0001)
    z0 = np.floor(zi).astype(int)
    wz = (zi - z0)[:, None]
    Rz = R[z0] * (1 - wz) + R[z0 + 1] * wz  # (nz, n_theta): the loft radius at each grid height
    radius = Rz[:, t0] * (1 - wt) + Rz[:, t1] * wt  # (nz, nx, ny)
    return r[:, :, None] - np.moveaxis(radius, 0, -1)
