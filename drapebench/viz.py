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
    stages: dict | None = None,
    name: str = "drape",
) -> Path:
    """Write ``path`` (.rrd): body (T, Vb, 3) and garment (T, V, 3) meshes on a ``frame`` timeline
    (and ``time`` in seconds); triangles are logged once as static, positions and colours per frame
    in columns. Garment colours show strain; ``penetrating`` (T, V) bool vertices are magenta. An
    optional physics-based ``reference`` (T, V, 3) is logged as ``reference`` (blue, hidden by default).
    ``stages`` are a method's intermediate results (``DrapeResult.extras``): each (T, V, 3) one is a mesh
    ``stages/<name>`` (green, hidden by default), each (T, V) bool one the points ``stages/<name>`` at
    those vertices of the first mesh stage (yellow)."""
    import rerun as rr
    import rerun.blueprint as rrb

    T = garment_vertices.shape[0]
    colors = strain_colors(garment_vertices.double(), garment_topology.to(dtype=torch.float64))
    if penetrating is not None:
        colors[penetrating.numpy()] = (230, 0, 200)
    stages = dict(stages or {})
    meshes = {k: v for k, v in stages.items() if v.dim() == 3}
    masks = {k: v for k, v in stages.items() if v.dim() == 2 and v.dtype == torch.bool}
    hidden = (["reference"] if reference is not None else []) + [f"stages/{k}" for k in meshes]
    overrides = {e: rrb.EntityBehavior(visible=False) for e in hidden} or None
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
        faces_u32 = garment_topology.faces.numpy().astype(np.uint32)
        for k, v in meshes.items():
            sv = v.detach().float().numpy()
            stream.log(f"stages/{k}", rr.Mesh3D.from_fields(triangle_indices=faces_u32, albedo_factor=(0.45, 0.8, 0.45, 1.0)), static=True)
            stream.send_columns(f"stages/{k}", indexes=index,
                                columns=rr.Mesh3D.columns(vertex_positions=sv.reshape(-1, 3)).partition([sv.shape[1]] * T))  # fmt: skip
        if masks and meshes:
            base = next(iter(meshes.values())).detach().float()
            for k, m in masks.items():
                stream.log(f"stages/{k}", rr.Points3D.from_fields(colors=(250, 210, 40), radii=0.004), static=True)
                pts = base[m].numpy()
                stream.send_columns(f"stages/{k}", indexes=index,
                                    columns=rr.Points3D.columns(positions=pts).partition(m.sum(1).tolist()))  # fmt: skip
        stream.flush()
        stream.disconnect()
    return path
