"""Validity checks for garment meshes on the canonical body; every failure is named with indices."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree


@dataclass
class GarmentReport:
    """Named checks; ``failures`` maps check name -> message (with offending indices)."""

    stats: dict = field(default_factory=dict)
    failures: dict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return not self.failures

    def fail(self, name: str, message: str) -> None:
        self.failures[name] = message

    def __str__(self) -> str:
        if self.ok:
            return "garment ok: " + ", ".join(f"{k}={v}" for k, v in self.stats.items())
        return "garment failed checks:\n" + "\n".join(f"  - {k}: {v}" for k, v in self.failures.items())


def _first(idx, n=10) -> str:
    idx = np.asarray(idx).ravel()
    more = f" ... ({len(idx)} in all)" if len(idx) > n else ""
    return f"{idx[:n].tolist()}{more}"


def mesh_structure(V: np.ndarray, F: np.ndarray, report: GarmentReport) -> None:
    """Degenerate faces, duplicate and unreferenced vertices, non-manifold edges, inconsistent winding, boundary loops."""
    if F.size == 0:
        report.fail("empty", "the mesh has no faces")
        return
    if F.min() < 0 or F.max() >= len(V):
        report.fail("face_indices", f"faces index outside [0, {len(V)})")
        return
    if not np.isfinite(V).all():
        report.fail("nonfinite", f"vertices with NaN/Inf: {_first(np.flatnonzero(~np.isfinite(V).all(1)))}")
        return
    cross = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    area = 0.5 * np.linalg.norm(cross, axis=1)
    degenerate = np.flatnonzero((area < 1e-10) | (F[:, 0] == F[:, 1]) | (F[:, 1] == F[:, 2]) | (F[:, 0] == F[:, 2]))
    if len(degenerate):
        report.fail("degenerate_faces", f"zero-area faces {_first(degenerate)}")
    pairs = cKDTree(V).query_pairs(1e-7, output_type="ndarray")
    if len(pairs):
        report.fail("duplicate_vertices", f"coincident vertex pairs {_first(pairs[:, :2].tolist())}")
    unref = np.setdiff1d(np.arange(len(V)), np.unique(F))
    if len(unref):
        report.fail("unreferenced_vertices", f"vertices no face uses {_first(unref)}")
    a, b = F.ravel(), F[:, [1, 2, 0]].ravel()
    und = np.minimum(a, b) * len(V) + np.maximum(a, b)
    keys, counts = np.unique(und, return_counts=True)
    nonman = keys[counts > 2]
    if len(nonman):
        report.fail("non_manifold_edges", f"edges shared by > 2 faces {_first(np.stack([nonman // len(V), nonman % len(V)], 1).tolist())}")
    directed = a * len(V) + b
    d_keys, d_counts = np.unique(directed, return_counts=True)
    same_dir = d_keys[d_counts > 1]
    if len(same_dir):
        report.fail("inconsistent_winding", f"edges used twice in the same direction (flipped neighbours) {_first(np.stack([same_dir // len(V), same_dir % len(V)], 1).tolist())}")
    report.stats["boundary_edges"] = int((counts == 1).sum())
    report.stats["vertices"], report.stats["faces"] = len(V), len(F)


def boundary_loop_count(F: np.ndarray) -> int:
    """Number of boundary loops (closed chains of edges used by one face)."""
    a, b = F.ravel(), F[:, [1, 2, 0]].ravel()
    n = max(a.max(), b.max()) + 1
    und = np.minimum(a, b) * n + np.maximum(a, b)
    keys, counts = np.unique(und, return_counts=True)
    bnd = keys[counts == 1]
    if len(bnd) == 0:
        return 0
    import scipy.sparse
    from scipy.sparse.csgraph import connected_components

    i, j = bnd // n, bnd % n
    g = scipy.sparse.coo_matrix((np.ones(len(i)), (i, j)), shape=(n, n))
    ncomp, lab = connected_components(g, directed=False)
    return len(np.unique(lab[np.unique(np.concatenate([i, j]))]))


def triangle_quality(V: np.ndarray, F: np.ndarray, report: GarmentReport, target_edge: float | None) -> None:
    """At least 99 % of triangles with minimum angle >= 20 deg; mean edge within 15 % of the target."""
    e = [V[F[:, (k + 1) % 3]] - V[F[:, k]] for k in range(3)]
    ang = []
    for k in range(3):
        u, w = e[k], -e[(k + 2) % 3]
        c = (u * w).sum(1) / np.maximum(np.linalg.norm(u, axis=1) * np.linalg.norm(w, axis=1), 1e-30)
        ang.append(np.degrees(np.arccos(np.clip(c, -1, 1))))
    min_angle = np.min(ang, 0)
    share = float((min_angle >= 20).mean())
    report.stats["min_angle_ge20"] = round(share, 4)
    if share < 0.99:
        report.fail("triangle_quality", f"only {share:.1%} of triangles have min angle >= 20 deg; worst faces {_first(np.argsort(min_angle)[:10])}")
    mean_edge = float(np.mean([np.linalg.norm(x, axis=1).mean() for x in e]))
    report.stats["mean_edge_mm"] = round(mean_edge * 1e3, 2)
    if target_edge is not None and abs(mean_edge - target_edge) > 0.15 * target_edge:
        report.fail("edge_length", f"mean edge {mean_edge * 1e3:.1f} mm is not within 15% of the target {target_edge * 1e3:.1f} mm")


def body_clearance(V: np.ndarray, F: np.ndarray, body_V: np.ndarray, body_F: np.ndarray, report: GarmentReport, min_clearance: float = 2e-3) -> None:
    """Every vertex at least ``min_clearance`` outside the body (winding-number signed distance);
    faces oriented away from the body."""
    import igl

    sd = np.asarray(igl.signed_distance(V.astype(np.float64), body_V.astype(np.float64), body_F.astype(np.int64),
                                        sign_type=igl.SIGNED_DISTANCE_TYPE_FAST_WINDING_NUMBER)[0])  # fmt: skip
    report.stats["min_clearance_mm"] = round(float(sd.min()) * 1e3, 2)
    inside = np.flatnonzero(sd < 0)
    close = np.flatnonzero((sd >= 0) & (sd < min_clearance))
    if len(inside):
        report.fail("inside_body", f"{len(inside)} vertices inside the body: {_first(inside)}")
    if len(close):
        report.fail("too_close", f"{len(close)} vertices closer than {min_clearance * 1e3:.0f} mm to the body: {_first(close)}")
    centres = V[F].mean(1)
    normal = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    _, idx = cKDTree(body_V).query(centres)
    outward = float(((normal * (centres - body_V[idx])).sum(1) > 0).mean())
    report.stats["outward_faces"] = round(outward, 4)
    if outward < 0.9:
        report.fail("orientation", f"only {outward:.1%} of face normals point away from the body; flip the winding")


def placement(V: np.ndarray, body_V: np.ndarray, report: GarmentReport) -> None:
    """Units and placement: the garment's extent must be between 5 % and 150 % of the body's height and its
    bounding box must overlap the body's (a garment in centimetres is 100x too large, one modelled elsewhere
    does not touch the body)."""
    size, height = float(np.ptp(V, 0).max()), float(np.ptp(body_V, 0).max())
    report.stats["size_m"] = round(size, 3)
    plausible = lambda s: 0.05 * height <= s <= 1.5 * height  # noqa: E731
    if not plausible(size):
        unit = next((f" (looks like {u}: scale by {f:g})" for u, f in (("centimetres", 0.01), ("millimetres", 0.001)) if plausible(size * f)), "")
        report.fail("units", f"the garment is {size:.3g} m across and the body {height:.2f} m tall{unit}; give the garment in metres")
        return
    lo, hi = np.maximum(V.min(0), body_V.min(0)), np.minimum(V.max(0), body_V.max(0))
    if np.any(lo > hi):
        report.fail("units", f"the garment's bounding box {V.min(0).round(2).tolist()}..{V.max(0).round(2).tolist()} m does not "
                    f"overlap the body's {body_V.min(0).round(2).tolist()}..{body_V.max(0).round(2).tolist()} m (Z up, facing -Y)")  # fmt: skip


def self_intersections(V: np.ndarray, F: np.ndarray, report: GarmentReport) -> None:
    """Faces intersecting other faces of the garment (pymeshlab)."""
    from drapebench.extras import require

    pymeshlab = require("pymeshlab", "the garment check for self-intersections")

    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(V.astype(np.float64), F.astype(np.int32)))
    ms.compute_selection_by_self_intersections_per_face()
    sel = np.flatnonzero(ms.current_mesh().face_selection_array())
    report.stats["self_intersecting_faces"] = int(len(sel))
    if len(sel):
        report.fail("self_intersection", f"{len(sel)} self-intersecting faces {_first(sel)}")


def cross_sections(V: np.ndarray, F: np.ndarray, z: float) -> int:
    """Number of separate pieces the horizontal plane at height ``z`` cuts the garment into."""
    from drapebench.garments.mesh_ops import face_components

    s = V[:, 2] - z
    hit = np.flatnonzero((s[F].min(1) < 0) & (s[F].max(1) > 0))
    if len(hit) == 0:
        return 0
    sub = F[hit]
    used, inv = np.unique(sub, return_inverse=True)
    return len(np.unique(face_components(inv.reshape(sub.shape), len(used))))


def validate_garment(V, F, body_V, body_F, target_edge=None, expected_loops=None, sections=()) -> GarmentReport:
    """Run every check; ``sections`` is a list of (z, expected_pieces) (e.g. one skirt piece below the hips,
    two pant legs)."""
    V, F = np.asarray(V, dtype=np.float64), np.asarray(F, dtype=np.int64)
    report = GarmentReport()
    mesh_structure(V, F, report)
    if report.failures.keys() & {"empty", "face_indices", "nonfinite"}:
        return report
    loops = boundary_loop_count(F)
    report.stats["boundary_loops"] = loops
    if loops == 0:
        report.fail("closed", "the mesh has no boundary; a garment needs openings")
    elif expected_loops is not None and loops != expected_loops:
        report.fail("openings", f"{loops} boundary loops, expected {expected_loops}")
    placement(V, np.asarray(body_V), report)
    if "units" in report.failures:
        return report
    triangle_quality(V, F, report, target_edge)
    body_clearance(V, F, np.asarray(body_V), np.asarray(body_F), report)
    self_intersections(V, F, report)
    for z, expected in sections:
        got = cross_sections(V, F, z)
        if got != expected:
            report.fail(f"cross_section_{z:.2f}", f"the plane z={z:.3f} cuts the garment into {got} pieces, expected {expected}")
    return report
