"""Cloth material: density, membrane and bending stiffness, collision and time-step settings.

Units: thickness m; bulk_density kg/m^3 (area density = bulk_density x thickness, kg/m^2);
young Pa; poisson dimensionless; lame_mu / lame_lambda Pa *per thickness* (the energies multiply
by thickness, as the GAPS/SNUG code does: the SNUG paper's 11.1 / 20.9 were already x t);
bending N m; collision_thickness m; gravity m/s^2; dt s.

Lame and bending follow ARCSim's formulas used by GAPS/SNUG (``material.py`` there):
A = E / (1 - nu^2), mu = A (1 - nu) / 2, lambda = A nu, k_bend = A t^3 / 12 x bending_multiplier.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import yaml

CONF_DIR = Path(__file__).resolve().parents[2] / "conf" / "material"


@dataclass(frozen=True)
class Material:
    """A cloth material (defaults: the GAPS/SNUG cotton, ``docs/references.md``).

    Fields: name; thickness t (m); bulk_density (kg/m^3); young E (Pa); poisson nu (-, in [0, 0.5));
    bending_multiplier (-, ARCSim/GAPS factor on the plate stiffness); collision_thickness eps (m,
    collision penalty margin); friction (-, Coulomb coefficient, used by the reference simulator);
    gravity (m/s^2, 3 components, Z up); dt (s, time step of the inertia term).
    Derived: area_density (kg/m^2), lame_mu / lame_lambda (Pa, per thickness), bending (N m).
    Default values: area density 0.2002 kg/m^2, mu 2.357e4 Pa, lambda 4.439e4 Pa, k_b 3.96e-5 N m.
    """

    name: str = "cotton"
    thickness: float = 4.7e-4
    bulk_density: float = 426.0
    young: float = 0.7e5
    poisson: float = 0.485
    bending_multiplier: float = 50.0
    collision_thickness: float = 2e-3
    friction: float = 0.5
    gravity: tuple = field(default=(0.0, 0.0, -9.81))
    dt: float = 1.0 / 30.0

    def __post_init__(self) -> None:
        for key in ("thickness", "bulk_density", "young", "bending_multiplier", "dt"):
            if not getattr(self, key) > 0:
                raise ValueError(f"Material.{key} must be positive, got {getattr(self, key)}")
        if not 0.0 <= self.poisson < 0.5:
            raise ValueError(f"Material.poisson must be in [0, 0.5), got {self.poisson}")
        if self.collision_thickness < 0 or self.friction < 0:
            raise ValueError("Material.collision_thickness and friction must be >= 0")
        object.__setattr__(self, "gravity", tuple(float(g) for g in self.gravity))
        if len(self.gravity) != 3:
            raise ValueError(f"Material.gravity must have 3 components, got {self.gravity}")

    @property
    def area_density(self) -> float:
        """Mass per area, kg/m^2."""
        return self.bulk_density * self.thickness

    @property
    def _plane_stress(self) -> float:
        return self.young / (1.0 - self.poisson**2)

    @property
    def lame_mu(self) -> float:
        """Per-thickness Lame mu (Pa)."""
        return 0.5 * self._plane_stress * (1.0 - self.poisson)

    @property
    def lame_lambda(self) -> float:
        """Per-thickness Lame lambda (Pa)."""
        return self._plane_stress * self.poisson

    @property
    def bending(self) -> float:
        """Bending stiffness k_b (N m)."""
        return self._plane_stress * self.thickness**3 / 12.0 * self.bending_multiplier

    def to_dict(self) -> dict:
        """The fields as a plain dict (Hydra/JSON friendly); ``Material.from_config`` inverts it."""
        return asdict(self)

    @classmethod
    def from_config(cls, cfg) -> "Material":
        """From a mapping (e.g. a Hydra ``material`` node); unknown keys are an error naming the valid ones."""
        d = dict(cfg)
        valid = set(cls.__dataclass_fields__)
        unknown = set(d) - valid
        if unknown:
            raise ValueError(f"unknown material key(s) {sorted(unknown)}; valid keys: {sorted(valid)}")
        return cls(**d)

    @classmethod
    def preset(cls, name: str) -> "Material":
        """A named preset from ``conf/material/<name>.yaml`` (cotton, silk, denim, leather); KeyError names the choices."""
        path = CONF_DIR / f"{name}.yaml"
        if not path.exists():
            names = sorted(p.stem for p in CONF_DIR.glob("*.yaml"))
            raise KeyError(f"unknown material {name!r}; presets: {', '.join(names)}")
        return cls.from_config(yaml.safe_load(path.read_text()))

    def with_(self, **changes) -> "Material":
        """A copy with some fields changed."""
        return replace(self, **changes)
