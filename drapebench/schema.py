"""Structured-config schema of ``conf/``: typos and wrong types fail when Hydra composes the config."""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum
from typing import Any, Dict, List, Optional

from hydra.core.config_store import ConfigStore


@dataclass
class MethodConf:
    name: str = "lbs"  # row label in tables
    impl: Optional[str] = None  # registered implementation (methods.available()); default: name
    params: Dict[str, Any] = field(default_factory=dict)


@dataclass
class BodyConf:
    name: str = "anny"  # anny, anny_lowres, or a path to an SMPL-format .npz/.pkl


@dataclass
class GarmentConf:
    kind: str = "tshirt"
    seed: int = 0
    params: Dict[str, Any] = field(default_factory=dict)


@dataclass
class MotionConf:
    name: str = "walk"
    n_frames: int = 90
    fps: float = 30.0
    transition: int = 15
    seed: int = 1000
    betas: Optional[List[float]] = None  # test body shape; None = mean
    params: Dict[str, Any] = field(default_factory=dict)


@dataclass
class MaterialConf:
    name: str = "cotton"
    thickness: float = 4.7e-4
    bulk_density: float = 426.0
    young: float = 7.0e4
    poisson: float = 0.485
    bending_multiplier: float = 50.0
    collision_thickness: float = 2.0e-3
    friction: float = 0.5
    gravity: List[float] = field(default_factory=lambda: [0.0, 0.0, -9.81])
    dt: float = 1.0 / 30.0


@dataclass
class TrainConf:
    name: str = "cpu"
    dataset: str = "train_small"  # drapebench.body.dataset name
    seed: int = 0
    params: Dict[str, Any] = field(default_factory=dict)  # method-specific training settings


@dataclass
class ReferenceConf:
    """Physics-based reference of the test sequence (drapebench.reference.SimSettings fields;
    None keeps the solver's default from conf/reference/<solver>.yaml)."""

    solver: Optional[str] = None  # None: no reference in this run (reference=none)
    substeps: Optional[int] = None
    iterations: Optional[int] = None
    settle_frames: Optional[int] = None
    pins: Optional[bool] = None
    self_contact: Optional[bool] = None
    contact_ke: Optional[float] = None
    contact_kd: Optional[float] = None
    contact_gap: Optional[float] = None
    damping: Optional[float] = None
    max_speed: Optional[float] = None
    device: Optional[str] = None  # None: cuda when available, else cpu


@dataclass
class EvalConf:
    skip_transition: bool = True
    energies: bool = True


class VizMode(Enum):
    rerun = "rerun"  # drape.rrd in the run directory
    none = "none"  # no recording (costs nothing)


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
    eval: EvalConf = field(default_factory=EvalConf)
    viz: VizMode = VizMode.rerun
    force: bool = False  # rebuild cached data, checkpoints and references
    on_failure: FailureMode = FailureMode.stop  # drapebench.errors.DrapeFailed: stop, or record and go on
    seed: int = 0
    threads: Optional[int] = None  # torch threads per job; None: the job's share of the CPU cores
    device: str = "cpu"
    experiment_name: str = "default"


def register() -> None:
    """Register the schema as ``base_config`` (used first in conf/config.yaml's defaults)."""
    ConfigStore.instance().store(name="base_config", node=Config)
