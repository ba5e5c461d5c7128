"""The Garment record, its export, and loading a user's garment with the same validity checks."""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import torch

from drapebench.cache import atomic_write
from drapebench.geometry.topology import Topology, get_topology


@dataclass
class Garment:
    """A garment on the canonical (rest-pose) body.

    vertices (V, 3) float32 metres; faces (F, 3) long, outward-oriented; pins (P,) long vertex
    indices the papers hold to the body (waistband / neck-shoulder band); topology: cached
    :class:`Topology`; kind, params (construction parameters), betas (S,) the body shape it was made on.
    """

    name: str
    kind: str
    vertices: torch.Tensor
    faces: torch.Tensor
    pins: torch.Tensor
    topology: Topology
    params: dict = field(default_factory=dict)
    betas: torch.Tensor = field(default_factory=lambda: torch.zeros(10))
    body_name: str = "anny"

    @property
    def n_vertices(self) -> int:
        return self.vertices.shape[0]

    def in_dtype(self, dtype: torch.dtype) -> Garment:
        """This garment with its topology (rest lengths, areas, ... that energies and metrics use) in ``dtype``;
        ``vertices`` stay the float32 record (content hashes do not depend on a run's precision)."""
        return self if self.topology.dtype == dtype else replace(self, topology=self.topology.to(dtype=dtype))

    def export(self, path: str | Path) -> None:
        """Write an OBJ or PLY (by suffix) atomically."""
        import trimesh

        path = Path(path)
        if path.suffix.lower() not in (".obj", ".ply"):
            raise ValueError(f"unsupported garment file type {path.suffix!r}; use .obj or .ply")
        mesh = trimesh.Trimesh(self.vertices.numpy(), self.faces.numpy(), process=False)
        with atomic_write(path, "wb") as f:
            mesh.export(f, file_type=path.suffix[1:].lower())


def read_obj(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and triangles of an OBJ exactly as written (polygons fan-triangulated; unlike trimesh,
    unreferenced vertices are kept so validation can report them)."""
    verts, faces = [], []
    try:
        text = Path(path).read_text()
    except UnicodeDecodeError as exc:
        raise ValueError(f"{path} is not a text OBJ file ({exc}); export the garment as .obj or .ply") from exc
    for n, line in enumerate(text.splitlines(), 1):
        parts = line.split()
        if not parts:
            continue
        try:
            if parts[0] == "v":
                verts.append([float(t) for t in parts[1:4]])
            elif parts[0] == "f":
                idx = [int(t.split("/")[0]) for t in parts[1:]]
                idx = [i - 1 if i > 0 else len(verts) + i for i in idx]
                faces += [[idx[0], idx[k], idx[k + 1]] for k in range(1, len(idx) - 1)]
        except ValueError as exc:
            raise ValueError(f"{path}:{n}: cannot parse {line!r} ({exc})") from exc
    return np.asarray(verts, dtype=np.float64).reshape(-1, 3), np.asarray(faces, dtype=np.int64).reshape(-1, 3)


# What a user does about each failed check of their garment (check names of drapebench.garments.validate).
USER_FIXES = {
    "units": "the garment must be in metres, placed on the body in its rest pose: scale or move it in a mesh editor",
    "inside_body": "the garment must start outside the body in its rest pose (the body at the given betas, pose 0): "
    "move those vertices outward (e.g. an inflate/offset of a few mm), or give the betas it was made on",
    "too_close": "keep every vertex at least 2 mm outside the body: offset the garment outward a little",
    "non_manifold_edges": "each edge may border at most two faces: repair the mesh (e.g. Blender: Select All by Trait > Non Manifold)",
    "degenerate_faces": "remove zero-area faces (e.g. Blender: Mesh > Clean Up > Degenerate Dissolve)",
    "duplicate_vertices": "merge coincident vertices (e.g. Blender: Mesh > Clean Up > Merge by Distance)",
    "unreferenced_vertices": "remove the loose vertices (e.g. Blender: Mesh > Clean Up > Delete Loose)",
    "orientation": "flip the face winding so normals point away from the body (e.g. Blender: Mesh > Normals > Flip)",
    "closed": "a garment needs openings (boundary loops): cut the neck, arm or waist openings",
    "self_intersection": "the garment crosses itself: separate the intersecting layers",
}


def load_garment(path: str | Path, body, betas=None, kind: str = "custom", pins=None, name: str | None = None) -> Garment:
    """Load a user's OBJ/PLY garment (metres, Z up) placed on the canonical body (rest pose, ``betas``), and
    validate it. ``pins`` (P,) vertex indices held to the body; None finds them (:func:`drapebench.garments.pins.find_pins`).

    Raises ValueError listing every failed check with its fix (not a mesh, wrong units, inside the body,
    non-manifold edges, degenerate faces, duplicate/unreferenced vertices, flipped orientation, ...).
    """
    import trimesh

    from drapebench.garments.pins import check_pins, find_pins
    from drapebench.garments.validate import validate_garment

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"garment file {path} does not exist (garment.path must name an .obj or .ply file)")
    if path.suffix.lower() == ".obj":
        V, F = read_obj(path)
    else:
        try:
            mesh = trimesh.load(path, process=False, force="mesh")
        except Exception as exc:  # trimesh raises many types for unreadable files
            raise ValueError(f"{path}: cannot read a triangle mesh ({exc}); export the garment as .obj or .ply") from exc
        V, F = np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces, dtype=np.int64)
    if len(V) < 3 or len(F) == 0:
        raise ValueError(f"{path} is not a mesh: {len(V)} vertices and {len(F)} faces; a garment file needs 'v' and 'f' lines (OBJ) or faces (PLY)")
    betas_t = body.full_betas(betas, note=True)
    with torch.no_grad():
        body_v = body.shaped(betas_t[None])[0][0].double().numpy()
    report = validate_garment(V, F, body_v, body.faces.numpy())
    # a user's mesh is judged on structure and placement, not on our factory's triangle targets
    report.failures.pop("triangle_quality", None)
    if not report.ok:
        fixes = "\n".join(f"  fix {k}: {USER_FIXES[k]}" for k in report.failures if k in USER_FIXES)
        raise ValueError(f"{path} is not a valid garment:\n{report}\n{fixes}".rstrip())
    name = name or path.stem
    pins_t = check_pins(pins, len(V), name) if pins is not None else find_pins(torch.as_tensor(V), torch.as_tensor(body_v), name)
    return Garment(
        name=name, kind=kind, vertices=torch.as_tensor(V, dtype=torch.float32),
        faces=torch.as_tensor(F), pins=pins_t, topology=get_topology(V, F), params={"source": str(path)},
        betas=betas_t.float().cpu(), body_name=body.name,
    )  # fmt: skip
