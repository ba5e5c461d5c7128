"""Bad input at every entry point (run.py overrides, the Python API, files on disk) fails with a message that
names the problem and the fix, and leaves no partial file; a user's own garment and motion work from run.py.

Covered elsewhere: a truncated or corrupt cache file of every kind (tests/test_cache.py), a truncated
training checkpoint and a training killed mid-way then started again (tests/train/test_trainer.py), a run
interrupted mid-way (tests/test_experiment.py), a damaged body file (tests/body/test_model.py), broken
garment meshes by check name (tests/garments/test_factory.py), bad materials (tests/physics/test_material.py).
"""

import logging
import multiprocessing
from pathlib import Path

import h5py
import numpy as np
import pytest
import torch
from hydra import compose, initialize_config_dir

import methods
from drapebench.body import BodySequence, load_body, make_sequence
from drapebench.body.motion_file import load_motion
from drapebench.body.motion_source import sequence_from_config
from drapebench.cache import Cache
from drapebench.experiment import run, warn_untrained_shape
from drapebench.garments import garment_from_config, load_garment, make_garment
from drapebench.garments.pins import MIN_PINS
from drapebench.physics import Material
from drapebench.schema import check_keys, register

ROOT = Path(__file__).resolve().parents[1]
register()


def _compose(overrides):
    with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
        return compose("config", overrides=overrides)


# ---------------------------------------------------------------- config keys (issue point 7)
@pytest.mark.parametrize(
    "override, named, listed",
    [("+garment.obj=my.obj", "'garment.obj'", "'garment.kind', 'garment.name', 'garment.params', 'garment.path', 'garment.pins', 'garment.seed'"),
     ("+garmnet=skirt", "did you mean 'garment'", "'garment'"), ("+motion.foo=1", "'motion.foo'", "'motion.betas', 'motion.fps'")],
)  # fmt: skip
def test_a_key_added_with_plus_that_nothing_reads_fails_naming_it_and_the_valid_keys(override, named, listed, tmp_path):
    cfg = _compose([override, "body=anny_lowres", "viz=none"])
    with pytest.raises(ValueError, match=named) as err:
        run(cfg, tmp_path / "out")
    assert "nothing reads it" in str(err.value) and "valid: [" in str(err.value) and listed in str(err.value)
    assert not (tmp_path / "out").exists()  # nothing written
    check_keys(_compose(["body=anny_lowres"]))  # the defaults pass


def test_lbs_rejects_a_parameter_it_does_not_read():
    import methods

    with pytest.raises(ValueError, match=r"unknown lbs parameter\(s\) \['foo'\]"):
        methods.get("lbs")({"foo": 1})
    methods.get("lbs")({})


# ---------------------------------------------------------------- a user's garment (issue point 6)
@pytest.fixture(scope="module")
def skirt_obj(tmp_path_factory, body_lowres):
    path = tmp_path_factory.mktemp("user") / "skirt.obj"
    g = make_garment("skirt", body_lowres)
    g.export(path)
    return path, g


def test_a_user_garment_gets_pins_on_its_top_band_or_the_ones_given(skirt_obj, body_lowres):
    path, made = skirt_obj
    g = garment_from_config({"kind": "obj", "path": str(path), "pins": None, "params": {}, "seed": 0}, body_lowres)
    assert g.kind == "obj" and g.pins.numel() >= MIN_PINS
    z = g.vertices[:, 2]
    assert z[g.pins].min() > z.max() - 0.25  # the waistband, not the hem
    assert z[g.pins].mean() > z.mean()
    given = garment_from_config({"kind": "obj", "path": str(path), "pins": [0, 1, 2, 3], "params": {}}, body_lowres)
    assert given.pins.tolist() == [0, 1, 2, 3]
    with pytest.raises(ValueError, match=r"pin indices \[99999\] are outside"):
        load_garment(path, body_lowres, pins=[0, 1, 99999])
    with pytest.raises(ValueError, match="garment.path is read only by garment=obj"):
        garment_from_config({"kind": "skirt", "path": str(path), "params": {}}, body_lowres)
    with pytest.raises(ValueError, match="garment=obj reads path and pins"):
        garment_from_config({"kind": "obj", "path": str(path), "params": {"ease": 0.01}}, body_lowres)
    with pytest.raises(ValueError, match=r"garment=obj needs the file: garment.path="):
        garment_from_config(dict(_compose(["garment=obj"]).garment), body_lowres)


def _write_obj(path, V, F):
    with open(path, "w") as f:
        f.writelines(f"v {x} {y} {z}\n" for x, y, z in V)
        f.writelines(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in F)


def test_a_user_garment_that_is_no_mesh_too_large_or_inside_the_body_fails_with_the_fix(tmp_path, skirt_obj, body_lowres):
    _, g = skirt_obj
    V, F = g.vertices.numpy().astype(np.float64), g.faces.numpy()
    (tmp_path / "text.obj").write_text("just some text\n")
    with pytest.raises(ValueError, match=r"is not a mesh: 0 vertices and 0 faces"):
        load_garment(tmp_path / "text.obj", body_lowres)
    (tmp_path / "binary.obj").write_bytes(bytes(range(256)))
    with pytest.raises(ValueError, match="not a text OBJ"):
        load_garment(tmp_path / "binary.obj", body_lowres)
    _write_obj(tmp_path / "cm.obj", V * 100, F)
    with pytest.raises(ValueError, match=r"looks like centimetres: scale by 0.01") as err:
        load_garment(tmp_path / "cm.obj", body_lowres)
    assert "fix units" in str(err.value)
    _write_obj(tmp_path / "away.obj", V + [0.0, 0.0, 3.0], F)
    with pytest.raises(ValueError, match="does not overlap the body"):
        load_garment(tmp_path / "away.obj", body_lowres)
    centre = np.array([V[:, 0].mean(), V[:, 1].mean(), 0.0])
    shrunk = (V - centre) * [0.7, 0.7, 1.0] + centre  # pulled into the hips
    _write_obj(tmp_path / "inside.obj", shrunk, F)
    with pytest.raises(ValueError, match="inside_body") as err:
        load_garment(tmp_path / "inside.obj", body_lowres)
    assert "fix inside_body: the garment must start outside the body" in str(err.value)


# ---------------------------------------------------------------- a user's motion (issue point 6)
@pytest.fixture(scope="module")
def kick():
    return make_sequence("kick", 12, 30.0, seed=3, transition=0)


def test_a_motion_file_round_trips_after_the_blend_from_the_rest_pose(tmp_path, kick, body_lowres):
    np.savez(tmp_path / "kick.npz", poses=kick.poses.numpy(), trans=kick.trans.numpy(), fps=25.0, betas=np.array([1.0, -0.5]))
    seq = load_motion(tmp_path / "kick.npz", body_lowres, transition=5)
    assert seq.n_frames == 5 + 12 and seq.n_transition == 5 and seq.fps == 25.0
    assert torch.equal(seq.poses[5:], kick.poses) and torch.equal(seq.trans[5:], kick.trans)
    assert torch.equal(seq.poses[0], torch.zeros_like(seq.poses[0]))  # starts at the rest pose the garment is made on
    step = (seq.poses[1:6] - seq.poses[:5]).norm(dim=(1, 2))
    assert step.max() < 0.5 * (kick.poses[0]).norm()  # a blend, not a jump
    assert seq.betas.tolist() == [1.0, -0.5] + [0.0] * 8
    with h5py.File(tmp_path / "kick.h5", "w") as f:  # h5 with fps as an attribute, poses flattened (T, 3J)
        f["poses"] = kick.poses.reshape(12, -1).numpy()
        f.attrs["fps"] = 30.0
    seq = load_motion(tmp_path / "kick.h5", body_lowres, transition=0, n_frames=10)
    assert seq.n_frames == 10 and torch.equal(seq.poses, kick.poses[:10]) and not seq.trans.any()


@pytest.mark.parametrize(
    "arrays, message",
    [
        (lambda p, t: {"pose": p}, r"has no 'poses' array \(found \['pose'\]\)"),
        (lambda p, t: {"poses": p[:, :21], "fps": 30}, r"poses have 21 joints, body anny_lowres has 22; .*0 pelvis, 1 spine1"),
        (lambda p, t: {"poses": np.degrees(p) + 200, "fps": 30}, "degrees"),
        (lambda p, t: {"poses": p, "trans": t * 100 + np.arange(len(t))[:, None], "fps": 30}, "centimetres"),
        (lambda p, t: {"poses": np.tile(np.eye(3), (len(p), 22, 1, 1)), "fps": 30}, "rotation matrices"),
        (lambda p, t: {"poses": p}, r"has no fps; give it in the file or as motion.fps"),
        (lambda p, t: {"poses": p[:1], "fps": 30}, "1 frame"),
        (lambda p, t: {"poses": p, "fps": 0}, "fps must be > 0"),
        (lambda p, t: {"poses": p, "fps": 30, "betas": np.ones(12)}, r"12 betas given; body anny_lowres has 10"),
    ],
)
def test_a_bad_motion_file_fails_naming_the_problem(arrays, message, tmp_path, kick, body_lowres):
    np.savez(tmp_path / "m.npz", **arrays(kick.poses.numpy(), kick.trans.numpy()))
    with pytest.raises(ValueError, match=message):
        load_motion(tmp_path / "m.npz", body_lowres)


@pytest.mark.parametrize(
    "arrays, message",
    [
        (lambda p, t: {"poses": np.zeros((0, 22, 3)), "fps": 30}, r"m.npz: poses is empty \(shape \(0, 22, 3\)\); give \(T, J, 3\)"),
        (lambda p, t: {"poses": np.ones(p.shape, dtype=bool), "fps": 30}, r"m.npz: poses holds booleans \(bool\), not numbers; give"),
        (lambda p, t: {"poses": np.full(p.shape, "0.1"), "fps": 30}, r"m.npz: poses holds text \(<U3\), not numbers"),
        (lambda p, t: {"poses": p, "trans": np.zeros((0, 3)), "fps": 30}, r"m.npz: trans is empty .*or leave trans out"),
        (lambda p, t: {"poses": p, "trans": t.astype(bool), "fps": 30}, r"m.npz: trans holds booleans"),
        (lambda p, t: {"poses": p, "fps": np.array([])}, r"m.npz: fps is empty .*e.g. fps=30"),
        (lambda p, t: {"poses": p, "fps": "thirty"}, r"m.npz: fps holds text .*e.g. fps=30"),
        (lambda p, t: {"poses": p, "fps": True}, r"m.npz: fps holds booleans"),
        (lambda p, t: {"poses": p, "fps": [30, 60]}, r"m.npz: fps holds 2 values"),
        (lambda p, t: {"poses": p, "fps": np.inf}, r"fps must be > 0 and finite .*got inf"),
        (lambda p, t: {"poses": p, "fps": 30, "betas": np.array([], dtype=np.float32)}, r"m.npz: betas is empty .*leave betas out"),
        (lambda p, t: {"poses": p, "fps": 30, "betas": np.array(["tall"])}, r"m.npz: betas holds text"),
        (lambda p, t: {"poses": p, "fps": 30, "betas": np.array([True, False])}, r"m.npz: betas holds booleans"),
        (lambda p, t: {"poses": p, "fps": 30, "betas": np.array([0.0, 300.0])}, r"m.npz's betas: body shape b1=300 is outside \+-5"),
        (lambda p, t: {"poses": p, "trans": t + [0.0, 0.0, 5.0], "fps": 30}, r"first frame's root is 5.0\d* m above the rest pose"),
        (lambda p, t: {"poses": np.array([p[0], None], dtype=object), "fps": 30}, r"m.npz: poses holds Python objects \(an object array\)"),
    ],
)
def test_a_motion_file_with_empty_text_or_boolean_arrays_names_the_file_the_key_and_the_fix(arrays, message, tmp_path, kick, body_lowres):
    np.savez(tmp_path / "m.npz", **arrays(kick.poses.numpy(), kick.trans.numpy()))
    with pytest.raises(ValueError, match=message):
        load_motion(tmp_path / "m.npz", body_lowres)


def test_a_motion_file_far_from_the_origin_is_moved_to_start_above_it(tmp_path, kick, body_lowres, caplog):
    np.savez(tmp_path / "far.npz", poses=kick.poses.numpy(), trans=kick.trans.numpy().astype(np.float64) + [1.0e4, -2.5e4, 0.0], fps=30)
    with caplog.at_level(logging.INFO, logger="drapebench"):
        seq = load_motion(tmp_path / "far.npz", body_lowres, transition=3)
    assert "the root starts at x=1e+04, y=-2.5e+04 m; the motion is moved to start above the origin" in caplog.text
    assert torch.allclose(seq.trans[3:], kick.trans - kick.trans[:1] * torch.tensor([1.0, 1.0, 0.0]), atol=1e-6)  # not 1 mm apart


def test_a_slow_centimetre_sway_is_refused_naming_the_unit(tmp_path, body_lowres):
    """Standing still (pose 0 with a 1 mrad tremor) while the root sways +-2 cm over 3 s, written in centimetres: 4 cm/s,
    read as 4 m/s, is no fast root, but a +-2 m sway while no joint moves is no human motion in metres."""
    T, fps = 90, 30.0
    t = np.arange(T) / fps
    poses = 1e-3 * np.sin(t)[:, None, None] * np.ones((T, 22, 3))
    sway = np.stack([0.02 * np.sin(2 * np.pi * t / 3), np.zeros(T), 0.005 * np.cos(2 * np.pi * t / 3)], 1)  # metres
    np.savez(tmp_path / "cm.npz", poses=poses, trans=100 * sway, fps=fps)
    with pytest.raises(ValueError, match=r"cm.npz: the root travels .* m while no joint moves more than .* relative to it, implausible "
                                         r"for body anny_lowres \(1.70 m tall\); trans looks like centimetres: divide it by 100"):  # fmt: skip
        load_motion(tmp_path / "cm.npz", body_lowres)
    np.savez(tmp_path / "m.npz", poses=poses, trans=sway, fps=fps)
    assert load_motion(tmp_path / "m.npz", body_lowres, transition=0).trans.abs().max() < 0.03  # the same sway in metres


def test_unreadable_or_missing_motion_files(tmp_path, body_lowres):
    (tmp_path / "cut.npz").write_bytes(b"PK\x03\x04 truncated")
    with pytest.raises(ValueError, match="cannot be read as npz"):
        load_motion(tmp_path / "cut.npz", body_lowres)
    with pytest.raises(FileNotFoundError, match="motion.path must name"):
        load_motion(tmp_path / "nope.npz", body_lowres)
    (tmp_path / "m.bvh").write_text("HIERARCHY")
    with pytest.raises(ValueError, match="unsupported motion file type '.bvh'"):
        load_motion(tmp_path / "m.bvh", body_lowres)


def test_run_py_drapes_a_user_garment_on_a_user_motion(tmp_path, skirt_obj, kick):
    np.savez(tmp_path / "kick.npz", poses=kick.poses.numpy(), trans=kick.trans.numpy(), fps=30.0)
    cfg = _compose(["body=anny_lowres", "viz=none", "garment=obj", f"garment.path={skirt_obj[0]}", "motion=file",
                    f"motion.path={tmp_path / 'kick.npz'}", "motion.transition=3"])  # fmt: skip
    record = run(cfg, tmp_path / "out")
    assert record["garment"] == "obj" and record["motion"] == "file" and record["n_frames"] == 12 + 3
    assert np.isfinite(record["eps_c"]) and (tmp_path / "out" / "metrics.json").exists()


# ---------------------------------------------------------------- body shape, device, frames (issue point 9)
def test_one_rule_for_betas_fewer_padded_more_or_nan_rejected(body_lowres, kick, caplog):
    with caplog.at_level(logging.INFO, logger="drapebench"):
        assert body_lowres.full_betas([1.0, 2.0, 3.0], note=True).tolist() == [1.0, 2.0, 3.0] + [0.0] * 7
    assert "3 betas given; zero-padded" in caplog.text
    with pytest.raises(ValueError, match="11 betas given; body anny_lowres has 10 shape coefficients: give at most 10"):
        body_lowres.full_betas(torch.ones(11))
    with pytest.raises(ValueError, match="betas contains NaN"):
        body_lowres.full_betas([0.0, float("nan")])
    import methods

    lbs = methods.get("lbs")()
    lbs.bind(body_lowres, Material())
    g = make_garment("skirt", body_lowres)
    short = make_sequence("walk", 4, 30.0, 0, betas=[1.0, -1.0, 0.5], transition=0)
    padded = make_sequence("walk", 4, 30.0, 0, betas=[1.0, -1.0, 0.5] + [0.0] * 7, transition=0)
    assert torch.equal(lbs.drape(g, short).vertices, lbs.drape(g, padded).vertices)  # 3 betas work in the Python API
    long = make_sequence("walk", 4, 30.0, 0, betas=[0.0] * 10 + [2.0], transition=0)
    with pytest.raises(ValueError, match="11 betas given"):
        lbs.drape(g, long)  # not silently cut to 10


def test_betas_outside_the_training_range_warn(caplog):
    with caplog.at_level(logging.WARNING, logger="drapebench"):
        assert warn_untrained_shape([3.0, 0.0, 0.0, 0.0, 0.5], {"dataset": "train_small"}, None, "gensim") == [0, 4]
    assert "b0=3, b4=0.5 are outside the range gensim was trained on" in caplog.text
    assert warn_untrained_shape([1.0, 2.0], {"dataset": "train_small"}, None, "gensim") == []
    assert warn_untrained_shape([1.0, 2.0], {"dataset": "train_small"}, (0.5, 2.0), "gaps") == [0]
    assert methods.get("gaps")({"train": {"beta_range": [0.5, 2.0]}}).trained_beta_bound() == (0.5, 2.0)  # what the run passes
    assert methods.get("gaps")({}).trained_beta_bound() == (2.0, 2.0, 2.0, 2.0)  # GapsTrain's default, the code's
    assert methods.get("gaps")({"single_shape": True}).trained_beta_bound() == (0.0, 0.0, 0.0, 0.0)  # ncs_like: the mean body only
    assert methods.get("gensim")({}).trained_beta_bound() is None  # GenSim's shapes are its dataset's


def test_cuda_without_a_cuda_torch_names_the_fix(monkeypatch):
    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)
    with pytest.raises(ValueError, match=r"device=cuda requested but .*use device=cpu, or install a CUDA build of torch"):
        load_body("anny_lowres", device="cuda")
    with pytest.raises(ValueError, match="is not a torch device"):
        load_body("anny_lowres", device="gpu0")


@pytest.mark.parametrize("value", [float("nan"), float("inf"), "1.0"])
def test_a_motion_or_garment_parameter_that_is_not_a_finite_number_is_named(value, body_lowres):
    """``motion.params.amplitude=nan`` once failed with "pose contains NaN" and ``=inf`` gave a saturated pose silently;
    ``garment.params.length=nan`` failed with "the mesh has no faces to keep"."""
    m = {"name": "walk", "n_frames": 4, "fps": 30.0, "transition": 0, "seed": 0, "params": {"amplitude": value}}
    with pytest.raises(ValueError, match=rf"motion\.params\.amplitude must be a finite number, got .*; e\.g\. motion\.params\.amplitude=1\.0"):
        sequence_from_config(m, body_lowres)
    with pytest.raises(ValueError, match=r"garment\.params\.length must be a finite number, got .*; e\.g\. garment\.params\.length=0\.45"):
        make_garment("skirt", body_lowres, cache=False, length=value)
    assert make_sequence("walk", 4, amplitude=np.int64(2), transition=0).n_frames == 4  # numpy's numbers are numbers
    assert make_sequence("kick", 4, side="left", transition=0).n_frames == 4  # a word parameter is not a number


@pytest.mark.parametrize("key, value", [("max_speed", float("inf")), ("contact_gap", float("inf")), ("contact_ke", float("inf")),
                                        ("damping", float("inf")), ("contact_kd", -1.0), ("max_speed", 0.0)])  # fmt: skip
def test_a_reference_setting_that_is_infinite_or_out_of_range_is_named(key, value):
    """``reference.max_speed=inf`` once turned the blow-up check off and ``contact_gap=inf`` reached the simulator."""
    from drapebench.reference.settings import SimSettings

    with pytest.raises(ValueError, match=rf"reference {key} must be finite and >=? 0, got {value}; e\.g\. reference\.{key}=\d"):
        SimSettings.for_solver("vbd", **{key: value})
    assert SimSettings.for_solver("vbd", contact_gap=0.0, damping=0.0, contact_kd=0.0).contact_gap == 0.0  # 0 is in range


def test_a_device_other_than_cpu_or_cuda_and_a_missing_gpu_index_name_the_fix(monkeypatch):
    """``device=mps`` (or ``meta``) once passed to torch and failed later with its bare error."""
    for device in ("mps", "meta"):
        with pytest.raises(ValueError, match=rf"device={device} is not supported: the suite runs on device=cpu or device=cuda"):
            load_body("anny_lowres", device=device)
    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)
    monkeypatch.setattr(torch.cuda, "device_count", lambda: 1)
    with pytest.raises(ValueError, match=r"device=cuda:1 requested but this machine has 1 CUDA GPU\(s\), numbered from 0"):
        load_body("anny_lowres", device="cuda:1")


@pytest.mark.parametrize(
    "motion, message",
    [
        ({"n_frames": 1, "transition": 0}, "fewer than 2 frames"),
        ({"n_frames": 0, "transition": 0}, "fewer than 2 frames"),
        ({"fps": 0.0}, "fps must be positive"),
        ({"path": "x.npz"}, "motion.path is read only by motion=file"),
        ({"name": "file", "path": None}, "motion=file needs the file: motion.path="),
        ({"betas": [0.0] * 11}, "11 betas given"),
    ],
)
def test_bad_motion_settings_fail(motion, message, body_lowres):
    m = {"name": "walk", "n_frames": 10, "fps": 30.0, "transition": 2, "seed": 0, "betas": None, "params": {}, **motion}
    with pytest.raises(ValueError, match=message):
        sequence_from_config(m, body_lowres)


def test_a_body_shape_beyond_five_standard_deviations_is_refused_before_anything_is_built(body_lowres, monkeypatch, kick, tmp_path):
    import drapebench.garments.factory as factory
    from drapebench.body.model import MAX_ABS_BETA, BodyShapeOutOfRange

    def no_build(*args, **kwargs):
        raise AssertionError("the garment was built on an absurd body shape")

    monkeypatch.setattr(factory, "_build", no_build)
    monkeypatch.setattr(factory, "signed_distance_grid", no_build)
    with pytest.raises(BodyShapeOutOfRange, match=r"^betas: body shape b1=-400 is outside \+-5 standard deviations.*Give betas within"):
        make_garment("skirt", body_lowres, betas=[0.0, -400.0])
    with pytest.raises(BodyShapeOutOfRange, match="^garment.betas: body shape b0=6"):
        garment_from_config({"kind": "tshirt", "betas": "motion", "params": {}}, body_lowres, [6.0])
    with pytest.raises(BodyShapeOutOfRange, match=r"^garment.betas: body shape b1=-7 is outside .* Give garment.betas within"):
        run(_compose(["body=anny_lowres", "viz=none", "motion.n_frames=2", "garment.betas=[0,-7]"]), tmp_path / "run")
    m = {"name": "walk", "n_frames": 4, "fps": 30.0, "transition": 0, "seed": 0, "betas": [0.0, 0.0, 1e3], "params": {}}
    with pytest.raises(BodyShapeOutOfRange, match="^motion.betas: body shape b2=1000"):
        sequence_from_config(m, body_lowres)
    with pytest.raises(BodyShapeOutOfRange, match=r"b3=-5.5"):
        body_lowres.forward(torch.tensor([[0.0, 0.0, 0.0, -5.5]]), kick.poses[:1])
    assert body_lowres.full_betas([MAX_ABS_BETA, -MAX_ABS_BETA]).abs().max() == MAX_ABS_BETA  # the bound itself is a body


def test_at_the_shape_bound_the_body_is_still_a_human_body(body_lowres):
    """+-5 standard deviations (MAX_ABS_BETA) of the first component: 1.2-2.2 m tall, hardly a face folded over."""
    from drapebench.body.model import MAX_ABS_BETA

    F = body_lowres.faces

    def normals(v):
        return torch.cross(v[F[:, 1]] - v[F[:, 0]], v[F[:, 2]] - v[F[:, 0]], dim=-1)

    rest = normals(body_lowres.v_template)
    for b0 in (-MAX_ABS_BETA, MAX_ABS_BETA):
        v = body_lowres.shaped(torch.tensor([[b0]]))[0][0]
        height = float(v[:, 2].max() - v[:, 2].min())
        folded = float(((normals(v) * rest).sum(-1) <= 0).float().mean())
        assert 1.2 < height < 2.2 and folded < 0.01, (b0, height, folded)


@pytest.mark.parametrize("key", ["motion.seed", "garment.seed", "train.seed", "data.seed"])
def test_a_negative_seed_is_named(key, body_lowres):
    from drapebench.data.reference_set import ReferenceSetSpec
    from drapebench.train import train_config

    with pytest.raises(ValueError, match=rf"{key} must be >= 0 \(it seeds numpy's generator\), got -1"):
        if key == "motion.seed":
            sequence_from_config({"name": "walk", "n_frames": 4, "fps": 30.0, "transition": 0, "seed": -1, "params": {}}, body_lowres)
        elif key == "garment.seed":
            make_garment("skirt", body_lowres, seed=-1)
        elif key == "train.seed":
            train_config({"seed": -1})
        else:
            ReferenceSetSpec(seed=-1)


def test_a_negative_run_seed_is_named_before_any_work(tmp_path):
    """``seed=-1`` with lbs (which trains nothing, so train.seed's check never ran) was once accepted and recorded."""
    with pytest.raises(ValueError, match=r"seed must be >= 0 \(it seeds torch and, through train.seed, numpy's generator\), got -1; e\.g\. seed=0"):
        run(_compose(["method=lbs", "seed=-1", "viz=none", "reference=none", "tracker=none"]), tmp_path / "run")
    assert not (tmp_path / "run" / "metrics.json").exists()


@pytest.mark.parametrize("fps", [float("inf"), float("nan"), -30.0])
def test_a_non_finite_or_negative_fps_is_named_as_the_frame_rate(fps, body_lowres):
    m = {"name": "walk", "n_frames": 4, "fps": fps, "transition": 2, "seed": 0, "betas": None, "params": {}}
    with pytest.raises(ValueError, match=r"fps must be positive and finite, got .*e.g. motion.fps=30"):
        sequence_from_config(m, body_lowres)
    with pytest.raises(ValueError, match="fps must be a finite number of frames per second > 0"):
        BodySequence("s", "walk", torch.zeros(10), torch.zeros(2, 22, 3), torch.zeros(2, 3), fps=fps)


def test_a_tiny_fps_that_sends_the_root_kilometres_away_is_refused_before_the_drape(tmp_path, monkeypatch):
    import methods.lbs.method as lbs
    from drapebench.metrics import FarFromOrigin

    monkeypatch.setattr(lbs.LBSMethod, "drape_chunks", lambda *a: pytest.fail("draped a scene float32 cannot measure"))
    cfg = _compose(["body=anny_lowres", "viz=none", "motion.fps=0.001", "motion.n_frames=4", "motion.transition=0"])
    with pytest.raises(FarFromOrigin, match=r"the motion's root lies up to \d+ m from the origin, .*dtype=float64"):
        run(cfg, tmp_path / "out")


@pytest.mark.parametrize("key", ["thickness", "bulk_density", "young", "bending_multiplier", "dt"])
@pytest.mark.parametrize("value", [0.0, -1.0])
def test_non_positive_material_values_are_named(key, value):
    with pytest.raises(ValueError, match=f"Material.{key} must be positive"):
        Material(**{key: value})


# ---------------------------------------------------------------- two identical runs share the cache (issue point 9)
def _build_entry(path, barrier, out):
    cache = Cache("race", 1)
    barrier.wait()
    value = cache.get_or_build(path, lambda: np.arange(200_000.0), lambda v, p: np.save(open(p, "wb"), v), lambda p: np.load(p))
    out.put(float(value.sum()))


def test_two_processes_building_one_cache_entry_at_once_both_get_it_and_leave_one_sealed_file(tmp_path, monkeypatch):
    monkeypatch.setenv("DRAPEBENCH_DATA", str(tmp_path))
    path = Cache("race", 1).path("entry", suffix=".npy")
    ctx = multiprocessing.get_context("fork")
    barrier, out = ctx.Barrier(2), ctx.Queue()
    procs = [ctx.Process(target=_build_entry, args=(path, barrier, out)) for _ in range(2)]
    for p in procs:
        p.start()
    for p in procs:
        p.join(60)
    assert [p.exitcode for p in procs] == [0, 0]
    expected = float(np.arange(200_000.0).sum())
    assert [out.get(timeout=5), out.get(timeout=5)] == [expected, expected]
    assert sorted(f.name for f in path.parent.iterdir()) == [path.name, path.name + ".sha256"]  # no temporary file left
    assert Cache("race", 1).load(path, np.load).sum() == expected  # sealed and intact


@pytest.mark.parametrize("method", ["gaps", "gensim", "vae"])
def test_a_cuda_run_without_cuda_is_refused_before_the_scene_naming_the_key(method, monkeypatch, tmp_path):
    from drapebench.experiment import run
    from tests.test_experiment import _compose

    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)
    with pytest.raises(ValueError, match=r"device=cuda requested but .*use device=cpu, or install a CUDA build of torch"):
        run(_compose([f"method={method}", "device=cuda", "viz=none"]), tmp_path)


def test_a_setting_json_cannot_hold_is_refused_before_the_scene_naming_the_key(monkeypatch, tmp_path):
    """A method's settings_key() is written to settings.json after the drape and scoring: a value JSON cannot hold
    (a tensor, a set) used to lose the finished run there with "not JSON serialisable: Tensor"."""
    from drapebench import experiment
    from methods.lbs.method import LBSMethod
    from tests.test_experiment import _compose

    monkeypatch.setattr(LBSMethod, "settings_key", lambda self: {"train": {"w": torch.zeros(2)}})
    monkeypatch.setattr(experiment.Scene, "from_config", lambda *a, **k: pytest.fail("the scene was built"))
    with pytest.raises(ValueError, match=r"lbs's settings_key\(\) holds train.w = tensor.*which JSON cannot hold"):
        run(_compose(["method=lbs", "viz=none"]), tmp_path)
    monkeypatch.setattr(LBSMethod, "settings_key", lambda self: {"grid": [1.0, {2.0}]})
    with pytest.raises(ValueError, match=r"holds grid\[1\] = \{2.0\}"):
        run(_compose(["method=lbs", "viz=none"]), tmp_path / "nan")
