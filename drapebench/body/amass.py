"""AMASS and other SMPL-family motion files as test sequences of the run's body (``motion=amass``).

A file (``.npz`` as AMASS distributes it, or a ``.pkl``/``.npz`` SMPL pose file) holds ``poses`` (T, 72) SMPL,
(T, 156) SMPL-H or (T, 165) SMPL-X axis-angle (radians; or (T, 24|52|55, 3)), ``trans`` (T, 3) metres and a
frame rate (``mocap_framerate``, ``mocap_frame_rate`` or ``fps``; else ``motion.source_fps``); ``betas`` and
``gender`` may be there but belong to the SMPL-family model, not to the run's body, and are not used.

The conversion (README "Your own motion"):

* **Joints by name**: the body's joints are found by name among the layout's (the shipped bodies' 22 are
  SMPL's first 22: pelvis ... right_wrist). Layout joints the body lacks (SMPL's hands, SMPL-H/X fingers,
  SMPL-X jaw and eyes) are dropped, one warning line per group that moves.
* **World axes**: ``up_axis="z"`` (AMASS as distributed): the file's world is Z up, the body's root rotation
  already carries SMPL's Y-up model frame into it; ``"y"``: SMPL's own Y-up frame (a person facing +Z), turned
  +90 degrees about X into the suite's Z up, facing -Y. Rotations are re-expressed with the fixed model-frame
  change ``C_MODEL`` (SMPL's Y up -> Z up).
* **Rest pose**: SMPL's pose 0 is a T-pose, the body's is its own rest pose (an A-pose for the shipped bodies).
  :func:`tpose_rotations` gives, per joint, the world rotation ``C_j`` that carries the body's rest pose into
  its T-pose (the upper arms and forearms levelled along +-X by the smallest rotation, everything else as at
  rest); a joint's world rotation on the body is ``R_A(j) = R_T(j) C_j`` and its local rotation follows from
  its parent's along the chain, so every bone points where the file's T-pose bone points.
* **Root**: orientation kept. ``root="ground"``: the translation is kept up to one offset that puts the first
  frame's root over its rest position and its lowest body point on the rest body's floor; ``"file"``: ``trans`` is
  the body's root translation as it is (a file written for this body, e.g. by :func:`to_smpl_layout`).
* **Time**: resampled to ``fps`` (rotations by slerp, translation linearly); ``start`` and ``n_frames`` count
  frames at ``fps``.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import torch
from scipy.spatial.transform import Rotation

from drapebench.body.defaults import DEFAULT_TRANSITION
from drapebench.body.motion_file import check_axis_angle, check_root_units, motion_sequence, numeric_array, read_motion_file
from drapebench.body.sequence import BodySequence

log = logging.getLogger("drapebench")

SMPL_BODY_JOINTS = ("pelvis", "left_hip", "right_hip", "spine1", "left_knee", "right_knee", "spine2", "left_ankle", "right_ankle",
                    "spine3", "left_foot", "right_foot", "neck", "left_collar", "right_collar", "head", "left_shoulder",
                    "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist")  # fmt: skip
SMPL_BODY_PARENTS = (-1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19)
_FINGERS = ("index", "middle", "pinky", "ring", "thumb")
HAND_JOINTS = tuple(f"{side}_{finger}{k}" for side in ("left", "right") for finger in _FINGERS for k in (1, 2, 3))
FACE_JOINTS = ("jaw", "left_eye_smplhf", "right_eye_smplhf")


def _hand_parents(first: int) -> tuple:
    """Parents of the 2 x 15 finger joints starting at index ``first`` (each finger a chain of 3 from its wrist)."""
    return tuple(wrist if k == 0 else first + 15 * side + 3 * f + k - 1 for side, wrist in ((0, 20), (1, 21)) for f in range(5) for k in range(3))


# number of pose values -> (layout name, joint names, parents), per the models' public definitions
LAYOUTS = {
    72: ("SMPL", (*SMPL_BODY_JOINTS, "left_hand", "right_hand"), (*SMPL_BODY_PARENTS, 20, 21)),
    156: ("SMPL-H", (*SMPL_BODY_JOINTS, *HAND_JOINTS), (*SMPL_BODY_PARENTS, *_hand_parents(22))),
    165: ("SMPL-X", (*SMPL_BODY_JOINTS, *FACE_JOINTS, *HAND_JOINTS), (*SMPL_BODY_PARENTS, 15, 15, 15, *_hand_parents(25))),
}
LAYOUT_NAMES = {name: size for size, (name, _, _) in LAYOUTS.items()}
FPS_KEYS = ("mocap_framerate", "mocap_frame_rate", "fps")
C_MODEL = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])  # SMPL's Y-up model frame -> Z up, facing -Y
WORLD = {"z": np.eye(3), "y": C_MODEL}  # the file's world axes -> the suite's
# bone levelled in the T-pose: joint -> (its child, the bone's T-pose direction)
T_POSE_BONES = {"left_shoulder": ("left_elbow", (1.0, 0.0, 0.0)), "left_elbow": ("left_wrist", (1.0, 0.0, 0.0)),
                "right_shoulder": ("right_elbow", (-1.0, 0.0, 0.0)), "right_elbow": ("right_wrist", (-1.0, 0.0, 0.0))}  # fmt: skip
NEEDS = "poses (T, 72|156|165) SMPL/SMPL-H/SMPL-X axis-angle, trans (T, 3) metres, mocap_framerate"


def _smallest_rotation(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(3, 3) rotation turning unit vector ``a`` onto unit vector ``b`` about their common normal."""
    axis = np.cross(a, b)
    s = np.linalg.norm(axis)
    if s < 1e-12:
        return np.eye(3)
    return Rotation.from_rotvec(axis / s * np.arctan2(s, float(a @ b))).as_matrix()


def tpose_rotations(body) -> np.ndarray:
    """(J, 3, 3) float64: per joint, the world rotation ``C_j`` that carries the body's rest pose (mean shape) into
    its T-pose: the bones of :data:`T_POSE_BONES` (upper arms, forearms) turned level along +-X by the smallest
    rotation (the elbow straightened about its hinge), every other joint carried rigidly by its parent."""
    missing = sorted({j for k, (c, _) in T_POSE_BONES.items() for j in (k, c)} - set(body.joint_names))
    if missing:
        raise ValueError(f"body {body.name} has no joint(s) {missing}: motion=amass maps joints by SMPL name; give the body "
                         f"file joint_names (SMPL's: {', '.join(SMPL_BODY_JOINTS)}), or use motion=file with poses in its own order")  # fmt: skip
    joints = body.shaped()[1][0].detach().double().cpu().numpy()
    C = np.tile(np.eye(3), (body.n_joints, 1, 1))
    for j, name in enumerate(body.joint_names):
        if body.parents[j] >= 0:
            C[j] = C[body.parents[j]]
        if name in T_POSE_BONES:
            child, target = T_POSE_BONES[name]
            bone = C[j] @ (joints[body.joint_index(child)] - joints[j])
            C[j] = _smallest_rotation(bone / np.linalg.norm(bone), np.asarray(target)) @ C[j]
    return C


def _layout(poses: np.ndarray, source: str) -> tuple[str, tuple, tuple, np.ndarray]:
    """The layout (name, joint names, parents) of file poses and the poses as (T, n, 3) float64."""
    poses = numeric_array(poses, "poses", source)
    if poses.ndim == 3 and poses.shape[-1] == 3:
        poses = poses.reshape(len(poses), -1)
    if poses.ndim != 2 or poses.shape[1] not in LAYOUTS:
        raise ValueError(f"{source}: poses have shape {poses.shape}; expected (T, 72) SMPL, (T, 156) SMPL-H or (T, 165) SMPL-X "
                         "axis-angle (or (T, 24|52|55, 3)); poses in the body's own joint order are read by motion=file")  # fmt: skip
    name, joints, parents = LAYOUTS[poses.shape[1]]
    return name, joints, parents, poses.reshape(len(poses), -1, 3)


def _frame_rate(d: dict, source: str, source_fps: float | None) -> float:
    """The file's frame rate (Hz): ``source_fps`` if given, else the first of :data:`FPS_KEYS` in the file."""
    if source_fps is not None:
        key, value = "motion.source_fps", source_fps
    else:
        key = next((k for k in FPS_KEYS if k in d), None)
        if key is None:
            raise ValueError(f"{source} has no frame rate (none of {', '.join(FPS_KEYS)}); set it: motion.source_fps=120")
        value = numeric_array(d[key], "fps", f"{source}: {key}").reshape(-1)[0]
    if not np.isfinite(value) or value <= 0:
        raise ValueError(f"{source}: {key} = {value}; a frame rate must be a number > 0 (frames per second): fix the file or set "
                         "motion.source_fps=120")  # fmt: skip
    return float(value)


def _slerp_resample(poses: np.ndarray, trans: np.ndarray, source_fps: float, fps: float, start: int,
                    n_frames: int | None, source: str) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Poses (T, n, 3) and trans (T, 3) at ``source_fps`` sampled at the times (start + k) / fps, k < n_frames (None:
    to the end): rotations by slerp between the two nearest frames, translation linearly."""
    T = len(poses)
    last = int(np.floor((T - 1) * fps / source_fps + 1e-9))  # the last frame at fps inside the file
    if last < 1:
        raise ValueError(f"{source} lasts {(T - 1) / source_fps:.3g} s: fewer than 2 frames at {fps:g} fps; a motion needs at least "
                         "2 (a longer file, or a higher motion.fps)")  # fmt: skip
    if start < 0 or start > last - 1:
        raise ValueError(f"motion.start={start}: {source} has {last + 1} frames at {fps:g} fps; give 0..{last - 1}")
    n = last + 1 - start if n_frames is None else n_frames
    if not 2 <= n <= last + 1 - start:
        raise ValueError(f"motion.n_frames={n_frames}: {source} has {last + 1 - start} frames at {fps:g} fps from "
                         f"motion.start={start}; give 2..{last + 1 - start} or null for all")  # fmt: skip
    u = np.minimum((start + np.arange(n)) * source_fps / fps, T - 1)
    i = np.minimum(np.floor(u).astype(int), T - 2)
    a = u - i
    r0 = Rotation.from_rotvec(poses[i].reshape(-1, 3))
    r1 = Rotation.from_rotvec(poses[i + 1].reshape(-1, 3))
    step = (r0.inv() * r1).as_rotvec() * np.repeat(a, poses.shape[1])[:, None]
    out = (r0 * Rotation.from_rotvec(step)).as_rotvec().reshape(n, -1, 3)
    return out, trans[i] + a[:, None] * (trans[i + 1] - trans[i])


def _globals(local: np.ndarray, parents) -> np.ndarray:
    """World rotations (T, J, 3, 3) of local rotations (T, J, 3, 3) chained along ``parents``."""
    out = local.copy()
    for j, p in enumerate(parents):
        if p >= 0:
            out[:, j] = out[:, p] @ local[:, j]
    return out


def _locals(world: np.ndarray, parents) -> np.ndarray:
    """Local rotations (T, J, 3, 3) of world rotations (T, J, 3, 3) along ``parents`` (the inverse of :func:`_globals`)."""
    out = world.copy()
    for j, p in enumerate(parents):
        if p >= 0:
            out[:, j] = world[:, p].transpose(0, 2, 1) @ world[:, j]
    return out


def _matrices(rotvec: np.ndarray) -> np.ndarray:
    return Rotation.from_rotvec(rotvec.reshape(-1, 3)).as_matrix().reshape(*rotvec.shape[:-1], 3, 3)


def _rotvecs(matrices: np.ndarray) -> np.ndarray:
    return Rotation.from_matrix(matrices.reshape(-1, 3, 3)).as_rotvec().reshape(*matrices.shape[:-2], 3)


def _joint_map(body, joints: tuple, layout: str, source: str) -> list[int]:
    """Index in the layout's ``joints`` of each body joint, by name."""
    missing = [n for n in body.joint_names if n not in joints]
    if missing:
        raise ValueError(f"{source}: body {body.name} has joint(s) {missing} that the {layout} layout lacks: motion=amass maps "
                         f"joints by SMPL name ({', '.join(SMPL_BODY_JOINTS)}); give the body file SMPL joint_names, or "
                         "use motion=file with poses in the body's own order")  # fmt: skip
    return [joints.index(n) for n in body.joint_names]


def _warn_dropped(poses: np.ndarray, joints: tuple, body, layout: str, source: str) -> None:
    """One warning line per group of layout joints the body lacks (hands, face) that the file moves."""
    kept = set(body.joint_names)
    groups = {"face": [n for n in FACE_JOINTS if n in joints and n not in kept],
              "hand": [n for n in joints if n not in kept and n not in FACE_JOINTS]}  # fmt: skip
    for group, names in groups.items():
        if names and np.abs(poses[:, [joints.index(n) for n in names]]).max() > 0:
            shown = ", ".join(names) if len(names) <= 3 else f"{names[0]} ... {names[-1]}"
            log.warning("%s: the %s rotations of its %d %s joint(s) (%s) are dropped: body %s has no such joints", source, layout,
                        len(names), group, shown, body.name)  # fmt: skip


def _to_body(poses: np.ndarray, trans: np.ndarray, body, index: list[int], parents: tuple, up_axis: str) -> tuple[np.ndarray, np.ndarray]:
    """File poses (T, n, 3) axis-angle (SMPL's T-pose rest, ``up_axis`` world; layout ``parents``) and trans (T, 3) m as
    the body's poses (T, J, 3) (its rest pose, Z up; body joint j is layout joint ``index[j]``) and trans (T, 3)."""
    W = WORLD[up_axis]
    world_t = W @ _globals(_matrices(poses), parents) @ C_MODEL.T  # world rotations on SMPL's T-pose rest, suite axes
    world_a = world_t[:, index] @ tpose_rotations(body)
    return _rotvecs(_locals(world_a, body.parents)), trans @ W.T


def to_smpl_layout(seq: BodySequence, body, layout: str = "SMPL", up_axis: str = "z") -> dict:
    """The inverse of :func:`load_amass`'s conversion: a sequence on ``body`` as an AMASS-layout dict (``poses`` (T, n) float64
    in ``layout`` (SMPL, SMPL-H, SMPL-X) with the layout's other joints at 0, ``trans`` (T, 3), ``mocap_framerate``),
    which ``motion=amass`` with ``motion.root=file`` reads back into the same sequence."""
    if layout not in LAYOUT_NAMES:
        raise ValueError(f"layout must be one of {sorted(LAYOUT_NAMES)}, not {layout!r}")
    _, joints, parents = LAYOUTS[LAYOUT_NAMES[layout]]
    W = WORLD[up_axis]
    index = _joint_map(body, joints, layout, seq.name)
    world_a = _globals(_matrices(seq.poses.double().numpy()), body.parents)
    world_t = np.tile(np.eye(3), (seq.n_frames, len(joints), 1, 1))
    world_t[:, index] = world_a @ tpose_rotations(body).transpose(0, 2, 1)
    for j, p in enumerate(parents):  # a joint the body lacks keeps its rest rotation: its parent's world rotation
        if j not in index:
            world_t[:, j] = world_t[:, p]
    file_world = W.T @ world_t @ C_MODEL
    poses = _rotvecs(_locals(file_world, parents)).reshape(seq.n_frames, -1)
    return {"poses": poses, "trans": seq.trans.double().numpy() @ W, "mocap_framerate": np.array(float(seq.fps))}


def _check_up_axis(poses: np.ndarray, up_axis: str, source: str) -> None:
    """Warn when the body's up direction (SMPL's model Y carried by the root rotation) points along another world
    axis than ``up_axis`` on average: a file in the other convention."""
    up = Rotation.from_rotvec(poses[:, 0]).apply([0.0, 1.0, 0.0]).mean(0)
    axis = "xyz"[int(np.argmax(np.abs(up)))]
    if axis != up_axis:
        log.warning("%s: the body's up direction points along the file's %s axis on average, not %s: a %s-up file? set "
                    "motion.up_axis=%s", source, axis.upper(), up_axis.upper(), axis.upper(), axis)  # fmt: skip


def _ground(poses: np.ndarray, trans: np.ndarray, body, betas) -> np.ndarray:
    """``trans`` (T, 3) shifted so that frame 0's root is over its rest position (horizontally) and its lowest body
    point at the rest body's lowest point (the floor)."""
    full = body.full_betas(betas)[None]
    with torch.no_grad():
        rest = body.shaped(full)[0][0, :, 2].min()
        first = body.forward(full, torch.as_tensor(poses[:1]).to(body.device, body.dtype),
                             torch.as_tensor(trans[:1]).to(body.device, body.dtype)).vertices[0, :, 2].min()  # fmt: skip
    return trans - np.array([trans[0, 0], trans[0, 1], float(first - rest)], dtype=np.float32)


def load_amass(path: str | Path, body, fps: float | None = 30.0, start: int = 0, n_frames: int | None = None,
               source_fps: float | None = None, up_axis: str = "z", root: str = "ground", betas=None,
               transition: int = DEFAULT_TRANSITION, name: str | None = None) -> BodySequence:  # fmt: skip
    """An AMASS/SMPL-family motion file (module docstring) as a test :class:`BodySequence` on ``body``.

    ``fps`` the sequence's frame rate (Hz; None: the file's), ``start``/``n_frames`` the frames kept (counted at
    ``fps``; None: to the end), ``source_fps`` the file's frame rate when it has none (or to override it),
    ``up_axis`` the file's world up ("z": AMASS, "y"), ``root`` "ground" or "file", ``betas`` the body's shape (None:
    the mean; the file's SMPL betas are not this body's), ``transition`` frames blending from the rest pose.
    Raises ValueError naming the file, the key and the fix (layout, missing keys, NaN, frame rate, frame range, a
    translation in centimetres: :func:`drapebench.body.motion_file.check_root_units`, before ``root`` moves it).
    """
    path = Path(path)
    source = str(path)
    if up_axis not in WORLD:
        raise ValueError(f"motion.up_axis must be 'z' (AMASS) or 'y' (SMPL's own frame), not {up_axis!r}")
    if root not in ("ground", "file"):
        raise ValueError(f"motion.root must be 'ground' or 'file', not {root!r}")
    d = read_motion_file(path, needs=NEEDS)
    layout, joints, parents, poses = _layout(d["poses"], source)
    check_axis_angle(poses, source)
    if "trans" not in d:
        raise ValueError(f"{source} has no 'trans' array (found {sorted(d)}); an SMPL motion needs trans (T, 3) root "
                         "translation in metres: add it (zeros for a motion in place)")  # fmt: skip
    trans = numeric_array(d["trans"], "trans", source)
    if trans.shape != (len(poses), 3):
        raise ValueError(f"{source}: trans has shape {trans.shape}; expected ({len(poses)}, 3) metres, one row per pose")
    if not np.isfinite(trans).all():
        raise ValueError(f"{source}: trans contains NaN or Inf (frames {np.flatnonzero(~np.isfinite(trans).all(1))[:10].tolist()}); clean the file")
    file_fps = _frame_rate(d, source, source_fps)
    if len(poses) < 2:
        raise ValueError(f"{source} has {len(poses)} frame(s); a motion needs at least 2")
    fps = file_fps if fps is None else float(fps)
    if not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"motion.fps must be a finite number > 0 frames per second (null: the file's), got {fps}")
    body.full_betas(betas, key="motion.betas")  # before the body is posed with them (root=ground)
    index = _joint_map(body, joints, layout, source)
    _check_up_axis(poses, up_axis, source)
    _warn_dropped(poses, joints, body, layout, source)
    file_betas = numeric_array(d["betas"], "betas", source).reshape(-1) if "betas" in d else np.zeros(0)
    if np.any(file_betas != 0):
        gender = np.asarray(d.get("gender", "")).reshape(-1)[0]
        gender = f" (gender {gender.decode() if isinstance(gender, bytes) else gender})" if gender else ""
        log.warning("%s: its %d betas%s are the shape of the SMPL-family model it was fitted with, not body %s's shape space: "
                    "not used; the body has %s", source, len(file_betas), gender, body.name,
                    f"motion.betas={list(betas)}" if betas is not None else "its mean shape (set motion.betas=[...] for another)")  # fmt: skip
    poses, trans = _slerp_resample(poses, trans, file_fps, fps, int(start), n_frames, source)
    poses, trans = _to_body(poses, trans, body, index, parents, up_axis)
    check_root_units(poses, trans, body, source)  # before root=ground would move a root 90 m up to the floor
    if root == "ground":
        trans = _ground(poses, trans, body, betas)
    params = {"source": source, "layout": layout, "source_fps": file_fps, "start": int(start), "up_axis": up_axis, "root": root}
    return motion_sequence(poses, trans, fps, body, betas, transition, name or path.stem, "amass", params)
