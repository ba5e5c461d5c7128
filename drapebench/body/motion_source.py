"""The test sequence a config's ``motion`` node names: a procedural motion, a user's motion file or an AMASS file
(the one place that picks among the three readers)."""

from __future__ import annotations

from drapebench.body.amass import load_amass
from drapebench.body.motion_file import load_motion
from drapebench.body.sequence import BodySequence, make_sequence

AMASS_KEYS = ("start", "source_fps", "up_axis", "root")  # read only by motion=amass (drapebench.body.amass)


def sequence_from_config(m: dict, body) -> BodySequence:
    """The test sequence a config's ``motion`` node (a dict) describes: ``file`` reads ``path``
    (:func:`load_motion`), ``amass`` an SMPL-family file (:func:`drapebench.body.amass.load_amass`), any other
    name generates a procedural motion (:func:`make_sequence`), with betas padded by
    :meth:`BodyModel.full_betas`. Raises ValueError for a key the chosen motion does not read."""
    name = m["name"]
    given = [k for k in AMASS_KEYS if m.get(k) is not None]
    if given and name != "amass":
        raise ValueError(f"motion.{given[0]} is read only by motion=amass (an AMASS/SMPL file), not by motion={name}")
    if name in ("file", "amass"):
        if m.get("params"):
            raise ValueError(f"motion.params {sorted(m['params'])} are parameters of the procedural motions; motion={name} reads path")
        if m.get("path") in (None, "???"):
            example = "poses.npz (or .h5)" if name == "file" else "CMU/01/01_01_poses.npz (AMASS .npz or an SMPL .pkl)"
            raise ValueError(f"motion={name} needs the file: motion.path=/path/to/{example}")
        if name == "file":
            return load_motion(m["path"], body, fps=m.get("fps"), betas=m.get("betas"), n_frames=m.get("n_frames"),
                               transition=int(m["transition"]))  # fmt: skip
        enum = {k: getattr(m.get(k), "name", m.get(k)) for k in ("up_axis", "root")}  # Enum members once validated by the schema
        return load_amass(m["path"], body, fps=m.get("fps"), start=int(m.get("start") or 0), n_frames=m.get("n_frames"),
                          source_fps=m.get("source_fps"), betas=m.get("betas"), transition=int(m["transition"]), **enum)  # fmt: skip
    if m.get("path") is not None:
        raise ValueError(f"motion.path is read only by motion=file and motion=amass (a user's pose file), not by motion={name}")
    if m.get("n_frames") is None or m.get("fps") is None:
        raise ValueError(f"motion={name} needs motion.n_frames and motion.fps (null only for motion=file and motion=amass)")
    if int(m["n_frames"]) + int(m["transition"]) < 2:
        raise ValueError(f"motion.n_frames={m['n_frames']} with transition={m['transition']} gives fewer than 2 frames; "
                         "a motion needs at least 2 (velocities): raise motion.n_frames")  # fmt: skip
    betas = None if m.get("betas") is None else body.full_betas(m["betas"], note=True, key="motion.betas").float().cpu()
    return make_sequence(name, int(m["n_frames"]), float(m["fps"]), int(m["seed"]), betas=betas,
                         transition=int(m["transition"]), split="test", **m.get("params", {}))  # fmt: skip
