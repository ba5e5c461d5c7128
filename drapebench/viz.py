"""rerun recordings of drapes: the posed body and the garment over the sequence's timeline."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from drapebench.cache import atomic_write
from drapebench.extras import require


def require_rerun(module: str = "rerun"):
    """rerun (or ``module``, one of its sub-modules); :class:`drapebench.extras.MissingExtra` naming the ``viz``
    extra when rerun-sdk is not installed."""
    return require(module, "viz=rerun (the drape.rrd recording; viz=none runs without it)")


def vertex_strain(x: torch.Tensor, topology) -> np.ndarray:
    """Per-vertex strain (T, V) of positions ``x`` (T, V, 3) m: the mean relative edge-length change
    |l - l0| / l0 of the vertex's edges (dimensionless; 0.1 = 10 %), in ``x``'s dtype."""
    from drapebench.geometry.ops import edge_lengths

    with torch.no_grad():
        rel = (edge_lengths(x, topology.edges) - topology.rest_edge_lengths).abs() / topology.rest_edge_lengths
        V = topology.n_vertices
        acc = torch.zeros(x.shape[0], V, dtype=x.dtype)
        cnt = torch.zeros(V, dtype=x.dtype)
        for k in range(2):
            acc.index_add_(1, topology.edges[:, k], rel)
            cnt.index_add_(0, topology.edges[:, k], torch.ones_like(rel[0]))
        return (acc / cnt.clamp_min(1)).numpy()


def strain_colors(x: torch.Tensor, topology, max_strain: float = 0.1) -> np.ndarray:
    """Per-vertex RGB (T, V, 3) uint8 of :func:`vertex_strain`: white (0) -> orange -> red (>= ``max_strain``)."""
    return strain_rgb(vertex_strain(x, topology), max_strain)


def strain_rgb(strain: np.ndarray, max_strain: float = 0.1) -> np.ndarray:
    """RGB (..., 3) uint8 of strain values (...) (0.1 = 10 %): white (0) -> orange -> red (>= ``max_strain``)."""
    s = np.clip(strain, 0, max_strain) / max_strain
    white, orange, red = np.array([235, 235, 240.0]), np.array([255, 160, 40.0]), np.array([210, 30, 30.0])
    lo = white + (orange - white) * np.clip(s * 2, 0, 1)[..., None]
    rgb = np.where((s > 0.5)[..., None], orange + (red - orange) * np.clip(s * 2 - 1, 0, 1)[..., None], lo)
    return rgb.astype(np.uint8)


def displacement_rgb(distance_mm: np.ndarray, max_mm: float) -> np.ndarray:
    """RGB (..., 3) uint8 of distances (...) in mm: white (0) -> light blue -> dark blue (>= ``max_mm``)."""
    s = np.clip(distance_mm / max_mm, 0, 1)[..., None]
    white, light, dark = np.array([235, 235, 240.0]), np.array([110, 170, 235.0]), np.array([20, 40, 150.0])
    rgb = np.where(s < 0.5, white + (light - white) * s * 2, light + (dark - light) * (s * 2 - 1))
    return rgb.astype(np.uint8)


def displacement_scale(distance_mm: np.ndarray) -> float:
    """The colour scale's top (mm) for distances (...): their 99th percentile rounded up to 1, 2 or 5 x 10^k, at least 1 mm."""
    top = max(float(np.quantile(distance_mm, 0.99)), 1.0)
    step = 10 ** np.floor(np.log10(top))
    return float(next(m * step for m in (1, 2, 5, 10) if m * step >= top))


LEGEND = """**Colours**

- garment: strain, the mean relative edge-length change at a vertex: white 0 -> orange 5 % -> red >= 10 %
- **magenta** garment vertices: inside the body (the rule behind eps_c)
- skin: the posed body; blue `reference`: the physics-based drape (hidden, tick it in the blueprint)
- green `stages/*`: a method's intermediate meshes (hidden), yellow points: its handle vertices; `moved/*`
  (its own view): the drape coloured by its distance from that stage, white 0 -> blue (scale below)

**Plots** (per frame; the rest-pose transition at the start is not evaluated): eps_e / eps_a mean edge / face-area
change (%), eps_c vertices inside the body (%), penetration_mm, vertex_error_mm (mm). Lower is better;
definitions in docs/metrics.md.
"""
PERCENT_PLOTS = ("eps_e", "eps_a", "eps_c")
MM_PLOTS = ("penetration_mm", "vertex_error_mm")
NORMAL_STEPS = 64  # shading normals are stored in steps of 1/64 per component (< 1 degree)


def camera(body_vertices: np.ndarray, fov_y_deg: float = 45.0, aspect: float = 0.9, margin: float = 1.08) -> tuple[np.ndarray, np.ndarray]:
    """Eye position and look target (m) of a 3D camera that frames every frame of ``body_vertices``
    (T, Vb, 3; Z up, the body facing -Y) from the front-left, slightly above: the nearest eye whose view
    (vertical field ``fov_y_deg``, width / height ``aspect``, as the recording's 3D panel) holds every
    vertex, pulled back by ``margin``."""
    pts = body_vertices.reshape(-1, 3).astype(np.float64)
    target = (pts.min(0) + pts.max(0)) / 2
    back = np.array([-0.45, -1.0, 0.2])
    back /= np.linalg.norm(back)  # from the target towards the eye
    right = np.cross(-back, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, -back)
    rel = pts - target
    t = np.tan(np.radians(fov_y_deg) / 2)
    # a vertex at depth (d - rel . back) from the eye is in view when |rel . up| <= depth t and |rel . right| <= depth t aspect
    need = rel @ back + np.maximum(np.abs(rel @ up) / t, np.abs(rel @ right) / (t * aspect))
    return target + margin * float(need.max()) * back, target


def walk_in_place(x: torch.Tensor, root_translation: torch.Tensor) -> torch.Tensor:
    """Positions (T, N, 3) m with each frame's horizontal root translation (T, 3) m taken out (heights
    kept): the view of a body walking in place."""
    shift = torch.zeros_like(x[:, :1])
    shift[..., :2] = root_translation[:, None, :2].to(shift)
    return x - shift


def _blueprint(name: str, eye: np.ndarray, target: np.ndarray, hidden: list[str], plots: list[str], moved: list[str] = ()):
    """The view a recording opens on: the 3D scene framed by ``eye``/``target`` (and, per stage in ``moved``,
    a 3D view of the body and ``moved/<stage>``) beside the per-frame metric plots and the colour legend, on
    the ``frame`` timeline."""
    rrb = require_rerun("rerun.blueprint")

    overrides = {e: rrb.EntityBehavior(visible=False) for e in hidden} or None
    eyes = rrb.EyeControls3D(position=eye, look_target=target, eye_up=(0.0, 0.0, 1.0))
    scene = rrb.Spatial3DView(origin="/", name=name, contents=["+ /**", "- /metrics/**", "- /legend", "- /moved/**"], overrides=overrides,
                              eye_controls=eyes)  # fmt: skip
    scenes = [scene] + [rrb.Spatial3DView(origin="/", name=f"moved from {k}", contents=["+ /body", f"+ /moved/{k}"], eye_controls=eyes)
                        for k in moved]  # fmt: skip
    side = [rrb.TimeSeriesView(name=f"{title} per frame", origin="/metrics", contents=[f"+ /metrics/{m}" for m in group])
            for title, group in (("%", [m for m in plots if m in PERCENT_PLOTS]), ("mm", [m for m in plots if m in MM_PLOTS])) if group]  # fmt: skip
    side.append(rrb.TextDocumentView(origin="/legend", name="legend"))
    return rrb.Blueprint(
        rrb.Horizontal(*scenes, rrb.Vertical(*side, row_shares=[2] * (len(side) - 1) + [1]), column_shares=[3] * len(scenes) + [2]),
        rrb.TimePanel(timeline="frame", state="collapsed"), rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
    )  # fmt: skip


def _send_mesh(stream, entity: str, x: torch.Tensor, faces: torch.Tensor, index, albedo=None, colors=None) -> None:
    """Log mesh ``entity`` over the timeline ``index``: triangles and albedo once (static), positions
    and vertex normals (shading) of every frame of ``x`` (T, V, 3), and per-frame ``colors`` (T, V, 3) uint8."""
    rr = require_rerun()

    from drapebench.geometry.ops import vertex_normals

    x = x.detach().float()
    stream.log(entity, rr.Mesh3D.from_fields(triangle_indices=faces.numpy().astype(np.uint32), albedo_factor=albedo), static=True)
    T, V = x.shape[:2]
    normals = (vertex_normals(x, faces) * NORMAL_STEPS).round() / NORMAL_STEPS  # quantised: the file compresses ~30 % better
    fields = {"vertex_positions": x.reshape(-1, 3).numpy(), "vertex_normals": normals.reshape(-1, 3).numpy()}
    if colors is not None:
        fields["vertex_colors"] = colors.reshape(-1, 3)
    stream.send_columns(entity, indexes=index, columns=rr.Mesh3D.columns(**fields).partition([V] * T))


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
    metrics=None,
    name: str = "drape",
    in_place: torch.Tensor | None = None,
    displaced_from: tuple[str, ...] = (),
) -> Path:
    """Write ``path`` (.rrd): body (T, Vb, 3) and garment (T, V, 3) meshes on a ``frame`` timeline
    (and ``time`` in seconds), shaded by per-frame vertex normals; triangles and flat colours are
    logged once (static). Garment colours show strain; ``penetrating`` (T, V) bool vertices are
    magenta. An optional physics-based ``reference`` (T, V, 3) is logged as ``reference`` (blue,
    hidden by default). ``stages`` are a method's intermediate results (``DrapeResult.extras``): each
    (T, V, 3) one is a mesh ``stages/<name>`` (green, hidden by default) and, for those named in
    ``displaced_from`` (stages in the drape's own space), in a 3D view of its own the drape ``moved/<name>``
    coloured by its distance from that stage (white 0 -> blue at the 99th percentile, e.g. a network's correction
    displacement as its Fig. 11 shows it); each (T, V) bool one the points
    ``stages/<name>`` at those vertices of the first mesh stage (yellow). ``metrics`` (a
    per-frame DataFrame with a ``frame`` column, the run's frames.csv) are plotted beside the 3D view
    as ``metrics/<name>`` time series. A ``legend`` text entity says what the colours mean. The view
    opens on the ``frame`` timeline with a camera that frames the whole body. ``in_place`` (T, 3), the
    root translation (m), has its horizontal part removed from every mesh: the body walks in place and the
    camera stays close (the metrics are computed on world positions)."""
    rr = require_rerun()

    legend = LEGEND
    if in_place is not None:
        body_vertices, garment_vertices = walk_in_place(body_vertices, in_place), walk_in_place(garment_vertices, in_place)
        reference = None if reference is None else walk_in_place(reference, in_place)
        stages = {k: walk_in_place(v, in_place) if v.dim() == 3 else v for k, v in (stages or {}).items()}
        legend += "\nThe body walks in place: the root's horizontal travel is removed from the view.\n"

    T = garment_vertices.shape[0]
    colors = strain_colors(garment_vertices.double(), garment_topology.to(dtype=torch.float64))
    if penetrating is not None:
        colors[penetrating.numpy()] = (230, 0, 200)
    stages = dict(stages or {})
    meshes = {k: v for k, v in stages.items() if v.dim() == 3}
    masks = {k: v for k, v in stages.items() if v.dim() == 2 and v.dtype == torch.bool}
    hidden = (["reference"] if reference is not None else []) + [f"stages/{k}" for k in meshes]
    plots = [] if metrics is None else [m for m in (*PERCENT_PLOTS, *MM_PLOTS) if m in metrics and metrics[m].notna().any()]
    moved = {k: ((garment_vertices - v).detach().double().norm(dim=-1) * 1e3).numpy() for k, v in meshes.items() if k in displaced_from}
    scales = {k: displacement_scale(d) for k, d in moved.items()}
    legend += "".join(f"\n`moved/{k}`: distance of the drape from the `{k}` stage, white 0 -> blue >= {scales[k]:g} mm\n" for k in moved)
    eye, target = camera(body_vertices.detach().float().numpy())
    blueprint = _blueprint(name, eye, target, hidden, plots, list(moved))
    stream = rr.RecordingStream("drapebench", recording_id=f"{name}-{np.random.default_rng().integers(1 << 62)}")
    path = Path(path)
    faces = garment_topology.faces
    with atomic_write(path, mode=None) as tmp:
        stream.save(str(tmp), default_blueprint=blueprint)
        stream.log("/", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        stream.log("legend", rr.TextDocument(legend, media_type=rr.MediaType.MARKDOWN), static=True)
        frames = np.arange(T)
        index = [rr.TimeColumn("frame", sequence=frames), rr.TimeColumn("time", duration=frames / fps)]
        _send_mesh(stream, "body", body_vertices, body_faces, index, albedo=(0.85, 0.75, 0.68, 1.0))
        _send_mesh(stream, "garment", garment_vertices, faces, index, colors=colors)
        if reference is not None:
            _send_mesh(stream, "reference", reference, faces, index, albedo=(0.35, 0.55, 0.95, 1.0))
        for k, v in meshes.items():
            _send_mesh(stream, f"stages/{k}", v, faces, index, albedo=(0.45, 0.8, 0.45, 1.0))
            if k in moved:
                _send_mesh(stream, f"moved/{k}", garment_vertices, faces, index, colors=displacement_rgb(moved[k], scales[k]))
        if masks and meshes:
            base = next(iter(meshes.values())).detach().float()
            for k, m in masks.items():
                stream.log(f"stages/{k}", rr.Points3D.from_fields(colors=(250, 210, 40), radii=0.004), static=True)
                pts = base[m].numpy()
                stream.send_columns(f"stages/{k}", indexes=index,
                                    columns=rr.Points3D.columns(positions=pts).partition(m.sum(1).tolist()))  # fmt: skip
        for m in plots:
            rows = metrics[["frame", m]].dropna()
            f = rows["frame"].to_numpy()
            stream.send_columns(f"metrics/{m}", indexes=[rr.TimeColumn("frame", sequence=f), rr.TimeColumn("time", duration=f / fps)],
                                columns=rr.Scalars.columns(scalars=rows[m].to_numpy(np.float64)))  # fmt: skip
        stream.flush()
        stream.disconnect()
    return path
