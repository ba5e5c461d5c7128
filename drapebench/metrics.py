"""One metric suite for every method (definitions in DESIGN.md).

Per frame: ``eps_e`` / ``eps_a`` mean absolute relative change (%) of edge lengths / face areas vs
the template; ``eps_c`` % of vertices inside the posed body (exact signed distance < 0);
``eps_c_nn`` the same by nearest-body-vertex normal distance (how the GAPS code counts);
``edge_mm`` mean absolute edge-length change (mm); ``smoothness`` mean |cotangent Laplacian| of
the positions (m); ``penetration_mm`` mean depth of penetrating vertices (0 if none); ``jitter``
mean |second difference| of positions (mm, frames with both neighbours); ``vertex_error_mm`` mean
distance to the reference when one is given; energies (J; collision unweighted, m^3).
The summary averages over frames (``eps_c_std`` is the std over frames); by default the
sequence's transition frames (rest pose -> motion) are left out.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import torch

from drapebench.geometry.ops import edge_lengths, face_areas
from drapebench.geometry.proximity import nearest_body_vertex, signed_distance
from drapebench.physics.energies import collision_energy, laplacian
from drapebench.physics.material import Material
from drapebench.physics.terms import energy_terms


def _check_prediction(prediction: torch.Tensor, n_frames: int, n_vertices: int, what: str) -> torch.Tensor:
    p = torch.as_tensor(prediction)
    if p.shape != (n_frames, n_vertices, 3):
        raise ValueError(f"{what} has shape {tuple(p.shape)}; expected ({n_frames}, {n_vertices}, 3) for this garment and sequence")
    bad = (~torch.isfinite(p)).any(-1).any(-1)
    if bad.any():
        raise ValueError(f"{what} contains NaN/Inf in frames {torch.nonzero(bad).squeeze(1)[:10].tolist()}")
    return p


def evaluate(
    garment,
    seq,
    body,
    prediction,
    reference=None,
    material: Material | None = None,
    skip_transition: bool = True,
    energies: bool = True,
) -> tuple[dict, pd.DataFrame]:
    """Metrics of a drape.

    Args:
        garment: :class:`drapebench.garments.Garment` (its topology gives the template).
        seq: :class:`drapebench.body.BodySequence`; body: the :class:`BodyModel` it poses.
        prediction: (T, V, 3) draped vertices for all T frames of ``seq``.
        reference: optional (T, V, 3) physics-based drape of the same scene.
        material: for the energy breakdown (default :class:`Material`).
        skip_transition: leave the sequence's leading transition frames out of the metrics.
        energies: include the per-frame energy breakdown.
    Returns:
        (summary dict, per-frame DataFrame).
    """
    material = material or Material()
    topo = garment.topology
    x = _check_prediction(prediction, seq.n_frames, garment.n_vertices, "prediction").to(topo.dtype)
    ref = None if reference is None else _check_prediction(reference, seq.n_frames, garment.n_vertices, "reference").to(topo.dtype)
    first = seq.n_transition if skip_transition and seq.n_transition < seq.n_frames else 0
    frames = np.arange(first, seq.n_frames)
    x_eval = x[first:]
    body_v = seq.vertices(body)[first:].to(topo.dtype)
    body_n = seq.vertex_normals(body)[first:].to(topo.dtype)
    with torch.no_grad():
        lengths = edge_lengths(x_eval, topo.edges)
        rel_e = (lengths - topo.rest_edge_lengths).abs() / topo.rest_edge_lengths
        rel_a = (face_areas(x_eval, topo.faces) - topo.face_areas).abs() / topo.face_areas
        sd = signed_distance(x_eval, body_v, body.faces)
        nn = nearest_body_vertex(x_eval, body_v, body_n)
        inside = sd < 0
        depth = torch.where(inside, -sd, torch.zeros_like(sd))
        n_in = inside.sum(-1)
        cols = {
            "frame": frames,
            "eps_e": rel_e.mean(-1) * 100,
            "eps_a": rel_a.mean(-1) * 100,
            "eps_c": inside.to(x.dtype).mean(-1) * 100,
            "eps_c_nn": (nn.distance < 0).to(x.dtype).mean(-1) * 100,
            "edge_mm": (lengths - topo.rest_edge_lengths).abs().mean(-1) * 1e3,
            "smoothness": laplacian(x_eval, topo).norm(dim=-1).mean(-1),
            "penetration_mm": torch.where(n_in > 0, depth.sum(-1) / n_in.clamp_min(1), torch.zeros_like(n_in, dtype=x.dtype)) * 1e3,
        }
        jitter = torch.full((len(frames),), float("nan"), dtype=x.dtype)
        if seq.n_frames >= 3:
            acc = (x[2:] - 2 * x[1:-1] + x[:-2]).norm(dim=-1).mean(-1) * 1e3  # frames 1..T-2
            for k, f in enumerate(frames):
                if 1 <= f <= seq.n_frames - 2:
                    jitter[k] = acc[f - 1]
        cols["jitter"] = jitter
        if ref is not None:
            cols["vertex_error_mm"] = (x_eval - ref[first:]).norm(dim=-1).mean(-1) * 1e3
        if energies:
            terms = energy_terms(x_eval, topo, material)
            terms["collision"] = collision_energy(x_eval, nn.point, nn.normal, material.collision_thickness)
            for k, v in terms.items():
                cols[f"energy_{k}"] = v
    df = pd.DataFrame({k: (v.cpu().numpy() if isinstance(v, torch.Tensor) else v) for k, v in cols.items()})
    summary = {k: float(np.nanmean(df[k])) for k in df.columns if k != "frame"}
    summary["eps_c_std"] = float(df["eps_c"].std(ddof=0))
    summary["n_frames_evaluated"] = len(frames)
    return summary, df
