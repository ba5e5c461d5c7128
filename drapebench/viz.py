"""rerun recordings of drapes: the posed body and the garment over the sequence's timeline."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from drapebench.cache import atomic_write


def strain_colors(x: torch.Tensor, topology, max_strain: float = 0.1) -> np.ndarray:
    """Per-vertex RGB (T, V, 3) uint8: mean relative edge-length change of incident edges,
    white (0) -> orange -> red (>= ``max_strain``)."""
    from drapebench.geometry.ops import edge_lengths

    with torch.no_grad():
        rel = (edge_lengths(x, topology.edges) - topology.rest_edge_lengths).abs() / topology.rest_edge_lengths
        V = topology.n_vertices
        acc = torch.zeros(x.shape[0], V, dtype=x.dtype)
        cnt = torch.zeros(V, dtype=x.dtype)
        for k in range(2):
            acc.index_add_(1, topology.edges[:, k], rel)
            cnt.index_add_(0, topology.edges[:, k], torch.ones_like(rel[0]))
        s = (acc / cnt.clamp_min(1)).clamp(0, max_strain).numpy() / max_strain
    white, orange, red = np.array([235, 235, 240.0]), np.array([255, 160, 40.0]), np.array([210, 30, 30.0])
    lo = white + (orange - white) * np.clip(s * 2, 0, 1)[..., None]
    rgb = np.where((s > 0.5)[..., None], orange + (red - orange) * np.clip(s * 2 - 1, 0, 1)[..., None], lo)
    return rgb.astype(np.uint8)


def record_drape(
    path: str | Path,
    body_vertices: torch.Tensor,
    body_faces: torch.Tensor,
    garment_vertices: torch.Tensor,
    garment_topology,
    fps: float,
    penetrating: torch.Tensor | None = None,
    reference: torch.Tensor | None = None,
    name: str = "drape",
) -> Path:
    """Write ``path`` (.rrd): body (T, Vb, 3) and garment (T, V, 3) meshes on a ``frame`` timeline
    (and ``time`` in seconds); triangles are logged once as static, positions and colours per frame
    in columns. Garment colours show strain; ``penetrating`` (T, V) bool vertices are magenta. An
    optional physics-based ``reference`` (T, V, 3) is logged as ``reference`` (blue, hidden by default)."""
    import rerun as rr
    import rerun.blueprint as rrb

    T = garment_vertices.shape[0]
    colors = strain_colors(garment_vertices.double(), garment_topology.to(dtype=torch.float64))
    if penetrating is not None:
        colors[penetrating.numpy()] = (230, 0, 200)
    overrides = {"reference": rrb.EntityBehavior(visible=False)} if reference is not None else None
    blueprint = rrb.Blueprint(rrb.Spatial3DView(origin="/", name=name, overrides=overrides), rrb.TimePanel(state="collapsed"))
    stream = rr.RecordingStream("drapebench", recording_id=f"{name}-{np.random.default_rng().integers(1 << 62)}")
    path = Path(path)
    with atomic_write(path, mode=None) as tmp:
        stream.save(str(tmp), default_blueprint=blueprint)
        stream.log("/", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        stream.log("body", rr.Mesh3D.from_fields(triangle_indices=body_faces.numpy().astype(np.uint32),
                                                 albedo_factor=(0.85, 0.75, 0.68, 1.0)), static=True)  # fmt: skip
        stream.log("garment", rr.Mesh3D.from_fields(triangle_indices=garment_topology.faces.numpy().astype(np.uint32)), static=True)
        frames = np.arange(T)
        index = [rr.TimeColumn("frame", sequence=frames), rr.TimeColumn("time", duration=frames / fps)]
        bv = body_vertices.detach().float().numpy()
        gv = garment_vertices.detach().float().numpy()
        stream.send_columns("body", indexes=index, columns=rr.Mesh3D.columns(vertex_positions=bv.reshape(-1, 3)).partition([bv.shape[1]] * T))
        stream.send_columns(
            "garment", indexes=index,
            columns=rr.Mesh3D.columns(vertex_positions=gv.reshape(-1, 3), vertex_colors=colors.reshape(-1, 3)).partition([gv.shape[1]] * T),
        )  # fmt: skip
        if reference is not None:
            rv = reference.detach().float().numpy()
            stream.log("reference", rr.Mesh3D.from_fields(triangle_indices=garment_topology.faces.numpy().astype(np.uint32),
                                                          albedo_factor=(0.35, 0.55, 0.95, 1.0)), static=True)  # fmt: skip
            stream.send_columns("reference", indexes=index,
                                columns=rr.Mesh3D.columns(vertex_positions=rv.reshape(-1, 3)).partition([rv.shape[1]] * T))  # fmt: skip
        stream.flush()
        stream.disconnect()
    return path
