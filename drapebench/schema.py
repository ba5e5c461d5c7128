"""Structured-config schema of ``conf/``: typos and wrong types fail when Hydra composes the config, and
keys added with ``+`` that nothing reads fail in :func:`check_keys` before a run starts; ``method.params`` is open
(:func:`base_config`): its keys are checked by the method's own dataclass as the run starts. The nodes of the domain's
own records (``material``, ``reference``, ``data``) are made from their dataclasses (:func:`node`), not copied."""

from __future__ import annotations

import copy
import types
import typing
from dataclasses import MISSING as MISSING_FIELD
from dataclasses import dataclass, field, fields, is_dataclass, make_dataclass
from enum import Enum
from typing import Any, Dict, List, Optional

from hydra.core.config_store import ConfigStore
from omegaconf import MISSING, DictConfig, OmegaConf

from drapebench.data.reference_spec import ReferenceSetSpec
from drapebench.keys import check_known
from drapebench.physics.material import Material
from drapebench.reference.settings import SimSettings


@dataclass
class MethodConf:
    name: str = MISSING  # row label in tables (conf/config.yaml's defaults choose the method)
    impl: Optional[str] = None  # registered implementation (methods.available()); default: name
    params: Dict[str, Any] = field(default_factory=dict)  # open to any key (base_config); the method's dataclass checks them


@dataclass
class BodyConf:
    name: str = "anny"  # anny, anny_lowres, or a path to an SMPL-format .npz/.pkl


@dataclass
class GarmentConf:
    kind: str = "tshirt"  # a parametric kind, or obj: a user's file (conf/garment/obj.yaml)
    name: Optional[str] = None  # the garment's name in run records, tables and recordings (None: its kind)
    seed: int = 0
    params: Dict[str, Any] = field(default_factory=dict)
    path: Optional[str] = None  # garment=obj: the .obj/.ply file (metres, on the rest-pose body)
    pins: Optional[List[int]] = None  # garment=obj: vertex indices held to the body; None: found automatically
    betas: Any = None  # body shape the garment is made on: None = mean body (each method and the reference transfer
    #                    it to the sequence's shape), "motion" = the sequence's betas, or a list of betas


class UpAxis(Enum):
    z = "z"  # AMASS as distributed: Z up, the root rotation carries SMPL's Y-up model frame into it
    y = "y"  # SMPL's own frame: Y up, the person facing +Z


class RootPlacement(Enum):
    ground = "ground"  # the first frame's root over its rest position, its lowest point on the rest body's floor
    file = "file"  # trans is the body's root translation as it is


@dataclass
class MotionConf:
    name: str = "walk"  # a procedural motion, file: a user's pose file, amass: an AMASS/SMPL file (conf/motion/)
    n_frames: Optional[int] = 90  # motion=file/amass: None = every frame of the file (amass: from start)
    fps: Optional[float] = 30.0  # motion=file: None = the file's fps; amass: the file is resampled to it (None: the file's)
    transition: int = 15
    seed: int = 1000
    betas: Optional[List[float]] = None  # test body shape; None = mean (motion=file: the file's betas)
    params: Dict[str, Any] = field(default_factory=dict)
    path: Optional[str] = None  # motion=file: .npz/.h5 with poses (T, J, 3) axis-angle [, trans, betas, fps]; amass: .npz/.pkl
    start: Optional[int] = None  # motion=amass: first frame kept, counted at fps
    source_fps: Optional[float] = None  # motion=amass: the file's frame rate when it has none (None: mocap_framerate, ...)
    up_axis: Optional[UpAxis] = None  # motion=amass: the file's world up axis
    root: Optional[RootPlacement] = None  # motion=amass: how the root translation is placed


def node(cls: type, name: str, /, optional: bool = False, **defaults) -> type:
    """The structured-config dataclass ``name`` with the fields of the domain dataclass ``cls``, in its order, typed as
    OmegaConf checks them (a tuple as a list of its items' type, ``X | None`` as Optional[X], a dict as Dict[str, Any])
    and with its defaults (``defaults`` replacing some); with ``optional`` every field is Optional with default None
    (None: the code's default). The domain class stays the one declaration of its fields."""
    hints = typing.get_type_hints(cls)
    out = []
    for f in fields(cls):
        kind = _config_type(hints[f.name])
        if optional:
            out.append((f.name, Optional[kind], field(default=None)))
            continue
        value = defaults.get(f.name, f.default if f.default is not MISSING_FIELD else f.default_factory())
        mutable = isinstance(value, (list, tuple, dict))
        made = (lambda v=value: copy.deepcopy(list(v) if isinstance(v, tuple) else v)) if mutable else None
        out.append((f.name, kind, field(default_factory=made) if mutable else field(default=value)))
    return make_dataclass(name, out)


def _config_type(hint) -> Any:
    """The type OmegaConf checks a domain field of type ``hint`` as."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (typing.Union, types.UnionType):
        inner = [a for a in args if a is not type(None)]
        return Optional[_config_type(inner[0])] if len(inner) == 1 else Any
    if hint is tuple or hint is list:
        return List[Any]
    if origin in (tuple, list):
        return List[_config_type(args[0])] if args else List[Any]
    if hint is dict or origin is dict:
        return Dict[str, Any]
    return hint


MaterialConf = node(Material, "MaterialConf")
ReferenceConf = node(SimSettings, "ReferenceConf", optional=True)  # None: conf/reference/<solver>.yaml's value
DataConf = node(ReferenceSetSpec, "DataConf", name="cpu")  # reference training data of supervised methods (conf/data/<name>.yaml)


@dataclass
class TrainConf:
    """The training budget of every learned method (drapebench.train); keys only one method reads live
    in that method's config (e.g. conf/method/<name>_budget/)."""

    name: str = "default"  # preset name (conf/train/<name>.yaml)
    dataset: str = "train_small"  # drapebench.body.dataset name
    seed: int = 0
    epochs: int = 1000  # passes over the training items; ignored when steps is set
    steps: Optional[int] = None  # optimizer steps (overrides epochs)
    batch_size: int = 16
    lr: float = 1e-3  # Adam learning rate (each parameter group scales it by its factor)
    lr_after: Optional[float] = 1e-4  # the rate from epoch lr_switch_epoch on
    lr_switch_epoch: Optional[int] = 10  # None: lr throughout
    lr_decay_fraction: Optional[float] = None  # linear decay to 0 over this last fraction of the budget
    grad_clip: Optional[float] = None  # scale each step's gradient to at most this global norm
    ema_decay: Optional[float] = None  # use an exponential moving average of the weights as the model
    max_minutes: Optional[float] = None  # time budget: stop with a warning and keep the best state
    checkpoint_every: int = 200  # steps between resumable checkpoints
    log_every: int = 10  # steps between progress-bar loss updates


@dataclass
class EvalConf:
    skip_transition: bool = True
    energies: bool = True


class VizMode(Enum):
    rerun = "rerun"  # drape.rrd in the run directory
    none = "none"  # no recording (costs nothing)


class Precision(Enum):
    float32 = "float32"  # the default
    float64 = "float64"  # body, garment topology, methods and metrics in double precision


class ExportFormat(Enum):
    none = "none"  # nothing exported (the default)
    usd = "usd"  # export/drape.usd: garment and body, time-sampled (drapebench.export)
    obj = "obj"  # export/obj/: an OBJ of the garment and of the body per frame
    pc2 = "pc2"  # export/pc2/: a PC2 point cache and a rest OBJ each of garment and body


class TrackerName(Enum):
    mlflow = "mlflow"  # every run logged to MLflow (drapebench.tracker), the default
    none = "none"  # the run folder only


@dataclass
class TrackerConf:
    name: TrackerName = TrackerName.mlflow
    uri: Optional[str] = None  # MLflow tracking URI; None: $MLFLOW_TRACKING_URI, else sqlite:///data/mlflow.db


class FailureMode(Enum):
    stop = "stop"  # a diverged simulation or training raises (the sweep stops)
    record = "record"  # it is written to the run's failed.json and the sweep goes on


@dataclass
class Config:
    method: MethodConf = field(default_factory=MethodConf)
    body: BodyConf = field(default_factory=BodyConf)
    garment: GarmentConf = field(default_factory=GarmentConf)
    motion: MotionConf = field(default_factory=MotionConf)
    material: MaterialConf = field(default_factory=MaterialConf)
    train: TrainConf = field(default_factory=TrainConf)
    reference: ReferenceConf = field(default_factory=ReferenceConf)
    data: DataConf = field(default_factory=DataConf)
    eval: EvalConf = field(default_factory=EvalConf)
    tracker: TrackerConf = field(default_factory=TrackerConf)
    viz: VizMode = VizMode.rerun
    export: ExportFormat = ExportFormat.none  # after the drape, into the run directory (python -m drapebench.export does it later)
    viz_body: Optional[str] = None  # body drawn in drape.rrd (e.g. anny_lowres: ~4x smaller file); None: the run's body
    force: bool = False  # rebuild cached data, checkpoints and references
    on_failure: FailureMode = FailureMode.stop  # drapebench.errors.DrapeFailed: stop, or record and go on
    seed: int = 0
    threads: Optional[int] = None  # torch threads per job; None: the job's share of the CPU cores
    chunk_frames: int = 64  # frames draped (by a method that streams), written to prediction.h5 and scored at once
    device: str = "cpu"
    dtype: Precision = Precision.float32  # float64: the whole run in double precision (stability checks)
    experiment_name: str = "default"


def choice(value) -> str:
    """The name of a config choice: an Enum member's name once the schema has validated the config (``cfg.viz`` is a
    :class:`VizMode`), the value as a string in a config that was not composed against it (e.g. a plain mapping)."""
    return value.name if isinstance(value, Enum) else str(value)


def check_keys(cfg, schema: type = None, prefix: str = "") -> None:
    """Raise ValueError naming the first key of ``cfg`` (a DictConfig or mapping) that ``schema`` (default
    :class:`Config`) does not have, with the valid keys: Hydra's ``+key=value`` adds keys the schema lacks,
    which would otherwise be ignored. ``params`` mappings are checked by the code that reads them."""
    schema = schema or Config
    known = {f.name: f for f in fields(schema)}
    check_known([f"{prefix}{key}" for key in cfg], [f"{prefix}{key}" for key in known], "config key", "(nothing reads it)")
    for key in cfg:
        sub = known[key].default_factory if is_dataclass(getattr(known[key], "default_factory", None)) else None
        if sub is not None and cfg[key] is not None:
            check_keys(cfg[key], sub, f"{prefix}{key}.")


def base_config() -> DictConfig:
    """:class:`Config` as the node conf/config.yaml starts from, with ``method.params`` open: ``method.params.<key>=v``
    sets any key of a method's parameters from the command line (no ``+``) though its yaml does not name it, and the
    method's parameter dataclass (methods/params.py: ``typed_params``) checks the keys and their values when the run
    starts, naming an unknown key, the nearest valid one and every valid one. The flag survives the merges of the
    method's yaml files; every other node stays closed (a typo there fails as Hydra composes the config)."""
    cfg = OmegaConf.structured(Config)
    OmegaConf.set_struct(cfg.method.params, False)
    return cfg


def register() -> None:
    """Register :func:`base_config` as ``base_config`` (used first in conf/config.yaml's defaults)."""
    ConfigStore.instance().store(name="base_config", node=base_config())
