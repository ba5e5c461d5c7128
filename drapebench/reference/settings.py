"""Solver settings of the reference simulator; defaults live in ``conf/reference/<solver>.yaml``."""

from __future__ import annotations

import math
import typing
from dataclasses import asdict, dataclass, fields, replace
from pathlib import Path

import yaml

from drapebench.keys import check_known, check_type

CONF_DIR = Path(__file__).resolve().parents[2] / "conf" / "reference"
SOLVERS = ("vbd", "style3d")


@dataclass(frozen=True)
class SimSettings:
    """How the reference is simulated (see ``conf/reference/vbd.yaml`` for each field's meaning and unit).

    solver "vbd" | "style3d"; substeps per frame; iterations per substep; settle_frames before the
    sequence; pins (bool); self_contact (bool); contact_ke N/m; contact_kd N s/m; contact_gap m;
    damping s (Rayleigh beta); max_speed m/s (blow-up threshold); device None | "cpu" | "cuda[:i]";
    retry_substeps: substep counts tried in turn after a divergence (those not above ``substeps`` are
    skipped; empty: no retry).
    """

    solver: str = "vbd"
    substeps: int = 10
    iterations: int = 10
    settle_frames: int = 30
    pins: bool = True
    self_contact: bool = False
    contact_ke: float = 1000.0
    contact_kd: float = 0.01
    contact_gap: float = 0.01
    damping: float = 0.001
    max_speed: float = 50.0
    device: str | None = None
    retry_substeps: tuple[int, ...] = ()

    def __post_init__(self) -> None:
        if self.solver not in SOLVERS:
            raise ValueError(
                f"unknown reference solver {self.solver!r}; available: {', '.join(SOLVERS)} "
                "(XPBD and semi-implicit are not offered: they explode at realistic cloth mass)"
            )
        hints = typing.get_type_hints(type(self))
        for f in fields(self):
            check_type(getattr(self, f.name), hints[f.name], "reference setting", f.name)
        object.__setattr__(self, "retry_substeps", tuple(int(n) for n in self.retry_substeps))
        if any(n < 1 for n in self.retry_substeps):
            raise ValueError(f"reference retry_substeps must all be >= 1, got {list(self.retry_substeps)}")
        for key in ("substeps", "iterations"):
            if int(getattr(self, key)) < 1:
                raise ValueError(f"reference {key} must be >= 1, got {getattr(self, key)}")
        if int(self.settle_frames) < 0:
            raise ValueError(f"reference settle_frames must be >= 0, got {self.settle_frames}")
        defaults = {f.name: f.default for f in fields(self)}
        for key, positive in (("contact_ke", True), ("max_speed", True), ("contact_kd", False), ("contact_gap", False), ("damping", False)):
            value = float(getattr(self, key))  # inf would disable the check or the contact it sets, silently
            if not (math.isfinite(value) and (value > 0 if positive else value >= 0)):
                raise ValueError(f"reference {key} must be finite and {'> 0' if positive else '>= 0'}, got {getattr(self, key)}; "
                                 f"e.g. reference.{key}={defaults[key]}")  # fmt: skip

    @classmethod
    def for_solver(cls, solver: str = "vbd", **overrides) -> "SimSettings":
        """Defaults of ``conf/reference/<solver>.yaml`` with ``overrides`` (None values are ignored)."""
        if solver not in SOLVERS:
            cls(solver=solver)  # raises the ValueError naming the choices
        base = yaml.safe_load((CONF_DIR / f"{solver}.yaml").read_text())
        given = {k: v for k, v in overrides.items() if v is not None}
        check_known(given, [f.name for f in fields(cls)], "reference setting")
        return cls(**{**base, **given, "solver": solver})

    def with_(self, **changes) -> "SimSettings":
        """A copy with some fields changed."""
        return replace(self, **changes)

    def to_dict(self) -> dict:
        return asdict(self)
