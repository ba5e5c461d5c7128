"""A run's drape for animation tools: ``python -m drapebench.export <run dir> --format usd|obj|pc2``, or
``export=usd|obj|pc2`` in a run (after the drape).

Into ``<run dir>/export/``, every file written atomically (a temporary file renamed into place):

* ``usd``: ``drape.usd``, one stage with the meshes ``/drape/garment`` and ``/drape/body``, their points
  time-sampled (time code k = frame k of ``prediction.h5``) relative to the frame's root, whose translation is the
  time-sampled double-precision ``xformOp:translate`` of ``/drape`` (USD points are float32: so they keep their
  resolution at the body's scale however far the motion goes), the garment's per-vertex strain as the primvar
  ``strain`` (mean relative edge-length change, 0.1 = 10 %) and as ``displayColor`` (the recording's white ->
  red); metres (metersPerUnit 1), Z up, timeCodesPerSecond = framesPerSecond = the run's fps. Needs
  ``usd-core`` (``pip install -e ".[export]"``).
* ``obj``: ``obj/garment_0000.obj``, ``obj/body_0000.obj``, ... one pair per frame.
* ``pc2``: ``pc2/garment.pc2`` and ``pc2/body.pc2`` point caches (Blender's Mesh Cache modifier: header
  ``POINTCACHE2\\0``, version 1, points, start frame 0, 1 sample per frame, samples; then float32 xyz) with the
  rest meshes ``pc2/garment_rest.obj`` and ``pc2/body_rest.obj`` (same vertex order). The format holds float32
  only: positions beyond 1 km of the origin are rounded more coarsely than 0.1 mm (logged; use usd or obj).

Metres, Z up, the body facing -Y (the suite's frame) in every format; OBJ coordinates to 1 um. The export is made
from what the run recorded: ``prediction.h5`` holds the content hashes of its body, motion and garment
(:func:`input_hashes`), and a scene rebuilt from ``config.yaml`` whose inputs hash otherwise is refused
(:class:`RunInputsChanged`). Temporary files an earlier, killed export left in ``export/`` are removed first; a
folder that cannot be written raises :class:`ExportFailed`.
"""

from __future__ import annotations

import argparse
import json
import logging
import re
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from drapebench.cache import atomic_write, body_key, content_hash
from drapebench.garments.factory import garment_label

log = logging.getLogger("drapebench")

FORMATS = ("usd", "obj", "pc2")
PC2_HEADER = struct.Struct("<12siiffi")  # signature, version, points, start frame, sampling (frames per sample), samples
EXPORT_DIR = "export"  # the sub-folder of the run directory
PC2_EXACT = 1000.0  # m: farther from the origin, PC2's float32 rounds positions more coarsely than 0.1 mm (logged)
TEMPORARY = re.compile(r"^\..+\.tmp(\.\w+)?$")  # drapebench.cache.atomic_write's temporary names


class RunInputsChanged(ValueError):
    """An input of a finished run (its body, motion or garment) differs from what the run recorded; nothing is exported."""


class ExportFailed(OSError):
    """The export folder could not be written; the message names it, the cause and the fix."""


def input_hashes(garment, seq, body) -> dict:
    """Content hashes of what a drape depends on besides the method: ``body`` (:func:`drapebench.cache.body_key`),
    ``motion`` (the sequence's betas, poses, root translation, fps, transition) and ``garment`` (rest vertices,
    faces). Stored with the run (``prediction.h5``'s ``inputs``) and compared by :func:`drape_from_run`."""
    return {"body": body_key(body), "motion": content_hash(seq.betas, seq.poses, seq.trans, float(seq.fps), int(seq.n_transition)),
            "garment": content_hash(garment.vertices, garment.faces)}  # fmt: skip


@dataclass
class Drape:
    """What is exported: garment positions (T, V, 3) m, faces (F, 3), rest positions (V, 3) and strain (T, V);
    body positions (T, Vb, 3) m, faces (Fb, 3) and rest positions (Vb, 3) (numpy: positions in the run's dtype,
    float32 or float64; faces int64); fps (Hz); ``label`` a one-line description (method, garment, motion); ``root``
    (T, 3) float64 m, each frame's root translation (USD's translate)."""

    garment: np.ndarray
    garment_faces: np.ndarray
    garment_rest: np.ndarray
    strain: np.ndarray
    body: np.ndarray
    body_faces: np.ndarray
    body_rest: np.ndarray
    fps: float
    label: str
    root: np.ndarray

    @classmethod
    def from_scene(cls, vertices: torch.Tensor, garment, seq, body, label: str) -> Drape:
        """The drape ``vertices`` (T, V, 3) of ``garment`` on ``seq`` posed on ``body``."""
        from drapebench.viz import vertex_strain

        strain = vertex_strain(vertices.detach().cpu().double(), garment.topology.to(device="cpu", dtype=torch.float64))
        with torch.no_grad():
            rest = body.shaped(body.full_betas(seq.betas)[None])[0][0]

        dtype = torch.float64 if vertices.dtype == torch.float64 else torch.float32  # the run's

        def kept(t: torch.Tensor) -> np.ndarray:
            return t.detach().cpu().to(dtype).numpy()

        return cls(kept(vertices), garment.faces.cpu().numpy(), kept(garment.vertices), strain.astype(np.float32),
                   kept(seq.vertices(body)), body.faces.cpu().numpy(), kept(rest), float(seq.fps), label,
                   seq.trans.detach().cpu().double().numpy())  # fmt: skip


def drape_from_run(run_dir: str | Path) -> Drape:
    """The drape of a finished run: ``prediction.h5`` on the scene its ``config.yaml`` rebuilds
    (:meth:`drapebench.scene.Scene.from_config`: body, motion, garment in the run's dtype; on the CPU). Raises
    FileNotFoundError for a folder that is not a run, :class:`RunInputsChanged` when the rebuilt body, motion or
    garment is not what the run recorded (:func:`input_hashes`; an input file or the code changed since the run). A
    run recorded before the hashes is checked by its garment's faces and frame count only (logged)."""
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
        raise RunInputsChanged(f"{run_dir}: its config.yaml rebuilds a {garment.n_vertices}-vertex garment on {seq.n_frames} frames, "
                         f"prediction.h5 holds {vertices.shape[1]} vertices on {len(vertices)} frames: the code or an input file "
                         "changed since the run; run it again with export=usd (or obj, pc2)")  # fmt: skip
    if "inputs" in attrs:
        recorded, now = json.loads(attrs["inputs"]), input_hashes(garment, seq, scene.body)
        changed = [k for k in recorded if recorded[k] != now.get(k)]
        if changed:
            given = {"body": f"body.name={scene.cfg.body.name}", "motion": f"motion={scene.cfg.motion.name}" + (
                f" (motion.path={scene.cfg.motion.path})" if scene.cfg.motion.get("path") else ""),
                "garment": f"garment={garment_label(scene.cfg.garment)}" + (f" (garment.path={scene.cfg.garment.path})" if scene.cfg.garment.get("path") else "")}  # fmt: skip
            raise RunInputsChanged(f"{run_dir}: the {' and '.join(changed)} of this run changed since it ran "
                                   f"({'; '.join(given[k] for k in changed)}): its drape no longer belongs to them. Put the "
                                   "original file(s) back, or run it again with export=usd (or obj, pc2)")  # fmt: skip
    else:
        log.warning("%s was recorded without its inputs' hashes: only its garment's faces and frame count are checked", run_dir)
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
    """A PC2 point cache of positions (T, V, 3) m: one sample per frame from frame 0, atomically (float32, logged
    beyond :data:`PC2_EXACT` of the origin)."""
    T, V = vertices.shape[:2]
    far = float(np.abs(vertices).max()) if vertices.size else 0.0
    if far > PC2_EXACT:
        log.warning("%s: positions up to %.4g m from the origin, where PC2's float32 rounds them to %.2g mm; export usd or obj "
                    "for the run's precision", path.name, far, 1e3 * float(np.spacing(np.float32(far))))  # fmt: skip
    with atomic_write(path) as f:
        f.write(PC2_HEADER.pack(b"POINTCACHE2\0", 1, V, 0.0, 1.0, T))
        f.write(np.ascontiguousarray(vertices, dtype="<f4").tobytes())


def _write_usd(path: Path, drape: Drape) -> None:
    """The time-sampled USD stage of the module docstring, atomically (binary crate format)."""
    require_usd()
    from pxr import Gf, Sdf, Usd, UsdGeom, Vt

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
    top = UsdGeom.Xform.Define(stage, "/drape")
    stage.SetDefaultPrim(top.GetPrim())
    translate = top.AddTranslateOp(UsdGeom.XformOp.PrecisionDouble)  # the root, in float64; the points relative to it
    for t in range(T):
        translate.Set(Gf.Vec3d(*drape.root[t].tolist()), t)
    colors = strain_rgb(drape.strain).astype(np.float32) / 255.0
    for name, x, faces in (("garment", drape.garment, drape.garment_faces), ("body", drape.body, drape.body_faces)):
        mesh = UsdGeom.Mesh.Define(stage, f"/drape/{name}")
        mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)  # triangles as they are, not a subdivision cage
        mesh.CreateFaceVertexCountsAttr(Vt.IntArray([3] * len(faces)))
        mesh.CreateFaceVertexIndicesAttr(Vt.IntArray(faces.reshape(-1).tolist()))
        points, extent = mesh.CreatePointsAttr(), mesh.CreateExtentAttr()
        for t in range(T):
            local = (x[t] - drape.root[t]).astype(np.float32)
            points.Set(Vt.Vec3fArray.FromNumpy(local), t)
            extent.Set(Vt.Vec3fArray.FromNumpy(np.stack([local.min(0), local.max(0)])), t)
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
    """Write ``drape`` in format ``fmt`` (usd, obj, pc2; module docstring) into ``<run_dir>/export``; returns the files.
    Temporary files of an earlier, killed export are removed first (logged). Raises :class:`ExportFailed` naming the
    folder, the cause and the fix when it cannot be written."""
    if fmt not in FORMATS:
        raise ValueError(f"export format {fmt!r} is not one of {', '.join(FORMATS)} (export=usd|obj|pc2|none, --format)")
    out = Path(run_dir) / EXPORT_DIR
    try:
        stale = [p for p in out.rglob(".*") if p.is_file() and TEMPORARY.match(p.name)] if out.is_dir() else []
        for p in stale:
            p.unlink()
        if stale:
            log.warning("removed %d temporary file(s) an earlier, interrupted export left in %s", len(stale), out)
        return _write_format(out, drape, fmt)
    except OSError as err:
        raise ExportFailed(f"cannot write the {fmt} export into {out}: {err.strerror or err}"
                           f"{f' ({err.filename})' if err.filename else ''}; make the folder writable (or move what is in the "
                           "way), or copy the run folder somewhere writable and export it there") from err  # fmt: skip


def _write_format(out: Path, drape: Drape, fmt: str) -> list[Path]:
    """The files of ``fmt`` (module docstring) in ``out``; returns them."""
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
    except (ImportError, OSError, ValueError) as err:
        parser.error(str(err))
    print(f"wrote {len(paths)} file(s) into {paths[0].parent}" + (f": {paths[0].name}" if len(paths) == 1 else ""))
    return paths


if __name__ == "__main__":
    main()
