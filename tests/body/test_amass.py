"""motion=amass: AMASS/SMPL-family files built from shipped motions read back onto the body; conventions; bad files."""

import logging
import pickle

import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation

from drapebench.body import make_sequence
from drapebench.body.amass import C_MODEL, LAYOUT_NAMES, load_amass, to_smpl_layout
from drapebench.body.motion_source import sequence_from_config

AMASS_UPRIGHT = Rotation.from_matrix(C_MODEL).as_rotvec()  # an AMASS root rotation of a person standing upright (+90 deg about X)
TOLERANCE_M = 1e-5  # float32 rounding of the rotations through the conversion and back


@pytest.fixture(scope="module")
def walk120():
    """0.4 s of the shipped walk at AMASS's 120 fps."""
    return make_sequence("walk", 48, 120.0, seed=1000, transition=0)


def _save(path, layout_dict, **extra):
    np.savez(path, **{**layout_dict, **extra})
    return path


@pytest.mark.parametrize("layout", ["SMPL", "SMPL-H", "SMPL-X"])
def test_each_layout_read_back_gives_the_original_vertices_at_the_runs_fps(layout, walk120, body_lowres, tmp_path):
    d = to_smpl_layout(walk120, body_lowres, layout)
    assert d["poses"].shape == (48, LAYOUT_NAMES[layout])
    assert np.allclose(Rotation.from_rotvec(d["poses"][:, :3]).apply([0.0, 1.0, 0.0])[:, 2], 1.0, atol=0.05)  # AMASS: SMPL's up is Z
    path = _save(tmp_path / f"walk_{layout}.npz", d, betas=np.zeros(16), gender=np.array("female"))
    seq = load_amass(path, body_lowres, fps=30.0, root="file", transition=0)
    assert seq.n_frames == 12 and seq.fps == 30.0 and seq.motion == "amass" and seq.params["layout"] == layout
    error = (seq.vertices(body_lowres) - walk120.vertices(body_lowres)[::4]).norm(dim=-1).max()
    assert error < TOLERANCE_M, f"{layout}: {error * 1e3:.3f} mm"


def test_resampling_between_file_frames_follows_the_motion(walk120, body_lowres, tmp_path):
    """120 fps read at 50 fps: every frame falls between two file frames (slerp, linear translation)."""
    path = _save(tmp_path / "walk.npz", to_smpl_layout(walk120, body_lowres))
    seq = load_amass(path, body_lowres, fps=50.0, start=2, n_frames=15, root="file", transition=0)
    walk50 = make_sequence("walk", 17, 50.0, seed=1000, transition=0)
    error = (seq.vertices(body_lowres) - walk50.vertices(body_lowres)[2:]).norm(dim=-1).max()
    assert error < 5e-4, f"{error * 1e3:.3f} mm"  # measured 0.15 mm: the motion's curvature between 1/120 s samples
    assert load_amass(path, body_lowres, fps=None, root="file", transition=0).n_frames == 48  # fps=null: the file's


def test_smpl_pose_zero_is_the_t_pose_z_up_facing_minus_y(body_lowres, tmp_path):
    poses = np.zeros((2, 72))
    poses[:, :3] = AMASS_UPRIGHT
    seq = load_amass(_save(tmp_path / "t.npz", {"poses": poses, "trans": np.zeros((2, 3)), "mocap_framerate": 30.0}), body_lowres,
                     root="file", transition=0)  # fmt: skip
    j = {n: seq.joints(body_lowres)[0, i].numpy() for i, n in enumerate(body_lowres.joint_names)}
    rest = {n: body_lowres.shaped()[1][0, i].numpy() for i, n in enumerate(body_lowres.joint_names)}
    for side, sign in (("left", 1), ("right", -1)):
        shoulder, elbow, wrist = (j[f"{side}_{n}"] for n in ("shoulder", "elbow", "wrist"))
        assert abs(wrist[2] - shoulder[2]) < 1e-4 and abs(elbow[2] - shoulder[2]) < 1e-4  # arms level
        assert sign * (wrist[0] - elbow[0]) > 0.15 and sign * (elbow[0] - shoulder[0]) > 0.15  # pointing out along +-X
        assert rest[f"{side}_wrist"][2] < rest[f"{side}_shoulder"][2] - 0.2  # the body's own rest is not a T-pose
        for n in ("hip", "knee", "ankle", "foot"):  # legs, spine and head as at rest: Z up, toes to -Y
            assert np.allclose(j[f"{side}_{n}"], rest[f"{side}_{n}"], atol=1e-5)
    assert np.allclose(j["head"], rest["head"], atol=1e-5)


def test_an_smpl_knee_flexion_bends_the_shin_backwards(body_lowres, tmp_path):
    """SMPL's +X rotation at the knee (Y up, facing +Z) flexes it: the ankle goes behind the knee, to +Y here."""
    poses = np.zeros((2, 24, 3))
    poses[:, 0] = AMASS_UPRIGHT
    poses[:, 4] = [1.2, 0.0, 0.0]  # left_knee
    seq = load_amass(_save(tmp_path / "k.npz", {"poses": poses, "trans": np.zeros((2, 3)), "mocap_framerate": 30.0}), body_lowres,
                     root="file", transition=0)  # fmt: skip
    joints = seq.joints(body_lowres)[0].numpy()
    knee, ankle = joints[body_lowres.joint_index("left_knee")], joints[body_lowres.joint_index("left_ankle")]
    shin = (ankle - knee) / np.linalg.norm(ankle - knee)
    assert shin[1] > 0.85 and abs(shin[0]) < 0.15  # 1.2 rad = 69 deg of flexion from straight down
    right = joints[body_lowres.joint_index("right_ankle")] - joints[body_lowres.joint_index("right_knee")]
    assert right[2] < -0.4  # the other leg stands


def test_a_y_up_file_reads_with_up_axis_y_and_a_wrong_axis_is_named(walk120, body_lowres, tmp_path, caplog):
    path = _save(tmp_path / "y.npz", to_smpl_layout(walk120, body_lowres, up_axis="y"))
    seq = load_amass(path, body_lowres, up_axis="y", root="file", transition=0)
    assert (seq.vertices(body_lowres) - walk120.vertices(body_lowres)[::4]).norm(dim=-1).max() < TOLERANCE_M
    with caplog.at_level(logging.WARNING, logger="drapebench"):
        load_amass(path, body_lowres, up_axis="z", transition=0)
    assert "points along the file's Y axis on average, not Z: a Y-up file? set motion.up_axis=y" in caplog.text


def test_root_ground_keeps_the_motion_over_the_origin_on_the_floor(walk120, body_lowres, tmp_path):
    d = to_smpl_layout(walk120, body_lowres)
    far = _save(tmp_path / "far.npz", d, trans=d["trans"] + [3.0, -2.0, 0.9])  # an AMASS trajectory away from the origin
    seq = load_amass(far, body_lowres, transition=0)
    assert seq.params["root"] == "ground" and seq.trans[0, :2].abs().max() < 1e-6
    floor = body_lowres.shaped()[0][0, :, 2].min()
    assert abs(float(seq.vertices(body_lowres)[0, :, 2].min() - floor)) < 1e-5
    moved = seq.trans - seq.trans[0]
    assert torch.allclose(moved, walk120.trans[::4] - walk120.trans[0], atol=1e-5)  # the motion itself is kept


def test_what_cannot_map_is_named_one_line_each(walk120, body_lowres, tmp_path, caplog):
    d = to_smpl_layout(walk120, body_lowres, "SMPL-X")
    clean = load_amass(_save(tmp_path / "clean.npz", d), body_lowres, root="file", transition=0)
    d["poses"][:, 66:69] = [0.3, 0.0, 0.0]  # jaw
    d["poses"][:, 75:] = 0.1  # fingers
    path = _save(tmp_path / "x.npz", d, betas=np.full(16, 0.5), gender=np.array("male"))
    with caplog.at_level(logging.WARNING, logger="drapebench"):
        seq = load_amass(path, body_lowres, root="file", transition=0)
    lines = [r.getMessage() for r in caplog.records]
    assert len(lines) == 3, lines
    assert "SMPL-X rotations of its 3 face joint(s) (jaw, left_eye_smplhf, right_eye_smplhf) are dropped" in lines[0]
    assert "SMPL-X rotations of its 30 hand joint(s) (left_index1 ... right_thumb3) are dropped" in lines[1]
    assert "its 16 betas (gender male) are the shape of the SMPL-family model" in lines[2] and "its mean shape" in lines[2]
    assert torch.equal(seq.poses, clean.poses)  # nothing of them reaches the body
    assert not seq.betas.any()


def test_a_plain_smpl_pickle_without_a_frame_rate_needs_source_fps(walk120, body_lowres, tmp_path):
    d = to_smpl_layout(walk120, body_lowres)
    with open(tmp_path / "smpl.pkl", "wb") as f:
        pickle.dump({"poses": d["poses"], "trans": d["trans"]}, f)
    with pytest.raises(ValueError, match=r"smpl.pkl has no frame rate \(none of mocap_framerate, mocap_frame_rate, fps\); set it: motion.source_fps=120"):
        load_amass(tmp_path / "smpl.pkl", body_lowres)
    seq = load_amass(tmp_path / "smpl.pkl", body_lowres, source_fps=120.0, root="file", transition=0)
    assert seq.params["source_fps"] == 120.0
    assert (seq.vertices(body_lowres) - walk120.vertices(body_lowres)[::4]).norm(dim=-1).max() < TOLERANCE_M


def _bad(d, kind):
    T = len(d["poses"])
    nan_frame = np.ones(T)
    nan_frame[5] = np.nan
    return {
        "wrong layout": {**d, "poses": d["poses"][:, :69]},
        "body order": {**d, "poses": d["poses"][:, :66].reshape(T, 22, 3)},
        "no poses": {k: v for k, v in d.items() if k != "poses"},
        "no trans": {k: v for k, v in d.items() if k != "trans"},
        "NaN poses": {**d, "poses": d["poses"] * nan_frame[:, None]},
        "NaN trans": {**d, "trans": d["trans"] * nan_frame[:, None]},
        "zero frame rate": {**d, "mocap_framerate": np.array(0.0)},
        "NaN frame rate": {**{k: v for k, v in d.items() if k != "mocap_framerate"}, "mocap_frame_rate": np.array(np.nan)},
        "degrees": {**d, "poses": np.degrees(d["poses"])},
        "centimetres": {**d, "trans": d["trans"] * 100 + np.arange(T)[:, None]},
        "text betas": {**d, "betas": np.array(["tall", "slim"])},
        "one frame": {**d, "poses": d["poses"][:1], "trans": d["trans"][:1]},
        "short trans": {**d, "trans": d["trans"][:-1]},
    }[kind]


@pytest.mark.parametrize(
    "kind, message",
    [
        ("wrong layout", r"m.npz: poses have shape \(48, 69\); expected \(T, 72\) SMPL, \(T, 156\) SMPL-H or \(T, 165\) SMPL-X"),
        ("body order", r"poses have shape \(48, 66\); .*poses in the body's own joint order are read by motion=file"),
        ("no poses", r"m.npz has no 'poses' array \(found \['mocap_framerate', 'trans'\]\); a motion file needs poses \(T, 72\|156\|165\)"),
        ("no trans", r"m.npz has no 'trans' array .*add it \(zeros for a motion in place\)"),
        ("NaN poses", r"m.npz: poses contain NaN or Inf \(frames \[5\]\); clean the file"),
        ("NaN trans", r"m.npz: trans contains NaN or Inf \(frames \[5\]\)"),
        ("zero frame rate", r"m.npz: mocap_framerate = 0.0; a frame rate must be a number > 0 .*motion.source_fps=120"),
        ("NaN frame rate", r"m.npz: mocap_frame_rate = nan; a frame rate must be a number > 0"),
        ("degrees", r"poses must be axis-angle in radians \(degrees\? multiply by pi/180\)"),
        ("centimetres", r"m.npz: the root's median height \(trans z\) is .* m, implausible for body anny_lowres .*; trans looks like centimetres: divide it by 100"),
        ("text betas", r"m.npz: betas holds text \(<U4\), not numbers"),
        ("one frame", r"m.npz has 1 frame\(s\); a motion needs at least 2"),
        ("short trans", r"trans has shape \(47, 3\); expected \(48, 3\) metres"),
    ],
)
def test_a_bad_amass_file_fails_naming_the_file_the_key_and_the_fix(kind, message, walk120, body_lowres, tmp_path):
    np.savez(tmp_path / "m.npz", **_bad(to_smpl_layout(walk120, body_lowres), kind))
    with pytest.raises(ValueError, match=message):
        load_amass(tmp_path / "m.npz", body_lowres)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"start": 11}, r"motion.start=11: .* has 12 frames at 30 fps; give 0..10"),
        ({"start": 2, "n_frames": 11}, r"motion.n_frames=11: .* has 10 frames at 30 fps from motion.start=2; give 2..10 or null"),
        ({"fps": 0.0}, r"motion.fps must be a finite number > 0"),
        ({"fps": 2.0}, r"m.npz lasts 0.392 s: fewer than 2 frames at 2 fps; a motion needs at least 2"),
        ({"up_axis": "x"}, r"motion.up_axis must be 'z' \(AMASS\) or 'y'"),
        ({"root": "centre"}, r"motion.root must be 'ground' or 'file'"),
    ],
)
def test_bad_frame_ranges_and_options_are_named(kwargs, message, walk120, body_lowres, tmp_path):
    path = _save(tmp_path / "m.npz", to_smpl_layout(walk120, body_lowres))
    with pytest.raises(ValueError, match=message):
        load_amass(path, body_lowres, **kwargs)


def test_amass_keys_are_read_only_by_motion_amass(walk120, body_lowres, tmp_path):
    m = {"name": "walk", "n_frames": 10, "fps": 30.0, "transition": 2, "seed": 0, "betas": None, "params": {}}
    with pytest.raises(ValueError, match="motion.start is read only by motion=amass"):
        sequence_from_config({**m, "start": 0}, body_lowres)
    with pytest.raises(ValueError, match="motion.root is read only by motion=amass"):
        sequence_from_config({**m, "name": "file", "path": "x.npz", "root": "file"}, body_lowres)
    amass = {**m, "name": "amass", "n_frames": None, "start": 0, "up_axis": "z", "root": "file", "path": "???"}
    with pytest.raises(ValueError, match="motion=amass needs the file: motion.path=/path/to/CMU"):
        sequence_from_config(amass, body_lowres)
    path = _save(tmp_path / "m.npz", to_smpl_layout(walk120, body_lowres))
    seq = sequence_from_config({**amass, "path": str(path)}, body_lowres)
    assert seq.n_frames == 2 + 12 and seq.n_transition == 2 and seq.name == "m"


def test_motion_betas_out_of_range_are_named_as_the_config_key_not_the_file(tmp_path, body_lowres):
    path = tmp_path / "m.npz"
    np.savez(path, **to_smpl_layout(make_sequence("walk", 8, seed=0), body_lowres))
    with pytest.raises(ValueError, match=r"^motion\.betas: .*outside"):
        load_amass(path, body_lowres, betas=[0.0, 300.0])
    with pytest.raises(ValueError, match="finite number > 0"):
        load_amass(path, body_lowres, fps=float("inf"))


def test_a_slow_centimetre_motion_is_refused_naming_the_unit_before_root_ground_moves_it(body_lowres, tmp_path):
    """A person standing (pose 0) with the root 90 cm up and swaying +-2 cm over 4 s, written in centimetres: no root
    is fast (3 cm/s, read as 3 m/s), but a root 90 m above the floor, or a +-2 m sway of a body whose limbs do not
    move, is no human motion in metres. root=ground would have moved the 90 m down to the floor."""
    T, fps = 120, 30.0
    t = np.arange(T) / fps
    trans_m = np.stack([0.02 * np.sin(np.pi * t / 2), 0.01 * np.cos(np.pi * t / 2), np.full(T, 0.9)], 1)
    pose = np.zeros((T, 72))
    pose[:, :3] = AMASS_UPRIGHT
    for scale, unit in ((100.0, "centimetres: divide it by 100"), (1000.0, "millimetres: divide it by 1000")):
        path = _save(tmp_path / f"sway{scale:g}.npz", {"poses": pose, "trans": trans_m * scale, "mocap_framerate": np.array(fps)})
        for root in ("ground", "file"):
            with pytest.raises(ValueError, match=rf"sway{scale:g}.npz: the root's median height .* implausible for body .*; trans looks like {unit}"):
                load_amass(path, body_lowres, root=root, transition=0)
    seq = load_amass(_save(tmp_path / "metres.npz", {"poses": pose, "trans": trans_m, "mocap_framerate": np.array(fps)}), body_lowres, transition=0)
    assert seq.n_frames == T  # the same motion in metres is a motion
