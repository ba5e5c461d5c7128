"""What a reference set holds (:class:`ReferenceSetSpec`, the ``data`` config node's fields): a module that imports
no torch, so the config schema makes its node from the dataclass. :mod:`drapebench.data.reference_set` builds the set."""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from pathlib import Path

import yaml

from drapebench.body.defaults import DEFAULT_TRANSITION, HELD_OUT_MOTIONS
from drapebench.keys import check_known

CONF_DIR = Path(__file__).resolve().parents[2] / "conf" / "data"


@dataclass(frozen=True)
class ReferenceSetSpec:
    """What a reference set holds: ``per_motion`` sequences of each of ``motions`` (named motions and
    "random"), ``n_frames`` frames each plus ``transition``, at ``fps``; body shapes ``betas ~ N(0,
    beta_sigma^2)`` clipped to +-``beta_clip`` on the first ``n_shape_betas`` components; sequence seeds
    and shapes drawn from ``seed``; ``params`` per motion (e.g. ``{"random": {"amplitude": 0.8}}``).
    Simulated by ``solver`` with ``settings`` overriding ``conf/reference/<solver>.yaml``, against the
    collider ``body`` (a body name; None: the body the garment is draped on); ``n_jobs`` worker
    processes; a failed sequence is replaced by up to ``replace_failed`` new draws of its motion kind.
    The held-out test motions (kick, stress) are refused unless ``allow_held_out``."""

    name: str = "custom"
    motions: tuple[str, ...] = ("random",)
    per_motion: int = 1
    n_frames: int = 45
    seed: int = 40000
    fps: float = 30.0
    transition: int = DEFAULT_TRANSITION
    beta_sigma: float = 1.0
    beta_clip: float = 2.0
    n_shape_betas: int = 4
    params: dict = field(default_factory=dict)
    solver: str = "vbd"
    settings: dict = field(default_factory=dict)
    body: str | None = None
    n_jobs: int = 1
    replace_failed: int = 0
    allow_held_out: bool = False

    def __post_init__(self) -> None:
        object.__setattr__(self, "motions", tuple(self.motions))
        held = [m for m in self.motions if m in HELD_OUT_MOTIONS]
        if held and not self.allow_held_out:
            raise ValueError(f"reference set {self.name!r} asks for held-out test motion(s) {held}: training data must not "
                             "see them; drop them from motions or set allow_held_out=true")  # fmt: skip
        if int(self.replace_failed) < 0:
            raise ValueError(f"data.replace_failed must be >= 0 (replacement draws per failed sequence), got {self.replace_failed}")
        if int(self.per_motion) < 1 or int(self.n_frames) < 1 or int(self.n_jobs) < 1:
            raise ValueError(f"reference set {self.name!r} needs per_motion, n_frames and n_jobs >= 1, got "
                             f"{self.per_motion}, {self.n_frames}, {self.n_jobs}")  # fmt: skip
        if int(self.seed) < 0:
            raise ValueError(f"data.seed must be >= 0 (it seeds numpy's generator), got {self.seed}; e.g. data.seed=40000")

    @classmethod
    def from_config(cls, cfg) -> "ReferenceSetSpec":
        """From a mapping (a Hydra ``data`` node or a ``conf/data`` file); unknown keys name the valid ones."""
        cfg = dict(cfg)
        check_known(cfg, [f.name for f in fields(cls)], "reference set key")
        return cls(**cfg)

    @classmethod
    def preset(cls, name: str) -> "ReferenceSetSpec":
        """``conf/data/<name>.yaml`` (cpu, paper); KeyError names the choices."""
        path = CONF_DIR / f"{name}.yaml"
        if not path.exists():
            raise KeyError(f"unknown reference set preset {name!r}; presets: {', '.join(sorted(p.stem for p in CONF_DIR.glob('*.yaml')))}")
        return cls.from_config(yaml.safe_load(path.read_text()))

    def dataset_spec(self):
        """The body sequences to simulate, as a :class:`drapebench.body.dataset.DatasetSpec` (split "train")."""
        from drapebench.body.dataset import DatasetSpec

        return DatasetSpec(self.motions, int(self.per_motion), int(self.n_frames), "train", seed=int(self.seed), fps=float(self.fps),
                           transition=int(self.transition), beta_sigma=float(self.beta_sigma), beta_clip=float(self.beta_clip),
                           n_shape_betas=int(self.n_shape_betas), params=dict(self.params))  # fmt: skip
