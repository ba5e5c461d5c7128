"""One metric suite for every method: ``evaluate`` and its summary.

The metrics' definitions, units, summaries and which direction is better are in ``docs/metrics.md``, and only
there; this module implements them. Frames are evaluated in chunks (``chunk_frames``), the body posed per chunk,
so memory stays bounded on long sequences. The signed distance is the default path of
:mod:`drapebench.geometry.sdf` (``exact=True``: its libigl path); the nearest body vertex (``eps_c_nn``, the
collision energy) is searched over the corners of the body's outer faces in the same pass
(:func:`drapebench.geometry.sdf.body_proximity`). Every frame is measured in its local frame, the root translation
subtracted in float64; float32 positions farther than :data:`MAX_FLOAT32_DISTANCE` from the origin are refused
(:class:`FarFromOrigin`; the measured error against the distance is in ``docs/metrics.md``).
"""

from __future__ import annotations

import logging

import numpy as np
import pandas as pd
import torch

from drapebench.geometry.ops import edge_lengths, face_areas
from drapebench.geometry.sdf import body_proximity
from drapebench.physics import Material, energy_terms
from drapebench.progress import progress

log = logging.getLogger("drapebench")

MAX_FLOAT32_DISTANCE = 1000.0  # m: the farthest float32 positions are measured from the origin (docs/metrics.md)


class FarFromOrigin(ValueError):
    """Float32 positions too far from the origin to resolve a garment's edges; the message says how far and the fix."""


def _check_positions(x, n_frames: int, n_vertices: int, what: str):
    """``x`` as a (T, V, 3) tensor (a :class:`drapebench.results.StoredFrames` as it is: read a chunk at a time), or a
    ValueError naming the shape. Its values are checked chunk by chunk as they are read (:func:`_checked_frames`)."""
    from drapebench.results import StoredFrames

    p = x if isinstance(x, StoredFrames) else torch.as_tensor(x)
    if p.shape != (n_frames, n_vertices, 3):
        raise ValueError(f"{what} has shape {tuple(p.shape)}; expected ({n_frames}, {n_vertices}, 3) for this garment "
                         "and sequence (one row per frame of the sequence, one per garment vertex)")  # fmt: skip
    return p


def _checked_frames(x, start: int, stop: int, what: str) -> torch.Tensor:
    """Frames [start, stop) of positions ``x`` (T, V, 3) as a tensor; ValueError naming the frames with NaN/Inf, and
    :class:`FarFromOrigin` (:func:`check_near_origin`)."""
    part = x[start:stop]
    frames = [start + t for t in nonfinite_frames(part)]
    if frames:
        more = f" and {len(frames) - 10} more" if len(frames) > 10 else ""
        raise ValueError(f"{what} contains NaN/Inf in frames {frames[:10]}{more}")
    check_near_origin(part, what)
    return part


CHUNK_FRAMES = 256  # frames evaluated together: bounds evaluate()'s memory on long sequences


def nonfinite_frames(x: torch.Tensor, chunk_frames: int = CHUNK_FRAMES) -> list[int]:
    """The frames of positions ``x`` (T, ...) that hold NaN or Inf, checked ``chunk_frames`` at a time (no temporary
    the size of a long drape)."""
    bad = [torch.nonzero((~torch.isfinite(x[a : a + chunk_frames])).flatten(1).any(1)).flatten() + a for a in range(0, len(x), chunk_frames)]
    return torch.cat(bad).tolist() if bad else []


def evaluate(
    garment,
    seq,
    body,
    prediction,
    reference=None,
    material=None,
    skip_transition: bool = True,
    energies: bool = True,
    exact: bool = False,
    chunk_frames: int = CHUNK_FRAMES,
) -> tuple[dict, pd.DataFrame]:
    """Metrics of a drape (definitions: docs/metrics.md).

    Args:
        garment: :class:`drapebench.garments.Garment` (its ``topology`` is the template).
        seq: :class:`drapebench.body.BodySequence`; body: the :class:`BodyModel` it poses.
        prediction: (T, V, 3) draped vertices (m) for all T frames of ``seq``: a tensor, or a drape streamed to
            its file (:class:`drapebench.results.StoredFrames`), read a chunk at a time.
        reference: optional (T, V, 3) physics-based drape of the same scene.
        material: :class:`drapebench.physics.Material` for the energy breakdown (default Material()).
        skip_transition: leave the sequence's ``n_transition`` leading frames out.
        energies: add the per-frame ``energy_*`` columns.
        exact: the libigl signed distance and a KD-tree nearest vertex instead of the warp BVH (same
            values within the tolerance in :mod:`drapebench.geometry.sdf`).
        chunk_frames: frames evaluated (and checked for NaN/Inf and distance from the origin) at once; the body
            is posed per chunk unless ``seq`` already holds its posed geometry, so memory stays bounded as
            sequences grow.
    Returns:
        (summary dict of floats (None for jitter and drift_mm where the drape is too short to measure them), per-frame
        DataFrame with a ``frame`` column and one column per metric).
    """
    if chunk_frames < 1:
        raise ValueError(f"chunk_frames must be >= 1, got {chunk_frames}")
    topo = garment.topology
    device, dtype = topo.device, topo.dtype
    p = _check_positions(prediction, seq.n_frames, garment.n_vertices, "prediction")
    ref = None if reference is None else _check_positions(reference, seq.n_frames, garment.n_vertices, "reference")
    first = seq.n_transition if skip_transition and seq.n_transition < seq.n_frames else 0
    for what, positions in (("prediction", p), ("reference", ref)):  # the frames left out are checked too
        if positions is not None and first:
            _checked_frames(positions, 0, first, what)
    faces, outer = body.faces.to(device), body.outer_faces.to(device)
    origin = seq.trans.to(device, torch.float64)  # (T, 3) m: every frame is measured relative to its root
    material = material or Material()
    mass = float(topo.vertex_masses(material).double().sum()) if energies else 0.0  # kg: the garment's, fixed per garment
    columns, depth_sum, n_inside = {}, 0.0, 0  # one array per column, filled chunk by chunk (see _fill)
    with torch.no_grad():
        bar = progress(total=seq.n_frames - first, desc="metrics", unit="frames")
        for start in range(first, seq.n_frames, chunk_frames):
            stop = min(start + chunk_frames, seq.n_frames)
            lo, hi = max(start - 1, 0), min(stop + 1, seq.n_frames)  # one frame either side, for the jitter
            window = _checked_frames(p, lo, hi, "prediction").to(device, torch.float64)
            world = window[start - lo : stop - lo]
            x = (world - origin[start:stop, None]).to(dtype)  # local: float32 keeps its resolution at the body's scale
            body_v, body_n = (t.to(device, dtype) for t in seq.posed_frames(body, start, stop, local=True))
            cols, nn, depth, n_in = _frame_metrics(x, topo, body_v, body_n, faces, outer, exact)
            cols["jitter"] = _jitter(window)[start - lo : stop - lo]
            if ref is not None:
                cols["vertex_error_mm"] = (world - _checked_frames(ref, start, stop, "reference").to(device, torch.float64)).norm(dim=-1).mean(-1) * 1e3
            if energies:
                terms = energy_terms(x, topo, material, near=nn)
                cols.update({f"energy_{k}": v for k, v in terms.items()})
                cols["energy_gravity"] = cols["energy_gravity"].double() + _gravity_of_origin(origin[start:stop], mass, material)
            _fill(columns, cols, start - first, seq.n_frames - first)
            depth_sum += float(depth.double().sum())
            n_inside += int(n_in.sum())
            bar.update(stop - start)
        bar.close()
    df = pd.DataFrame({"frame": np.arange(first, seq.n_frames), **columns})
    summary = {k: float(df[k].mean()) for k in df.columns if k != "frame"}  # pandas skips the NaN jitter ends
    summary.update({f"{k}_std": float(df[k].std(ddof=0)) for k in ("eps_e", "eps_a", "eps_c")})
    summary["penetration_mm"] = depth_sum / max(n_inside, 1) * 1e3
    summary["max_strain"], summary["max_penetration_mm"] = float(df["max_strain"].max()), float(df["max_penetration_mm"].max())
    summary["drift_mm"] = drift(df["garment_body_mm"].to_numpy())
    summary["n_frames_evaluated"] = len(df)
    _null_unmeasured(summary, len(df))
    return summary, df


def _null_unmeasured(summary: dict, n_evaluated: int) -> None:
    """Set to None (JSON's null, where it would have written NaN) the frame-to-frame metrics a drape too short cannot
    measure: ``jitter`` needs a frame with both neighbours, ``drift_mm`` 10 evaluated frames; a warning names them."""
    unmeasured = [k for k in ("jitter", "drift_mm") if np.isnan(summary[k])]
    if unmeasured:
        log.warning("%s not measured on %d evaluated frame(s): jitter needs a frame with both neighbours, drift_mm 10 frames "
                    "(raise motion.n_frames, or set eval.skip_transition=false to evaluate the transition frames too); written as null",
                    " and ".join(unmeasured), n_evaluated)  # fmt: skip
        summary.update(dict.fromkeys(unmeasured))


def _fill(columns: dict, cols: dict, at: int, n_rows: int) -> None:
    """Copy a chunk's metric columns ``cols`` ({name: (B,) tensor}) into rows [at, at + B) of ``columns`` ({name: (n_rows,)
    float64 array}, each made on first use). Arrays made once, not a small tensor kept per chunk: small long-lived
    allocations between a chunk's large temporaries fragment the heap, which then grows by about a chunk's worth of
    temporaries per chunk (measured: 35 KB per frame of a long skinned drape)."""
    for k, v in cols.items():
        column = columns.setdefault(k, np.full(n_rows, np.nan))
        column[at : at + len(v)] = v.detach().cpu().double().numpy()


def drift(per_frame: np.ndarray, share: float = 0.1) -> float:
    """|mean of the last ``share`` of the values - mean of the first ``share``| (same unit; NaN below 1/share values)."""
    n = int(len(per_frame) * share)
    return float(abs(per_frame[-n:].mean() - per_frame[:n].mean())) if n >= 1 else float("nan")


def _jitter(window: torch.Tensor) -> torch.Tensor:
    """(B,) float64 mean |x[t+1] - 2 x[t] + x[t-1]| in mm of consecutive frames x (B, V, 3) m, computed in float64
    (exact for the given positions wherever they are); NaN at the window's two ends (whose neighbour it does not
    hold: a sequence's first and last frame)."""
    acc = torch.full((window.shape[0],), float("nan"), dtype=torch.float64)
    if window.shape[0] > 2:
        w = window.double()
        acc[1:-1] = ((w[2:] - 2 * w[1:-1] + w[:-2]).norm(dim=-1).mean(-1) * 1e3).cpu()
    return acc


def _gravity_of_origin(origin: torch.Tensor, mass: float, material) -> torch.Tensor:
    """(B,) float64 J: the gravitational energy -M g . o of the garment's mass M (kg) moved by each frame's origin
    o (B, 3) m, so that energy_gravity keeps the world's datum (z = 0) though measured in the local frame."""
    g = torch.tensor(material.gravity, dtype=torch.float64, device=origin.device)
    return -mass * (origin @ g)


def check_near_origin(positions: torch.Tensor, what: str = "prediction") -> None:
    """Raise :class:`FarFromOrigin` when float32 (or coarser) ``positions`` (..., 3) m lie farther from the
    origin than :data:`MAX_FLOAT32_DISTANCE`, where float32 cannot resolve a garment's edges; float64
    positions are measured at any distance (in each frame's local frame)."""
    if positions.dtype == torch.float64 or positions.numel() == 0:
        return
    far = max(float(positions[a : a + CHUNK_FRAMES].abs().amax()) for a in range(0, len(positions), CHUNK_FRAMES))
    if far > MAX_FLOAT32_DISTANCE:
        spacing = float(torch.finfo(torch.float32).eps) * 2.0 ** np.floor(np.log2(far))
        raise FarFromOrigin(
            f"the {what} lies up to {far:.4g} m from the origin, where float32 positions are {1e3 * spacing:.3g} mm apart: "
            f"its strains and collisions cannot be measured (float32 runs accept up to {MAX_FLOAT32_DISTANCE:g} m). "
            "Keep the motion near the origin (a motion file's root translation in metres, a procedural motion at its "
            "usual motion.fps and length), or run in double precision (dtype=float64; the reference simulator is float32)"
        )


def _frame_metrics(xe, topo, body_v, body_n, faces, outer, exact: bool):
    """Per-frame metric columns (dict of (B,) tensors) of positions xe (B,V,3) against the posed body
    (B,Vb,3) with its outer faces (F,) bool, the nearest-vertex query, and per frame the summed depth
    (m) and count of the penetrating vertices."""
    lengths = edge_lengths(xe, topo.edges)
    d_len = (lengths - topo.rest_edge_lengths).abs()
    strain = d_len / topo.rest_edge_lengths
    rel_a = (face_areas(xe, topo.faces) - topo.face_areas).abs() / topo.face_areas
    surface, nn = body_proximity(xe, body_v, body_n, faces, exact=exact, outer_faces=outer)
    sd = surface.distance
    inside = sd < 0
    n_in = inside.sum(-1)
    depth = torch.where(inside, -sd, torch.zeros_like(sd)).sum(-1)
    lap = torch.sparse.mm(topo.laplacian, xe.permute(1, 0, 2).reshape(topo.n_vertices, -1))
    cols = {
        "eps_e": strain.mean(-1) * 100,
        "eps_a": rel_a.mean(-1) * 100,
        "eps_c": inside.to(xe.dtype).mean(-1) * 100,
        "eps_c_nn": (nn.distance < 0).to(xe.dtype).mean(-1) * 100,
        "edge_mm": d_len.mean(-1) * 1e3,
        "smoothness": lap.reshape(topo.n_vertices, -1, 3).norm(dim=-1).mean(0),
        "penetration_mm": depth / n_in.clamp_min(1) * 1e3,
        "max_strain": strain.amax(-1) * 100,
        "max_penetration_mm": torch.clamp(-sd, min=0).amax(-1) * 1e3,
        "garment_body_mm": sd.mean(-1) * 1e3,
    }
    return cols, nn, depth, n_in
