"""SMPL-format linear blend skinning body model and its loader.

Conventions (docs/design.md): metres, Z up, the body faces -Y, +X is the body's left side.
``pose`` is per-joint axis-angle (radians) in world-aligned axes about each joint, chained
parent -> child as in SMPL; ``pose = 0`` is the rest pose (the Anny A-pose for baked bodies).
"""

from __future__ import annotations

import logging
import pickle
import zipfile
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from drapebench.body.lbs import axis_angle_to_matrix, lbs

# Bodies shipped in data/bodies (baked from Anny by `python -m drapebench.body.bake`).
BODY_DIR = Path(__file__).resolve().parents[2] / "data" / "bodies"
SHIPPED_BODIES = ("anny", "anny_lowres")
REQUIRED_KEYS = ("v_template", "shapedirs", "J_regressor", "weights", "parents", "faces")
# Body shapes are betas in standard deviations of an adult population. Up to |beta| = 5 the shipped
# bodies are still human (1.25 / 2.16 m tall at b0 = -5 / +5, at most 0.22 % of the faces folded over); beyond
# it the linear shape space extrapolates into no body at all (b0 = -10: 0.80 m tall, 8 % of the faces
# folded). Measured in data/bodies/PROVENANCE.md; BodyModel refuses larger betas (BodyShapeOutOfRange).
MAX_ABS_BETA = 5.0


class BodyShapeOutOfRange(ValueError):
    """Shape coefficients beyond +-MAX_ABS_BETA standard deviations, where the shape space is no human body."""


@dataclass
class BodyOutput:
    """Result of :meth:`BodyModel.forward`.

    vertices (B, V, 3) posed vertices; joints (B, J, 3) posed joint positions;
    transforms (B, J, 4, 4) skinning transforms (translation included) for :func:`lbs`;
    rest_joints (B, J, 3) joint positions of the shaped rest body.
    """

    vertices: torch.Tensor | None
    joints: torch.Tensor
    transforms: torch.Tensor
    rest_joints: torch.Tensor


class BodyModel(torch.nn.Module):
    """SMPL-format LBS body: ``v_template (V,3)``, ``shapedirs (V,3,S)``, ``J_regressor (J,V)``,
    ``weights (V,J)``, ``parents (J,)`` (-1 for the root), ``faces (F,3)``, optional
    ``posedirs (V,3,9*(J-1))`` and ``joint_names``.

    Buffers follow ``.to(dtype/device)``; float32 by default.
    """

    def __init__(
        self,
        v_template,
        shapedirs,
        J_regressor,
        weights,
        parents,
        faces,
        joint_names=None,
        posedirs=None,
        name: str = "body",
        dtype: torch.dtype = torch.float32,
    ) -> None:
        super().__init__()
        arrays = _validate_arrays(
            dict(
                v_template=v_template,
                shapedirs=shapedirs,
                J_regressor=J_regressor,
                weights=weights,
                parents=parents,
                faces=faces,
                posedirs=posedirs,
            ),
            source=name,
        )
        f = lambda a: torch.as_tensor(np.asarray(a), dtype=dtype)  # noqa: E731
        self.name = name
        self.register_buffer("v_template", f(arrays["v_template"]))
        self.register_buffer("shapedirs", f(arrays["shapedirs"]))
        self.register_buffer("J_regressor", f(arrays["J_regressor"]))
        self.register_buffer("weights", f(arrays["weights"]))
        if arrays["posedirs"] is not None:
            self.register_buffer("posedirs", f(arrays["posedirs"]))
        else:
            self.posedirs = None
        self.register_buffer("faces", torch.as_tensor(np.asarray(arrays["faces"]), dtype=torch.long))
        self.parents = [int(p) for p in np.asarray(arrays["parents"]).reshape(-1)]
        n_joints = len(self.parents)
        self.joint_names = list(joint_names) if joint_names is not None else [f"joint{i}" for i in range(n_joints)]
        if len(self.joint_names) != n_joints:
            raise ValueError(f"{name}: {len(self.joint_names)} joint_names for {n_joints} joints")

    # ------------------------------------------------------------------ sizes
    @property
    def n_vertices(self) -> int:
        return self.v_template.shape[0]

    @property
    def n_joints(self) -> int:
        return len(self.parents)

    @property
    def n_betas(self) -> int:
        return self.shapedirs.shape[-1]

    @property
    def dtype(self) -> torch.dtype:
        return self.v_template.dtype

    @property
    def device(self) -> torch.device:
        return self.v_template.device

    @property
    def outer_faces(self) -> torch.Tensor:
        """(F,) bool: the faces on the body's outer surface, not buried inside another part, in the
        mean shape's rest pose (:mod:`drapebench.geometry.outer_surface`; cached by content hash)."""
        if getattr(self, "_outer_faces", None) is None or self._outer_faces.device != self.faces.device:
            from drapebench.geometry.outer_surface import outer_faces

            self._outer_faces = outer_faces(self.v_template, self.faces)
        return self._outer_faces

    def joint_index(self, name: str) -> int:
        """Index of a joint by name; raises with the valid names on a miss."""
        try:
            return self.joint_names.index(name)
        except ValueError:
            raise KeyError(f"unknown joint {name!r}; valid joints: {', '.join(self.joint_names)}") from None

    def full_betas(self, betas=None, note: bool = False, key: str = "betas") -> torch.Tensor:
        """The one rule for shape coefficients: (..., S') betas (None = mean) -> (..., S) float on the body's
        dtype/device, S = :attr:`n_betas`. Fewer than S are zero-padded (logged when ``note``); more, NaN/Inf or
        values that are no numbers raise ValueError naming the count and the fix; any beyond +-:data:`MAX_ABS_BETA`
        standard deviations raise :class:`BodyShapeOutOfRange` (before anything is built on them). Every message
        starts with ``key``, where the user gave the betas (``garment.betas``, ``motion.betas``, a file's key)."""
        if betas is None:
            return torch.zeros(self.n_betas, dtype=self.dtype, device=self.device)
        try:
            betas = torch.as_tensor(betas, dtype=self.dtype, device=self.device)
        except (TypeError, ValueError) as err:
            raise ValueError(f"{key}: {betas!r} are not numbers ({err}); give a list of numbers, e.g. [1.0,-0.5]") from None
        if betas.dim() == 0 or betas.shape[-1] > self.n_betas:
            got = 1 if betas.dim() == 0 else betas.shape[-1]
            raise ValueError(f"{key}: {got} betas given; body {self.name} has {self.n_betas} shape coefficients: give at most "
                             f"{self.n_betas} (fewer are zero-padded), e.g. [1.0,-0.5]")  # fmt: skip
        _check_finite(betas, key)
        _check_shape_range(betas, self.name, key)
        n = betas.shape[-1]
        if n < self.n_betas:
            if note and n:
                logging.getLogger("drapebench").info("%s: %d betas given; zero-padded to body %s's %d", key, n, self.name, self.n_betas)
            betas = torch.nn.functional.pad(betas, (0, self.n_betas - n))
        return betas

    # ------------------------------------------------------------------ model
    def shaped(self, betas: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        """Rest-pose vertices (B,V,3) and joints (B,J,3) for betas (B,S') (S' <= S; None = mean)."""
        betas = self._betas(betas, 1)
        v = self.v_template + torch.einsum("vcs,bs->bvc", self.shapedirs[..., : betas.shape[-1]], betas)
        j = torch.einsum("jv,bvc->bjc", self.J_regressor, v)
        return v, j

    def forward(
        self,
        betas: torch.Tensor | None = None,
        pose: torch.Tensor | None = None,
        trans: torch.Tensor | None = None,
        skin: bool = True,
    ) -> BodyOutput:
        """Pose the body.

        Args:
            betas: (B, S') or (S',) shape coefficients, S' <= n_betas; None = mean shape.
                A single row is broadcast over the batch.
            pose: (B, J, 3) or (B, J*3) axis-angle per joint (radians); None = rest pose.
            trans: (B, 3) root translation (metres) added after skinning; None = zero.
            skin: False skips the vertices (``vertices`` is None) when only joints/transforms are needed.
        Returns:
            :class:`BodyOutput` with (B, V, 3) vertices, (B, J, 3) joints, (B, J, 4, 4) transforms.
        """
        batch = 1
        for t in (pose, trans, betas):
            if t is not None and t.dim() >= 2:
                batch = max(batch, t.shape[0])
        pose = self._pose(pose, batch)
        trans = self._trans(trans, batch)
        betas = self._betas(betas, batch)

        if not skin:
            j_rest = torch.einsum("jv,bvc->bjc", self.J_regressor, self.shaped(betas)[0])
            j_rest = j_rest.expand(batch, -1, -1) if j_rest.shape[0] != batch else j_rest
            G = self.global_transforms(axis_angle_to_matrix(pose), j_rest)
            A = G.clone()
            A[..., :3, 3] = G[..., :3, 3] - torch.einsum("bjkl,bjl->bjk", G[..., :3, :3], j_rest) + trans[:, None]
            return BodyOutput(vertices=None, joints=G[..., :3, 3] + trans[:, None], transforms=A, rest_joints=j_rest)
        v_shaped, j_rest = self.shaped(betas)
        if v_shaped.shape[0] != batch:
            v_shaped, j_rest = v_shaped.expand(batch, -1, -1), j_rest.expand(batch, -1, -1)
        R = axis_angle_to_matrix(pose)  # (B,J,3,3)
        if self.posedirs is not None:
            eye = torch.eye(3, dtype=R.dtype, device=R.device)
            feat = (R[:, 1:] - eye).reshape(batch, -1)
            v_shaped = v_shaped + torch.einsum("vcp,bp->bvc", self.posedirs, feat)

        G = self.global_transforms(R, j_rest)  # (B,J,4,4)
        joints = G[..., :3, 3] + trans[:, None]
        A = G.clone()
        A[..., :3, 3] = G[..., :3, 3] - torch.einsum("bjkl,bjl->bjk", G[..., :3, :3], j_rest) + trans[:, None]
        verts = lbs(v_shaped, self.weights, A)
        return BodyOutput(vertices=verts, joints=joints, transforms=A, rest_joints=j_rest)

    def global_transforms(self, R: torch.Tensor, j_rest: torch.Tensor) -> torch.Tensor:
        """Chain local rotations R (B,J,3,3) about rest joints (B,J,3) into world transforms (B,J,4,4)."""
        batch = R.shape[0]
        rel = j_rest.clone()
        parents = self.parents
        rel[:, 1:] = j_rest[:, 1:] - j_rest[:, parents[1:]]
        local = torch.zeros(batch, self.n_joints, 4, 4, dtype=R.dtype, device=R.device)
        local[..., :3, :3] = R
        local[..., :3, 3] = rel
        local[..., 3, 3] = 1.0
        chain = [local[:, 0]]
        for j in range(1, self.n_joints):
            chain.append(chain[parents[j]] @ local[:, j])
        return torch.stack(chain, dim=1)

    # ------------------------------------------------------------------ input checks
    def _pose(self, pose, batch):
        J = self.n_joints
        if pose is None:
            return torch.zeros(batch, J, 3, dtype=self.dtype, device=self.device)
        pose = torch.as_tensor(pose, dtype=self.dtype, device=self.device)
        if pose.dim() == 2 and pose.shape[-1] == 3 * J:
            pose = pose.reshape(-1, J, 3)
        if pose.dim() == 2 and pose.shape == (J, 3):
            pose = pose.unsqueeze(0)
        if pose.dim() != 3 or pose.shape[1:] != (J, 3):
            raise ValueError(
                f"pose has shape {tuple(pose.shape)}; {self.name} expects (B, {J}, 3) or (B, {3 * J}) "
                f"axis-angle for joints {self.joint_names}"
            )
        _check_finite(pose, "pose")
        return pose.expand(batch, -1, -1) if pose.shape[0] == 1 else pose

    def _trans(self, trans, batch):
        if trans is None:
            return torch.zeros(batch, 3, dtype=self.dtype, device=self.device)
        trans = torch.as_tensor(trans, dtype=self.dtype, device=self.device)
        if trans.dim() == 1:
            trans = trans.unsqueeze(0)
        if trans.dim() != 2 or trans.shape[-1] != 3:
            raise ValueError(f"trans has shape {tuple(trans.shape)}; expected (B, 3) metres")
        _check_finite(trans, "trans")
        return trans.expand(batch, -1) if trans.shape[0] == 1 else trans

    def _betas(self, betas, batch):
        if betas is None:
            return torch.zeros(1, self.n_betas, dtype=self.dtype, device=self.device)
        betas = torch.as_tensor(betas, dtype=self.dtype, device=self.device)
        if betas.dim() == 1:
            betas = betas.unsqueeze(0)
        if betas.dim() != 2 or betas.shape[-1] > self.n_betas:
            raise ValueError(
                f"betas has shape {tuple(betas.shape)}; {self.name} expects (B, S) with S <= {self.n_betas}"
            )
        _check_finite(betas, "betas")
        _check_shape_range(betas, self.name)
        return betas

    def extra_repr(self) -> str:
        return f"name={self.name}, V={self.n_vertices}, J={self.n_joints}, S={self.n_betas}"


def _check_finite(t: torch.Tensor, what: str) -> None:
    if not torch.isfinite(t).all():
        bad = (~torch.isfinite(t)).nonzero()[:5].tolist()
        raise ValueError(f"{what} contains NaN or Inf (first bad indices {bad}); clean the input first")


def _check_shape_range(betas: torch.Tensor, body: str, key: str = "betas") -> None:
    """Raise :class:`BodyShapeOutOfRange` naming ``key`` (where the user gave them) and the components of betas
    (..., S) beyond +-MAX_ABS_BETA."""
    peak = betas.detach().abs().reshape(-1, betas.shape[-1]).amax(0) if betas.numel() else betas.new_zeros(0)
    over = torch.nonzero(peak > MAX_ABS_BETA).flatten().tolist()
    if over:
        values = betas.detach().reshape(-1, betas.shape[-1])
        worst = values.gather(0, values.abs().argmax(0, keepdim=True))[0]
        shown = ", ".join(f"b{k}={float(worst[k]):g}" for k in over)
        raise BodyShapeOutOfRange(
            f"{key}: body shape {shown} is outside +-{MAX_ABS_BETA:g} standard deviations, where {body}'s shape space stops "
            f"being a human body (anny at b0 = -5 / +5 is 1.25 / 2.16 m tall; beyond, the shape space extrapolates into "
            f"ever smaller or larger meshes with folded faces: data/bodies/PROVENANCE.md). Give {key} within "
            f"+-{MAX_ABS_BETA:g}, e.g. [2.0,-1.0]"
        )


def _validate_arrays(arrays: dict, source: str) -> dict:
    """Check keys and shapes of an SMPL-format dict; raise naming the bad key and the expected shape."""
    missing = [k for k in REQUIRED_KEYS if arrays.get(k) is None]
    if missing:
        raise ValueError(
            f"{source}: missing body model key(s) {missing}; an SMPL-format file needs {list(REQUIRED_KEYS)}"
            " (plus optional posedirs, joint_names)"
        )
    out = {k: (None if v is None else _dense(v)) for k, v in arrays.items()}
    vt = out["v_template"]
    if vt.ndim != 2 or vt.shape[1] != 3:
        raise ValueError(f"{source}: v_template has shape {vt.shape}; expected (V, 3)")
    V = vt.shape[0]
    parents = out["parents"].reshape(-1).astype(np.int64)
    J = parents.shape[0]
    expect = {
        "shapedirs": (V, 3, None),
        "J_regressor": (J, V),
        "weights": (V, J),
        "faces": (None, 3),
        "posedirs": (V, 3, 9 * (J - 1)),
    }
    for key, shape in expect.items():
        a = out[key]
        if a is None:
            continue
        ok = a.ndim == len(shape) and all(s is None or s == d for s, d in zip(shape, a.shape))
        if not ok:
            pretty = tuple("*" if s is None else s for s in shape)
            raise ValueError(f"{source}: {key} has shape {a.shape}; expected {pretty} (V={V}, J={J})")
    if parents[0] >= 0 or np.any(parents[1:] < 0) or np.any(parents[1:] >= np.arange(1, J)):
        raise ValueError(f"{source}: parents must have the root first (-1) and each parent before its child")
    if out["faces"].min() < 0 or out["faces"].max() >= V:
        raise ValueError(f"{source}: faces index outside [0, {V})")
    for key in ("v_template", "shapedirs", "J_regressor", "weights"):
        if not np.isfinite(out[key]).all():
            raise ValueError(f"{source}: {key} contains NaN or Inf")
    out["parents"] = parents
    return out


def _dense(a):
    if hasattr(a, "toarray"):  # scipy sparse (SMPL's J_regressor)
        a = a.toarray()
    return np.asarray(a)


class _ChumpyStub:
    """Stands in for chumpy arrays inside SMPL pickles, so chumpy need not be installed."""

    def __init__(self, *args, **kwargs):
        self.x = None

    def __setstate__(self, state):
        self.x = state.get("x") if isinstance(state, dict) else None

    def __array__(self, dtype=None, copy=None):
        return np.asarray(self.x, dtype=dtype)


PICKLE_BUILTINS = {("copy_reg", "_reconstructor"), ("copyreg", "_reconstructor"), ("__builtin__", "object"),
                   ("builtins", "object")}  # what numpy arrays in a (Python 2) pickle reconstruct with


class _SMPLUnpickler(pickle.Unpickler):
    """Loads only what SMPL-family files hold: numpy and scipy.sparse arrays, chumpy arrays (as stubs); any other
    class (which could run code on loading) is refused."""

    def find_class(self, module, name):
        if module.startswith("chumpy"):
            return _ChumpyStub
        if module.split(".")[0] == "numpy" or module.startswith("scipy.sparse") or (module, name) in PICKLE_BUILTINS:
            return super().find_class(module, name)
        raise pickle.UnpicklingError(f"refusing to load {module}.{name} from a pickle: an SMPL-family file holds only numpy, "
                                     "scipy.sparse and chumpy arrays; convert the file to .npz")  # fmt: skip


def read_pickle(path: Path) -> dict:
    """The dict of an SMPL-family pickle (a body model or a pose file; Python 2 pickles too), chumpy arrays as
    numpy, without chumpy installed. Raises ValueError when the pickle is not a dict or holds a class other than
    numpy's, scipy.sparse's or chumpy's (which could run code when loaded)."""
    with open(path, "rb") as f:
        try:
            d = _SMPLUnpickler(f, encoding="latin1").load()
        except pickle.UnpicklingError as err:
            raise ValueError(f"{path}: {err}") from None
    if not isinstance(d, dict):
        raise ValueError(f"{path}: expected a dict of SMPL arrays, found {type(d).__name__}")
    return {k: (np.asarray(v) if isinstance(v, _ChumpyStub) else v) for k, v in d.items()}


def _read_model_file(path: Path) -> dict:
    if path.suffix == ".npz":
        try:
            with np.load(path, allow_pickle=False) as z:
                d = {k: z[k] for k in z.files}
        except (zipfile.BadZipFile, zlib.error, OSError, EOFError, ValueError) as err:
            raise ValueError(
                f"{path} is truncated or corrupt ({type(err).__name__}: {err}); restore a shipped body with "
                f"`git checkout -- {path}` or bake it again with `python -m drapebench.body.bake`"
            ) from err
    elif path.suffix in (".pkl", ".pickle"):
        d = read_pickle(path)
    else:
        raise ValueError(f"{path}: unsupported body file type {path.suffix!r}; use .npz or .pkl")
    if "parents" not in d and "kintree_table" in d:
        kt = np.asarray(d["kintree_table"]).astype(np.int64)
        parents = kt[0].copy()
        parents[0] = -1
        d["parents"] = parents
    if "faces" not in d and "f" in d:
        d["faces"] = d["f"]
    return d


def torch_device(device) -> torch.device:
    """``device`` as a torch device; ValueError naming the fix when it is not a CPU or CUDA device (the reference
    simulator's and the BVH's kernels run on those two alone), asks for CUDA and torch has none, or names a GPU
    index this machine does not have."""
    try:
        dev = torch.device(device)
    except RuntimeError as err:
        raise ValueError(f"device {device!r} is not a torch device ({err}); use device=cpu or device=cuda") from err
    if dev.type not in ("cpu", "cuda"):
        raise ValueError(f"device={device} is not supported: the suite runs on device=cpu or device=cuda (cuda:N for the "
                         "N-th GPU), where its warp kernels run")  # fmt: skip
    if dev.type == "cuda" and not torch.cuda.is_available():
        why = "this torch is a CPU-only build" if torch.version.cuda is None else "no CUDA GPU is visible"
        raise ValueError(f"device={device} requested but {why} (torch {torch.__version__}); use device=cpu, or install a "
                         "CUDA build of torch (make venv TORCH_SPEC=... ; see README)")  # fmt: skip
    if dev.type == "cuda" and dev.index is not None and dev.index >= torch.cuda.device_count():
        raise ValueError(f"device={device} requested but this machine has {torch.cuda.device_count()} CUDA GPU(s), "
                         "numbered from 0; use device=cuda (the first) or device=cuda:N with N below that count")  # fmt: skip
    return dev


def load_body(name_or_path: str | Path = "anny", dtype: torch.dtype = torch.float32, device="cpu", up_axis: str | None = None) -> BodyModel:
    """Load a shipped body (``"anny"``, ``"anny_lowres"``) or an SMPL-format ``.npz``/``.pkl`` file.

    Args:
        name_or_path: shipped body name or a file path.
        dtype: float32 (default) or float64.
        device: torch device for the buffers.
        up_axis: for user files, ``"y"`` converts a Y-up, +Z-facing SMPL model into the suite's
            Z-up, -Y-facing frame; default: the file's ``up_axis`` entry if present, else ``"z"``.
    Returns:
        :class:`BodyModel`.
    """
    device = torch_device(device)
    name = str(name_or_path)
    if name in SHIPPED_BODIES:
        path = BODY_DIR / f"{name}.npz"
        if not path.exists():
            raise FileNotFoundError(f"{path} is missing; rebuild it with `python -m drapebench.body.bake`")
    elif Path(name_or_path).exists():
        path = Path(name_or_path)
    elif (BODY_DIR / f"{name}.npz").exists():  # a user's model placed in data/bodies (e.g. body=smpl)
        path = BODY_DIR / f"{name}.npz"
    else:
        raise FileNotFoundError(
            f"body {name!r} is neither a shipped body ({', '.join(SHIPPED_BODIES)}) nor an existing file, and "
            f"{BODY_DIR / (name + '.npz')} does not exist: put an SMPL-format .npz there, or pass the file's path "
            "(python run.py body=smpl body.name=/path/to/model.npz; see README, 'Your own body')"
        )
    d = _read_model_file(path)
    axis = up_axis or str(np.asarray(d.get("up_axis", "z")))
    if axis not in ("y", "z"):
        raise ValueError(f"up_axis must be 'y' or 'z', not {axis!r}")
    if axis == "y":  # rotate +90 deg about X: y -> z, z -> -y (facing +Z becomes facing -Y)
        C = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])
        d["v_template"] = np.asarray(d["v_template"]) @ C.T
        d["shapedirs"] = np.einsum("ij,vjs->vis", C, np.asarray(d["shapedirs"]))
        if d.get("posedirs") is not None:
            d["posedirs"] = np.einsum("ij,vjs->vis", C, np.asarray(d["posedirs"]))
    names = d.get("joint_names")
    names = [str(n) for n in np.asarray(names).tolist()] if names is not None else None
    body = BodyModel(
        d.get("v_template"),
        d.get("shapedirs"),
        d.get("J_regressor"),
        d.get("weights"),
        d.get("parents"),
        d.get("faces"),
        joint_names=names,
        posedirs=d.get("posedirs"),
        name=path.stem if name not in SHIPPED_BODIES else name,
        dtype=dtype,
    )
    return body.to(device)
