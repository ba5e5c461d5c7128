"""BodySequence: a body shape and a pose/translation track, with posed geometry on demand and exact h5 I/O."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import torch

from drapebench.body.defaults import DEFAULT_TRANSITION
from drapebench.body.model import BodyModel, BodyOutput
from drapebench.body.motions import generate
from drapebench.cache import atomic_write
from drapebench.geometry.ops import vertex_normals
from drapebench.keys import is_finite_number

LOCAL_REUSE = 2.0  # m: root translation up to which posed_frames(local=True) reuses the cached world geometry
#                    (world coordinates under 4 m: float32 rounds them as finely as the body's own scale)


def _key(kind: str, body: BodyModel) -> tuple:
    """Cache key of posed geometry: the body object (id, name, size) and its dtype/device."""
    return (kind, id(body), body.name, body.n_vertices, body.dtype, str(body.device))


@dataclass
class BodySequence:
    """One body motion.

    betas (S,) shape coefficients; poses (T, J, 3) axis-angle (radians); trans (T, 3) metres (float32, or
    float64 when given as a float64 tensor: a float64 run's root, exact far from the origin);
    fps frames per second; ``n_transition`` leading frames blend from the rest pose into the motion.
    Posed geometry (:meth:`vertices`, :meth:`vertex_normals`, ...) is computed once per body and
    cached on the object.
    """

    name: str
    motion: str
    betas: torch.Tensor
    poses: torch.Tensor
    trans: torch.Tensor
    fps: float = 30.0
    seed: int = 0
    split: str = "train"
    n_transition: int = 0
    params: dict = field(default_factory=dict)
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    def __post_init__(self) -> None:
        betas = torch.as_tensor(self.betas, dtype=torch.float32)
        if betas.dim() == 2 and betas.shape[0] == 1:
            betas = betas[0]
        if betas.dim() != 1:
            raise ValueError(f"{self.name}: betas must be (S,) shape coefficients, got {tuple(betas.shape)}")
        self.betas = betas
        self.poses = torch.as_tensor(self.poses, dtype=torch.float32)
        wide = isinstance(self.trans, torch.Tensor) and self.trans.dtype == torch.float64  # a float64 run's, kept
        self.trans = torch.as_tensor(self.trans, dtype=torch.float64 if wide else torch.float32)
        if self.poses.dim() != 3 or self.poses.shape[-1] != 3:
            raise ValueError(f"{self.name}: poses must be (T, J, 3), got {tuple(self.poses.shape)}")
        if self.trans.shape != (self.poses.shape[0], 3):
            raise ValueError(f"{self.name}: trans must be ({self.poses.shape[0]}, 3), got {tuple(self.trans.shape)}")
        for key in ("betas", "poses", "trans"):
            if not torch.isfinite(getattr(self, key)).all():
                raise ValueError(f"{self.name}: {key} contains NaN or Inf")
        if not (is_finite_number(self.fps) and self.fps > 0):
            raise ValueError(f"{self.name}: fps must be a finite number of frames per second > 0, got {self.fps!r}; e.g. fps=30")
        if not 0 <= self.n_transition <= self.poses.shape[0]:
            raise ValueError(f"{self.name}: n_transition {self.n_transition} outside [0, {self.poses.shape[0]}]")

    @property
    def n_frames(self) -> int:
        return self.poses.shape[0]

    @property
    def dt(self) -> float:
        return 1.0 / self.fps

    def held_frames(self) -> torch.Tensor:
        """(T,) long: for each frame, the first frame of the run of identical frames (same pose and root
        translation) it belongs to; frame t itself where the body moved. A held pose is posed once."""
        same = ((self.poses[1:] == self.poses[:-1]).flatten(1).all(1) & (self.trans[1:] == self.trans[:-1]).all(1))
        new_run = torch.cat([torch.ones(1, dtype=torch.bool, device=same.device), ~same])
        starts = torch.nonzero(new_run).squeeze(1)
        return starts[torch.cumsum(new_run.long(), 0) - 1]

    def body_output(self, body: BodyModel) -> BodyOutput:
        """Posed body for every frame (cached per body and dtype): vertices (T,V,3), joints, transforms.
        Frames that hold the previous frame's pose are not posed again (:meth:`held_frames`)."""
        key = _key("out", body)
        if key not in self._cache:
            self._check_joints(body)
            held = self.held_frames()
            distinct, inverse = torch.unique(held, return_inverse=True)
            with torch.no_grad():
                out = body.forward(
                    body.full_betas(self.betas)[None],
                    self.poses[distinct].to(body.device, body.dtype),
                    self.trans[distinct].to(body.device, body.dtype),
                )
            if len(distinct) < self.n_frames:
                inverse = inverse.to(out.joints.device)
                out = BodyOutput(*(None if t is None else t[inverse] for t in (out.vertices, out.joints, out.transforms, out.rest_joints)))
            self._cache[key] = out
        return self._cache[key]

    def _check_joints(self, body: BodyModel) -> None:
        if self.poses.shape[1] != body.n_joints:
            raise ValueError(
                f"{self.name}: poses have {self.poses.shape[1]} joints, body {body.name} has {body.n_joints}; "
                "use a body with the 22-joint skeleton of drapebench.body.bake.JOINT_NAMES"
            )

    def vertices(self, body: BodyModel) -> torch.Tensor:
        """Posed body vertices (T, V, 3)."""
        return self.body_output(body).vertices

    def vertex_normals(self, body: BodyModel) -> torch.Tensor:
        """Area-weighted unit normals of the posed body (T, V, 3), cached."""
        key = _key("normals", body)
        if key not in self._cache:
            self._cache[key] = vertex_normals(self.vertices(body), body.faces)
        return self._cache[key]

    def posed_frames(self, body: BodyModel, start: int, stop: int, local: bool = False) -> tuple[torch.Tensor, torch.Tensor]:
        """Posed vertices and unit normals (stop-start, V, 3) of frames [start, stop): slices of the
        cached whole-sequence geometry when this sequence holds it, else posed for those frames only
        and not cached (memory bounded by the chunk on long sequences).

        ``local``: each frame in its own local frame, its root translation ``trans[t]`` left out (world =
        local + trans[t]), so the body keeps float32's resolution at its own scale however far it travels:
        the cached geometry minus trans (in float64) while the root stays within ``LOCAL_REUSE`` m of the
        origin, else posed without the translation."""
        cached = _key("out", body) in self._cache
        if cached and (not local or float(self.trans[start:stop].abs().max()) <= LOCAL_REUSE):
            v, n = self.vertices(body)[start:stop], self.vertex_normals(body)[start:stop]
            if local:
                v = (v.double() - self.trans[start:stop, None].to(v.device, torch.float64)).to(v.dtype)
            return v, n
        part = self.slice(start, stop)
        if local:
            part.trans = torch.zeros_like(part.trans)  # a fresh slice: nothing posed or cached yet
        return part.vertices(body), part.vertex_normals(body)

    def joints(self, body: BodyModel) -> torch.Tensor:
        """Posed joint positions (T, J, 3)."""
        return self.body_output(body).joints

    def transforms(self, body: BodyModel) -> torch.Tensor:
        """Skinning transforms (T, J, 4, 4), translation included (without posing the vertices unless already done)."""
        full = _key("out", body)
        if full in self._cache:
            return self._cache[full].transforms
        key = _key("transforms", body)
        if key not in self._cache:
            self._check_joints(body)
            with torch.no_grad():
                self._cache[key] = body.forward(
                    body.full_betas(self.betas)[None], self.poses.to(body.device, body.dtype),
                    self.trans.to(body.device, body.dtype), skin=False,
                ).transforms  # fmt: skip
        return self._cache[key]

    def frame_transforms(self, body: BodyModel, start: int, stop: int) -> torch.Tensor:
        """Skinning transforms (stop-start, J, 4, 4) of frames [start, stop): slices of the whole sequence's when this
        sequence holds them (:meth:`transforms`, :meth:`body_output`), else computed for those frames only and not
        cached (memory bounded by the chunk on long sequences)."""
        if _key("out", body) in self._cache or _key("transforms", body) in self._cache:
            return self.transforms(body)[start:stop]
        return self.slice(start, stop).transforms(body)

    def slice(self, start: int, stop: int | None = None) -> BodySequence:
        """Frames [start, stop) as a new sequence (the transition count is clipped to what remains)."""
        stop = self.n_frames if stop is None else stop
        return BodySequence(
            name=f"{self.name}[{start}:{stop}]", motion=self.motion, betas=self.betas,
            poses=self.poses[start:stop], trans=self.trans[start:stop], fps=self.fps, seed=self.seed,
            split=self.split, n_transition=max(0, min(self.n_transition - start, stop - start)), params=dict(self.params),
        )  # fmt: skip

    # ------------------------------------------------------------------ h5
    def write_h5(self, group: h5py.Group) -> None:
        """Write into an open h5 group (datasets betas/poses/trans, scalars as attributes)."""
        for key in ("betas", "poses", "trans"):
            group.create_dataset(key, data=getattr(self, key).numpy())
        for key in ("name", "motion", "split"):
            group.attrs[key] = getattr(self, key)
        group.attrs["fps"] = float(self.fps)
        group.attrs["seed"] = int(self.seed)
        group.attrs["n_transition"] = int(self.n_transition)
        group.attrs["params"] = json.dumps(self.params, sort_keys=True)

    @classmethod
    def read_h5(cls, group: h5py.Group) -> BodySequence:
        """Read what :meth:`write_h5` wrote."""
        missing = [k for k in ("betas", "poses", "trans") if k not in group]
        if missing:
            raise ValueError(f"h5 group {group.name} is not a BodySequence: missing {missing}")
        a = group.attrs
        return cls(
            name=str(a["name"]), motion=str(a["motion"]), betas=group["betas"][()], poses=group["poses"][()],
            trans=group["trans"][()], fps=float(a["fps"]), seed=int(a["seed"]), split=str(a["split"]),
            n_transition=int(a["n_transition"]), params=json.loads(a["params"]),
        )  # fmt: skip

    def save(self, path: str | Path) -> None:
        """Write to an h5 file atomically."""
        with atomic_write(path, mode=None) as tmp, h5py.File(tmp, "w") as f:
            self.write_h5(f)

    @classmethod
    def load(cls, path: str | Path) -> BodySequence:
        """Read a file written by :meth:`save`."""
        with h5py.File(path, "r") as f:
            return cls.read_h5(f)


def make_sequence(
    motion: str,
    n_frames: int = 90,
    fps: float = 30.0,
    seed: int = 0,
    betas=None,
    transition: int = DEFAULT_TRANSITION,
    split: str = "train",
    name: str | None = None,
    **params,
) -> BodySequence:
    """A procedural motion (see :mod:`drapebench.body.motions`) as a :class:`BodySequence`.

    Args:
        motion: one of :data:`drapebench.body.motions.MOTIONS`.
        n_frames: frames of the motion proper; the sequence has ``transition + n_frames`` frames.
        fps: frame rate (Hz).
        seed: seeds amplitude, cadence and phase variations (and random motions).
        betas: (S,) body shape; None = mean shape (10 zeros).
        transition: leading frames that blend from the rest pose into the motion.
        **params: motion parameters (see ``motion_defaults(motion)``).
    """
    poses, trans = generate(motion, n_frames, fps, seed, transition, **params)
    betas = torch.zeros(10, device="cpu") if betas is None else torch.as_tensor(betas, dtype=torch.float32, device="cpu")  # a sequence is a CPU record
    return BodySequence(
        name=name or f"{motion}_s{seed}", motion=motion, betas=betas, poses=torch.from_numpy(poses),
        trans=torch.from_numpy(trans), fps=fps, seed=seed, split=split, n_transition=transition, params=dict(params),
    )  # fmt: skip
