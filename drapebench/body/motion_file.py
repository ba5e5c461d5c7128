"""A user's body motion from a file: poses in the body's joint order, checked, as a :class:`BodySequence`.

File (``.npz``, ``.pkl`` (a dict), or ``.h5``/``.hdf5`` with datasets of the same names): ``poses`` (T, J, 3) or (T, 3J)
axis-angle in radians per joint, in the body's joint order (``body.joint_names``; docs/design.md), each
rotation about the joint in world-aligned axes of the rest pose (Z up, facing -Y), chained parent ->
child; optional ``trans`` (T, 3) root translation in metres (default zero), ``betas`` (S,) shape,
``fps`` (a scalar, a dataset or an h5 attribute).
"""

from __future__ import annotations

import logging
import math
import pickle
import zipfile
import zlib
from pathlib import Path

import h5py
import numpy as np
import torch

from drapebench.body.defaults import DEFAULT_TRANSITION
from drapebench.body.model import read_pickle
from drapebench.body.motions import smoothstep
from drapebench.body.sequence import BodySequence

MAX_ROOT_SPEED = 15.0  # m/s; a faster root is taken for a translation in centimetres or millimetres
MAX_ROOT_HEIGHT = 5.0  # body heights: a root whose median height (trans z) is beyond it is taken for another unit
MAX_TRAVEL = 10.0  # a root travelling farther than this many times the most any joint moves relative to it, plus
#                    one body height, is taken for another unit (walking or running, the root travels about as far)
UNITS = (("centimetres", 100.0), ("millimetres", 1000.0))  # the units checked for, smallest first
SCALE_SAMPLES = 4096  # frames (evenly spaced) posed to measure how far the joints move
FIXES = {
    "poses": "give (T, J, 3) or (T, 3J) axis-angle rotations in radians, as float numbers",
    "trans": "give (T, 3) root translations in metres, as float numbers, or leave trans out (no translation)",
    "betas": "give (S,) body shape coefficients as float numbers, or leave betas out (the mean body)",
    "fps": "give the frame rate as one number, e.g. fps=30 in the file or motion.fps=30",
}
log = logging.getLogger("drapebench")


def numeric_array(value, key: str, source: str) -> np.ndarray:
    """``value`` (the file's array ``key``) as float64, or a ValueError naming the file, the key and the fix when
    it is empty or holds no numbers: text, booleans (True would be read as 1), complex or structured values."""
    a = np.asarray(value)
    fix = FIXES[key]
    if a.dtype.kind == "b":
        raise ValueError(f"{source}: {key} holds booleans ({a.dtype}), not numbers; {fix}")
    if a.dtype.kind not in "iuf":
        what = {"U": "text", "S": "bytes (text)", "O": "Python objects (an object array)", "c": "complex numbers"}.get(a.dtype.kind, f"{a.dtype} values")
        raise ValueError(f"{source}: {key} holds {what} ({a.dtype}), not numbers; {fix}")
    if a.size == 0:
        raise ValueError(f"{source}: {key} is empty (shape {a.shape}); {fix}")
    return a.astype(np.float64)


def read_motion_file(path: str | Path, needs: str = "poses (T, J, 3) axis-angle [, trans (T, 3), betas (S,), fps]") -> dict:
    """The arrays of a motion file (``.npz``, ``.h5``/``.hdf5`` or ``.pkl``; numpy): ``poses`` and whatever else it
    holds. ``needs`` describes the expected content in the error for a file without ``poses``. Entries of an
    ``.npz`` that only load as Python objects (allow_pickle) are not loaded: they read as ``None`` (an object array,
    which :func:`numeric_array` names)."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"motion file {path} does not exist (motion.path must name an .npz, .h5 or .pkl file)")
    suffix = path.suffix.lower()
    if suffix not in (".npz", ".h5", ".hdf5", ".pkl"):
        raise ValueError(f"{path}: unsupported motion file type {path.suffix!r}; use .npz, .h5 or .pkl")
    try:
        if suffix == ".npz":
            with np.load(path, allow_pickle=False) as z:
                d = {}
                for k in z.files:
                    try:
                        d[k] = z[k]
                    except ValueError:  # an object array (needs pickle): not loaded, reported if it is read
                        d[k] = np.array(None, dtype=object)
        elif suffix == ".pkl":
            d = read_pickle(path)
        else:
            with h5py.File(path, "r") as f:
                d = {k: f[k][()] for k in f if isinstance(f[k], h5py.Dataset)}
                if "fps" in f.attrs and "fps" not in d:
                    d["fps"] = f.attrs["fps"]
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, zlib.error, pickle.UnpicklingError) as err:
        raise ValueError(f"{path} cannot be read as {suffix[1:]} ({type(err).__name__}: {err}); write it with numpy.savez or h5py") from err
    if "poses" not in d:
        raise ValueError(f"{path} has no 'poses' array (found {sorted(d)}); a motion file needs {needs}")
    return d


def check_axis_angle(a: np.ndarray, source: str, key: str = "poses") -> None:
    """Raise ValueError naming the frames when axis-angle rotations ``a`` (T, ...) hold NaN/Inf, or the fix when
    they look like degrees (an angle above 2.5 pi)."""
    if not np.isfinite(a).all():
        frames = np.flatnonzero(~np.isfinite(a.reshape(len(a), -1)).all(1))[:10].tolist()
        raise ValueError(f"{source}: {key} contain NaN or Inf (frames {frames}); clean the file")
    angle = float(np.linalg.norm(a.reshape(-1, 3), axis=-1).max()) if a.size else 0.0
    if angle > 2.5 * np.pi:
        raise ValueError(f"{source}: a joint rotates by {angle:.0f} rad; {key} must be axis-angle in radians (degrees? multiply by pi/180)")


def check_poses(poses: np.ndarray, body, source: str) -> np.ndarray:
    """(T, J, 3) float32 axis-angle poses checked against ``body``: shape, joint count, radians."""
    names = ", ".join(f"{i} {n}" for i, n in enumerate(body.joint_names))
    J = body.n_joints
    poses = numeric_array(poses, "poses", source)
    if poses.ndim == 2 and poses.shape[1] % 3 == 0:
        poses = poses.reshape(len(poses), -1, 3)
    if poses.ndim == 4 and poses.shape[-2:] == (3, 3):
        raise ValueError(f"{source}: poses {poses.shape} are rotation matrices; give axis-angle (T, {J}, 3), e.g. "
                         "drapebench.body.matrix_to_axis_angle(torch.as_tensor(R))")  # fmt: skip
    if poses.ndim == 3 and poses.shape[-1] == 4:
        raise ValueError(f"{source}: poses {poses.shape} look like quaternions; give axis-angle (T, {J}, 3) in radians")
    if poses.ndim != 3 or poses.shape[-1] != 3:
        raise ValueError(f"{source}: poses have shape {poses.shape}; expected (T, {J}, 3) or (T, {3 * J}) axis-angle")
    if poses.shape[1] != J:
        raise ValueError(f"{source}: poses have {poses.shape[1]} joints, body {body.name} has {J}; give them in its "
                         f"joint order: {names}")  # fmt: skip
    check_axis_angle(poses, source)
    return poses.astype(np.float32)


def check_root_units(poses: np.ndarray, trans: np.ndarray, body, source: str) -> None:
    """Raise ValueError naming the likely unit and the fix when the root translation ``trans`` (T, 3) (Z up; body
    poses (T, J, 3) axis-angle) is implausible in metres for ``body``'s scale H (its rest height): a median root
    height |z| above :data:`MAX_ROOT_HEIGHT` H, or a root path longer than :data:`MAX_TRAVEL` times the longest path
    of a joint relative to the root, plus H (a metres-wide sway while the limbs barely move). The unit named is the
    first of :data:`UNITS` in which the motion is plausible. Paths are measured on at most
    :data:`SCALE_SAMPLES` evenly spaced frames."""
    with torch.no_grad():
        rest = body.shaped()[0][0, :, 2]
        height = float(rest.max() - rest.min())
        step = max(1, -(-len(poses) // SCALE_SAMPLES))
        joints = body.forward(None, torch.as_tensor(np.asarray(poses[::step])).to(body.device, body.dtype), skin=False).joints
        rel = (joints - joints[:, :1]).double().cpu()
        limbs = float((rel[1:] - rel[:-1]).norm(dim=-1).sum(0).max()) if len(rel) > 1 else 0.0

    def problem(t: np.ndarray) -> str | None:
        level = float(np.abs(np.median(t[:, 2])))
        if level > MAX_ROOT_HEIGHT * height:
            return f"the root's median height (trans z) is {level:.4g} m"
        travel = float(np.linalg.norm(np.diff(t[::step], axis=0), axis=1).sum())
        if travel > MAX_TRAVEL * limbs + height:
            return f"the root travels {travel:.4g} m while no joint moves more than {limbs:.3g} m relative to it"
        return None

    found = problem(trans)
    if found is None:
        return
    unit = next(((u, f) for u, f in UNITS if problem(trans / f) is None), None)
    fix = (f"trans looks like {unit[0]}: divide it by {unit[1]:g}" if unit else
           "trans must be metres: divide it by 100 (centimetres) or 1000 (millimetres)")  # fmt: skip
    raise ValueError(f"{source}: {found}, implausible for body {body.name} ({height:.2f} m tall); {fix} (trans is the root "
                     "translation in metres)")  # fmt: skip


def load_motion(path: str | Path, body, fps: float | None = None, betas=None, n_frames: int | None = None,
                transition: int = DEFAULT_TRANSITION, name: str | None = None) -> BodySequence:  # fmt: skip
    """A user's motion file (see the module docstring) as a test :class:`BodySequence` on ``body``.

    ``fps`` overrides the file's; ``betas`` the file's (else the mean shape; :meth:`BodyModel.full_betas`);
    ``n_frames`` keeps the first frames (None: all); ``transition`` frames are prepended that blend from the
    rest pose (pose 0, trans 0) into the first frame (quintic smoothstep). The motion is moved horizontally
    (in float64, logged) so that its first frame's root stands above the origin: a horizontal shift changes
    no metric, and far from the origin float32 could not resolve the garment. Raises ValueError naming the
    file, the key and the fix (no poses, an empty array, text or booleans, wrong joint count, degrees,
    centimetres (:func:`check_root_units`, or a root faster than :data:`MAX_ROOT_SPEED`), a root far above or below the rest pose, fewer than 2 frames, no or a non-finite fps).
    """
    path = Path(path)
    d = read_motion_file(path)
    poses = check_poses(d["poses"], body, str(path))
    T = len(poses)
    trans = np.zeros((T, 3)) if "trans" not in d else numeric_array(d["trans"], "trans", str(path))
    if trans.shape != (T, 3):
        raise ValueError(f"{path}: trans has shape {trans.shape}; expected ({T}, 3) metres, one row per pose")
    if not np.isfinite(trans).all():
        raise ValueError(f"{path}: trans contains NaN or Inf; {FIXES['trans']}")
    if fps is None:
        if "fps" not in d:
            raise ValueError(f"{path} has no fps; give it in the file or as motion.fps=30")
        rate = numeric_array(d["fps"], "fps", str(path))
        if rate.size != 1:
            raise ValueError(f"{path}: fps holds {rate.size} values; {FIXES['fps']}")
        fps = float(rate.reshape(-1)[0])
    if isinstance(fps, bool) or not (math.isfinite(float(fps)) and float(fps) > 0):
        raise ValueError(f"fps must be > 0 and finite (frames per second), got {fps} (motion.fps or {path}'s fps); e.g. motion.fps=30")
    fps = float(fps)
    if n_frames is not None:
        if not 2 <= n_frames <= T:
            raise ValueError(f"motion.n_frames={n_frames}: {path} has {T} frames; give 2..{T} or null for all")
        poses, trans = poses[:n_frames], trans[:n_frames]
    check_root_units(poses, trans, body, str(path))
    start = trans[0, :2].copy()
    if start.any():
        trans[:, :2] -= start
        log.info("%s: the root starts at x=%.4g, y=%.4g m; the motion is moved to start above the origin", path, *start)
    betas_source = "motion.betas"
    if betas is None and "betas" in d:
        betas, betas_source = numeric_array(d["betas"], "betas", str(path)).reshape(-1), f"{path}'s betas"
    return motion_sequence(poses, trans, fps, body, betas, transition, name or path.stem, "file", {"source": str(path)}, betas_source)


def motion_sequence(poses: np.ndarray, trans: np.ndarray, fps: float, body, betas, transition: int, name: str, motion: str,
                    params: dict, betas_source: str = "motion.betas") -> BodySequence:  # fmt: skip
    """A test :class:`BodySequence` from poses (T, J, 3) axis-angle in the body's joint order and trans (T, 3) m (kept
    in the body's dtype: a float64 run's root is exact far from the origin) at ``fps`` Hz, with ``transition`` frames prepended that blend from the rest pose (pose 0, trans 0) into the first
    frame (quintic smoothstep); betas padded by :meth:`BodyModel.full_betas` (None: mean shape). ``params["source"]``
    names the file in errors: fewer than 2 frames, a root faster than :data:`MAX_ROOT_SPEED` (centimetres), a first
    frame whose root the transition would have to lift faster than that, betas out of the body's range (named by
    ``betas_source``: the config key or the file's key)."""
    source = params["source"]
    if len(poses) < 2:
        raise ValueError(f"{source} has {len(poses)} frame(s); a motion needs at least 2")
    speed = float(np.linalg.norm(np.diff(trans, axis=0), axis=1).max()) * fps
    if speed > MAX_ROOT_SPEED:
        raise ValueError(f"{source}: the root moves at up to {speed:.0f} m/s; trans must be metres (centimetres? divide by 100)")
    if transition < 0:
        raise ValueError(f"motion.transition must be >= 0 frames, got {transition}")
    rise = abs(trans[0, 2]) * fps * 1.875 / max(transition, 1)  # the quintic blend's peak speed
    if transition and rise > MAX_ROOT_SPEED:
        raise ValueError(f"{source}: the first frame's root is {trans[0, 2]:.4g} m above the rest pose's; the {transition} "
                         f"transition frames would move it at {rise:.0f} m/s. trans z is relative to the rest pose, which "
                         "stands at trans 0: subtract the floor's height (or give trans in metres)")  # fmt: skip
    s = smoothstep(np.arange(transition) / max(transition, 1))[:, None]
    poses = np.concatenate([s[..., None] * poses[:1], poses]).astype(np.float32)
    trans = np.concatenate([s * trans[:1], trans])
    full = body.full_betas(betas, note=True, key=betas_source).float().cpu()
    return BodySequence(
        name=name, motion=motion, betas=full, poses=torch.from_numpy(poses),
        trans=torch.from_numpy(trans).to(body.dtype), fps=fps, split="test", n_transition=transition, params=params,
    )  # fmt: skip
