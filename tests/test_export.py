"""drapebench.export: a finished run's drape as a USD stage, an OBJ per frame and PC2 point caches, each read back
and compared with prediction.h5; export=... as a run option."""

import struct
import sys
from pathlib import Path

import numpy as np
import pytest
from hydra import compose, initialize_config_dir

from drapebench.body import load_body, make_sequence
from drapebench.experiment import run
from drapebench.export import export_drape, main
from drapebench.garments import make_garment
from drapebench.results import read_prediction
from drapebench.schema import register

ROOT = Path(__file__).resolve().parents[1]
N_FRAMES, TRANSITION = 6, 2


@pytest.fixture(scope="module")
def finished_run(tmp_path_factory):
    """A short lbs drape on the low-res body, exported as USD by the run itself (export=usd)."""
    register()
    with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
        cfg = compose("config", overrides=["body=anny_lowres", "garment=skirt", "viz=none", "export=usd", "motion=kick",
                                           f"motion.n_frames={N_FRAMES}", f"motion.transition={TRANSITION}"])  # fmt: skip
    out = tmp_path_factory.mktemp("run")
    record = run(cfg, out)
    assert record["export_s"] > 0
    vertices, faces, attrs = read_prediction(out / "prediction.h5")
    body = load_body("anny_lowres")
    seq = make_sequence("kick", N_FRAMES, 30.0, seed=1000, transition=TRANSITION)
    return out, vertices, faces, seq.vertices(body).numpy(), body.faces.numpy()


def _read_obj(path: Path) -> tuple[np.ndarray, np.ndarray]:
    v, f = [], []
    for line in path.read_text().splitlines():
        kind, *values = line.split()
        (v if kind == "v" else f).append(values)
    return np.array(v, dtype=np.float64), np.array(f, dtype=np.int64) - 1


def _strain(x: np.ndarray, rest: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Mean |l - l0| / l0 over each vertex's edges (T, V), computed here from the faces."""
    edges = np.unique(np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1), axis=0)
    l0 = np.linalg.norm(rest[edges[:, 0]] - rest[edges[:, 1]], axis=-1)
    rel = np.abs(np.linalg.norm(x[:, edges[:, 0]] - x[:, edges[:, 1]], axis=-1) - l0) / l0
    total, count = np.zeros(x.shape[:2]), np.zeros(x.shape[1])
    for k in range(2):
        np.add.at(total, (slice(None), edges[:, k]), rel)
        np.add.at(count, edges[:, k], 1)
    return total / count


def test_usd_stage_holds_the_prediction_at_the_runs_time_codes_and_frame_rate(finished_run):
    from pxr import Usd, UsdGeom

    out, vertices, faces, body_vertices, body_faces = finished_run
    stage = Usd.Stage.Open(str(out / "export" / "drape.usd"))
    T = N_FRAMES + TRANSITION
    assert stage.GetTimeCodesPerSecond() == 30.0 and stage.GetFramesPerSecond() == 30.0
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (0.0, T - 1.0)
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z and UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    garment, body = (UsdGeom.Mesh(stage.GetPrimAtPath(f"/drape/{n}")) for n in ("garment", "body"))
    assert garment.GetPointsAttr().GetTimeSamples() == list(range(T))
    assert np.array_equal(np.array(garment.GetFaceVertexIndicesAttr().Get()).reshape(-1, 3), faces)
    assert set(garment.GetFaceVertexCountsAttr().Get()) == {3}
    top = UsdGeom.Xformable(stage.GetPrimAtPath("/drape"))  # the root's translation, double precision; points relative to it
    root = np.stack([np.array(top.ComputeLocalToWorldTransform(t).ExtractTranslation()) for t in range(T)])[:, None]
    points = np.stack([np.array(garment.GetPointsAttr().Get(t)) for t in range(T)]) + root
    assert np.abs(points - vertices).max() < 1e-6
    body_points = np.stack([np.array(body.GetPointsAttr().Get(t)) for t in range(T)]) + root
    assert np.abs(body_points - body_vertices).max() < 1e-6
    assert np.array_equal(np.array(body.GetFaceVertexIndicesAttr().Get()).reshape(-1, 3), body_faces)
    strain = UsdGeom.PrimvarsAPI(garment).GetPrimvar("strain")
    assert strain.GetInterpolation() == UsdGeom.Tokens.vertex
    values = np.stack([np.array(strain.Get(t)) for t in range(T)])
    rest = make_garment("skirt", load_body("anny_lowres")).vertices.numpy()
    assert np.abs(values - _strain(vertices.astype(np.float64), rest.astype(np.float64), faces)).max() < 1e-5
    assert values[0].max() < 1e-5 < values[-1].max()  # frame 0 is the rest pose, the kick stretches it


def test_obj_sequence_and_pc2_caches_read_back_as_the_prediction(finished_run):
    out, vertices, faces, body_vertices, body_faces = finished_run
    T = N_FRAMES + TRANSITION
    paths = main([str(out), "--format", "obj"])
    assert len(paths) == 2 * T and not list((out / "export").rglob(".*.tmp*"))
    for t in (0, T - 1):
        v, f = _read_obj(out / "export" / "obj" / f"garment_{t:04d}.obj")
        assert np.array_equal(f, faces) and np.abs(v - vertices[t]).max() <= 5e-7 + 1e-7  # 6 decimals
        v, f = _read_obj(out / "export" / "obj" / f"body_{t:04d}.obj")
        assert np.array_equal(f, body_faces) and np.abs(v - body_vertices[t]).max() < 1e-6
    main([str(out), "--format", "pc2"])
    for name, x, x_faces in (("garment", vertices, faces), ("body", body_vertices, body_faces)):
        data = (out / "export" / "pc2" / f"{name}.pc2").read_bytes()
        signature, version, points, start, sampling, samples = struct.unpack_from("<12siiffi", data)  # Blender's PC2 header
        assert (signature, version, points, start, sampling, samples) == (b"POINTCACHE2\0", 1, x.shape[1], 0.0, 1.0, T)
        assert len(data) == 32 + T * x.shape[1] * 12
        cache = np.frombuffer(data, dtype="<f4", offset=32).reshape(T, -1, 3)
        assert np.abs(cache - x).max() < 1e-6
        rest, rest_faces = _read_obj(out / "export" / "pc2" / f"{name}_rest.obj")
        assert np.array_equal(rest_faces, x_faces) and len(rest) == x.shape[1]
    rest, _ = _read_obj(out / "export" / "pc2" / "garment_rest.obj")
    assert np.abs(rest - make_garment("skirt", load_body("anny_lowres")).vertices.numpy()).max() <= 6e-7


def test_usd_again_from_the_command_line_replaces_the_stage_atomically(finished_run):
    from pxr import Usd

    out = finished_run[0]
    (out / "export" / "drape.usd").write_text("stale")  # the export must replace it with a stage
    (path,) = main([str(out)])  # --format usd is the default
    assert path == out / "export" / "drape.usd" and path.read_bytes() != b"stale"
    assert Usd.Stage.Open(str(path)).GetEndTimeCode() == N_FRAMES + TRANSITION - 1
    assert not list((out / "export").glob(".*"))


def test_export_errors_name_the_fix(finished_run, tmp_path, capsys, monkeypatch):
    with pytest.raises(SystemExit):
        main([str(tmp_path), "--format", "pc2"])
    assert "has no prediction.h5 or config.yaml: give the folder of a finished run" in capsys.readouterr().err
    monkeypatch.setitem(sys.modules, "pxr.Usd", None)  # usd-core not installed
    with pytest.raises(SystemExit):
        main([str(finished_run[0])])
    assert "export=usd needs usd-core, which is not installed: pip install 'drapebench[export]'" in capsys.readouterr().err
    with pytest.raises(ValueError, match="export format 'fbx' is not one of usd, obj, pc2"):
        export_drape(tmp_path, None, "fbx")


def test_an_export_after_the_motion_file_changed_is_refused(tmp_path, capsys):
    """The run records its inputs' hashes; the same file exports, a changed one (poses of another motion under the
    same name) is refused, naming the motion and its path, instead of pairing the old garment with the new body."""
    register()
    kick = make_sequence("kick", 4, 30.0, seed=3, transition=0)
    np.savez(tmp_path / "m.npz", poses=kick.poses.numpy(), trans=kick.trans.numpy(), fps=30.0)
    with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
        cfg = compose("config", overrides=["body=anny_lowres", "garment=skirt", "viz=none", "motion=file",
                                           f"motion.path={tmp_path / 'm.npz'}", "motion.transition=2"])  # fmt: skip
    run(cfg, tmp_path / "run")
    assert len(main([str(tmp_path / "run"), "--format", "pc2"])) == 4  # unchanged: exported
    np.savez(tmp_path / "m.npz", poses=0.5 * kick.poses.numpy(), trans=kick.trans.numpy(), fps=30.0)
    with pytest.raises(SystemExit):
        main([str(tmp_path / "run"), "--format", "pc2"])
    assert f"the motion of this run changed since it ran (motion=file (motion.path={tmp_path / 'm.npz'}))" in capsys.readouterr().err


def test_an_export_clears_a_killed_exports_temporary_files_and_names_a_folder_it_cannot_write(finished_run, tmp_path, capsys):
    import shutil

    out = tmp_path / "run"
    shutil.copytree(finished_run[0], out)
    stale = out / "export" / "obj" / ".garment_0000.obj.k1ll3d.tmp"  # what atomic_write leaves when the process is killed
    stale.parent.mkdir(parents=True, exist_ok=True)
    stale.write_text("v 0 0")
    main([str(out), "--format", "obj"])
    assert not stale.exists() and (out / "export" / "obj" / "garment_0000.obj").exists()
    shutil.rmtree(out / "export" / "pc2", ignore_errors=True)  # an earlier test's pc2 export
    (out / "export" / "pc2").write_text("a file where the export's folder goes")
    with pytest.raises(SystemExit):
        main([str(out), "--format", "pc2"])
    err = capsys.readouterr().err
    assert f"cannot write the pc2 export into {out / 'export'}" in err and "make the folder writable" in err and "Traceback" not in err


def test_usd_display_colour_follows_each_frames_strain(finished_run):
    from pxr import Usd, UsdGeom

    from drapebench.viz import strain_rgb

    stage = Usd.Stage.Open(str(finished_run[0] / "export" / "drape.usd"))
    primvars = UsdGeom.PrimvarsAPI(stage.GetPrimAtPath("/drape/garment"))
    T = N_FRAMES + TRANSITION
    colours = [np.array(primvars.GetPrimvar("displayColor").Get(t)) for t in range(T)]
    for t in (0, T - 1):
        strain = np.array(primvars.GetPrimvar("strain").Get(t), dtype=np.float32)
        assert np.allclose(colours[t], strain_rgb(strain) / 255.0, atol=1e-6), t
    assert not np.allclose(colours[0], colours[-1])  # the kick stretches the skirt: its colours change
