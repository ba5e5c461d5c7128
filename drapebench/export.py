"""A run's drape for animation tools: ``python -m drapebench.export <run dir> --format usd|obj|pc2``, or
``export=usd|obj|pc2`` in a run (after the drape).

Into ``<run dir>/export/``, every file written atomically (a temporary file renamed into place):

* ``usd``: ``drape.usd``, one stage with the meshes ``/drape/garment`` and ``/drape/body``, their points
  time-sampled (time code k = frame k of ``prediction.h5``), the garment's per-vertex strain as the primvar
  ``strain`` (mean relative edge-length change, 0.1 = 10 %) and as ``displayColor`` (the recording's white ->
  red); metres (metersPerUnit 1), Z up, timeCodesPerSecond = framesPerSecond = the run's fps. Needs
  ``usd-core`` (``pip install -e ".[export]"``).
* ``obj``: ``obj/garment_0000.obj``, ``obj/body_0000.obj``, ... one pair per frame.
* ``pc2``: ``pc2/garment.pc2`` and ``pc2/body.pc2`` point caches (Blender's Mesh Cache modifier: header
  ``POINTCACHE2\\0``, version 1, points, start frame 0, 1 sample per frame, samples; then float32 xyz) with the
  rest meshes ``pc2/garment_rest.obj`` and ``pc2/body_rest.obj`` (same vertex order).

Metres, Z up, the body facing -Y (the suite's frame) in every format.
"""

from __future__ import annotations

import argparse
import logging
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from drapebench.cache import atomic_write

log = logging.getLogger("drapebench")

FORMATS = ("usd", "obj", "pc2")
PC2_HEADER = struct.Struct("<12siiffi")  # signature, version, points, start frame, sampling (frames per sample), samples
EXPORT_DIR = "export"  # the sub-folder of the run directory


@dataclass
class Drape:
    """What is exported: garment positions (T, V, 3) m, faces (F, 3), rest positions (V, 3) and strain (T, V);
    body positions (T, Vb, 3) m, faces (Fb, 3) and rest positions (Vb, 3) (float32 / int64 numpy); fps (Hz);
    ``label`` a one-line description (method, garment, motion)."""

    garment: np.ndarray
    garment_faces: np.ndarray
    garment_rest: np.ndarray
    strain: np.ndarray
    body: np.ndarray
    body_faces: np.ndarray
    body_rest: np.ndarray
    fps: float
    label: str

    @classmethod
    def from_scene(cls, vertices: torch.Tensor, garment, seq, body, label: str) -> Drape:
        """The drape ``vertices`` (T, V, 3) of ``garment`` on ``seq`` posed on ``body``."""
        from drapebench.viz import vertex_strain

        strain = vertex_strain(vertices.detach().cpu().double(), garment.topology.to(device="cpu", dtype=torch.float64))
        with torch.no_grad():
            rest = body.shaped(body.full_betas(seq.betas)[None])[0][0]

        def f32(t: torch.Tensor) -> np.ndarray:
            return t.detach().cpu().float().numpy()

        return cls(f32(vertices), garment.faces.cpu().numpy(), f32(garment.vertices), strain.astype(np.float32),
                   f32(seq.vertices(body)), body.faces.cpu().numpy(), f32(rest), float(seq.fps), label)  # fmt: skip


def drape_from_run(run_dir: str | Path) -> Drape:
    """The drape of a finished run: ``prediction.h5`` on the scene its ``config.yaml`` rebuilds
    (:meth:`drapebench.scene.Scene.from_config`: body, motion, garment in the run's dtype; on the CPU). Raises
    FileNotFoundError for a folder that is not a run, ValueError when the rebuilt garment or motion does not match the
    prediction (the code or the input files changed since the run)."""
    from omegaconf import OmegaConf

    from drapebench.results import read_prediction
    from drapebench.scene import Scene

    run_dir = Path(run_dir)
    missing = [n for n in ("prediction.h5", "config.yaml") if not (run_dir / n).exists()]
    if missing:
        raise FileNotFoundError(f"{run_dir} has no {' or '.join(missing)}: give the folder of a finished run (it prints it at the end)")
    vertices, faces, attrs = read_prediction(run_dir / "prediction.h5")
    scene = Scene.from_config(OmegaConf.load(run_dir / "config.yaml"), device="cpu")
    garment, seq = scene.garment, scene.seq
    if garment.faces.shape != faces.shape or not np.array_equal(garment.faces.numpy(), faces) or seq.n_frames != len(vertices):
        raise ValueError(f"{run_dir}: its config.yaml rebuilds a {garment.n_vertices}-vertex garment on {seq.n_frames} frames, "
                         f"prediction.h5 holds {vertices.shape[1]} vertices on {len(vertices)} frames: the code or an input file "
                         "changed since the run; run it again with export=usd (or obj, pc2)")  # fmt: skip
    label = f"{attrs.get('method')} {attrs.get('garment')} on {attrs.get('motion')} ({attrs.get('body')})"
    return Drape.from_scene(torch.from_numpy(vertices).to(scene.dtype), garment, seq, scene.body, label)


def require_usd() -> None:
    """Raise :class:`drapebench.extras.MissingExtra` naming the install when usd-core (the ``pxr`` package) is
    missing (obj and pc2 need nothing more)."""
    from drapebench.extras import require

    require("pxr.Usd", "export=usd")


def _obj_faces(faces: np.ndarray) -> bytes:
    return "".join(f"f {a} {b} {c}\n" for a, b, c in (faces + 1).tolist()).encode()


def _write_obj(path: Path, vertices: np.ndarray, faces: bytes) -> None:
    """An OBJ of vertices (V, 3) m (6 decimals: 1 um) and the face lines ``faces`` (:func:`_obj_faces`), atomically."""
    with atomic_write(path) as f:
        f.write((("v %.6f %.6f %.6f\n" * len(vertices)) % tuple(vertices.ravel().tolist())).encode())
        f.write(faces)


def _write_pc2(path: Path, vertices: np.ndarray) -> None:
    """A PC2 point cache of positions (T, V, 3) m: one sample per frame from frame 0, atomically."""
    T, V = vertices.shape[:2]
    with atomic_write(path) as f:
        f.write(PC2_HEADER.pack(b"POINTCACHE2\0", 1, V, 0.0, 1.0, T))
        f.write(np.ascontiguousarray(vertices, dtype="<f4").tobytes())


def _write_usd(path: Path, drape: Drape) -> None:
    """The time-sampled USD stage of the module docstring, atomically (binary crate format)."""
    require_usd()
    from pxr import Sdf, Usd, UsdGeom, Vt

    from drapebench.viz import strain_rgb

    T = len(drape.garment)
    stage = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    stage.SetTimeCodesPerSecond(drape.fps)
    stage.SetFramesPerSecond(drape.fps)
    stage.SetStartTimeCode(0)
    stage.SetEndTimeCode(T - 1)
    stage.GetRootLayer().documentation = f"drapebench drape: {drape.label}"
    stage.SetDefaultPrim(UsdGeom.Xform.Define(stage, "/drape").GetPrim())
    colors = strain_rgb(drape.strain).astype(np.float32) / 255.0
    for name, x, faces in (("garment", drape.garment, drape.garment_faces), ("body", drape.body, drape.body_faces)):
        mesh = UsdGeom.Mesh.Define(stage, f"/drape/{name}")
        mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)  # triangles as they are, not a subdivision cage
        mesh.CreateFaceVertexCountsAttr(Vt.IntArray([3] * len(faces)))
        mesh.CreateFaceVertexIndicesAttr(Vt.IntArray(faces.reshape(-1).tolist()))
        points, extent = mesh.CreatePointsAttr(), mesh.CreateExtentAttr()
        for t in range(T):
            points.Set(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(x[t])), t)
            extent.Set(Vt.Vec3fArray.FromNumpy(np.stack([x[t].min(0), x[t].max(0)])), t)
        if name == "garment":
            primvars = UsdGeom.PrimvarsAPI(mesh)
            strain = primvars.CreatePrimvar("strain", Sdf.ValueTypeNames.FloatArray, UsdGeom.Tokens.vertex)
            color = primvars.CreatePrimvar("displayColor", Sdf.ValueTypeNames.Color3fArray, UsdGeom.Tokens.vertex)
            for t in range(T):
                strain.Set(Vt.FloatArray.FromNumpy(np.ascontiguousarray(drape.strain[t])), t)
                color.Set(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(colors[t])), t)
    with atomic_write(path, mode=None, keep_suffix=True) as tmp:
        if not stage.GetRootLayer().Export(str(tmp)):
            raise OSError(f"usd-core could not write {path}")


def export_drape(run_dir: str | Path, drape: Drape, fmt: str) -> list[Path]:
    """Write ``drape`` in format ``fmt`` (usd, obj, pc2; module docstring) into ``<run_dir>/export``; returns the files."""
    if fmt not in FORMATS:
        raise ValueError(f"export format {fmt!r} is not one of {', '.join(FORMATS)} (export=usd|obj|pc2|none, --format)")
    out = Path(run_dir) / EXPORT_DIR
    meshes = (("garment", drape.garment, drape.garment_faces, drape.garment_rest), ("body", drape.body, drape.body_faces, drape.body_rest))
    if fmt == "usd":
        paths = [out / "drape.usd"]
        _write_usd(paths[0], drape)
    elif fmt == "obj":
        paths = []
        for name, x, faces, _ in meshes:
            lines = _obj_faces(faces)
            for t in range(len(x)):
                paths.append(out / "obj" / f"{name}_{t:04d}.obj")
                _write_obj(paths[-1], x[t], lines)
    else:
        paths = []
        for name, x, faces, rest in meshes:
            paths += [out / "pc2" / f"{name}.pc2", out / "pc2" / f"{name}_rest.obj"]
            _write_pc2(paths[-2], x)
            _write_obj(paths[-1], rest, _obj_faces(faces))
    return paths


def main(argv: list[str] | None = None) -> list[Path]:
    """Command line: export a finished run's drape (module docstring); prints what it wrote."""
    parser = argparse.ArgumentParser(prog="python -m drapebench.export", description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)  # fmt: skip
    parser.add_argument("run_dir", help="a run's folder (with prediction.h5 and config.yaml)")
    parser.add_argument("--format", choices=FORMATS, default="usd", help="usd (default): one stage; obj: a file per frame; pc2: point caches")
    args = parser.parse_args(argv)
    try:
        if args.format == "usd":
            require_usd()
        paths = export_drape(args.run_dir, drape_from_run(args.run_dir), args.format)
    except (ImportError, FileNotFoundError, ValueError) as err:
        parser.error(str(err))
    print(f"wrote {len(paths)} file(s) into {paths[0].parent}" + (f": {paths[0].name}" if len(paths) == 1 else ""))
    return paths


if __name__ == "__main__":
    main()
