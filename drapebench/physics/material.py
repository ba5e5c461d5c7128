"""Cloth material: density, membrane and bending stiffness, collision and time-step settings.

Units: thickness m; bulk_density kg/m^3 (area density = bulk_density x thickness, kg/m^2);
young Pa; poisson dimensionless; lame_mu / lame_lambda Pa *per thickness* (the energies multiply
by thickness, as the SNUG code and Chen et al. 2024's do: the SNUG paper's 11.1 / 20.9 were already x t);
bending N m; collision_thickness m; gravity m/s^2; dt s.

Lame and bending follow ARCSim's formulas used by SNUG and Chen et al. 2024 (``material.py`` there):
A = E / (1 - nu^2), mu = A (1 - nu) / 2, lambda = A nu, k_bend = A t^3 / 12 x bending_multiplier.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import yaml

from drapebench.keys import check_known, is_finite_number

CONF_DIR = Path(__file__).resolve().parents[2] / "conf" / "material"
# What a cloth can be (field: lowest, highest, unit): generous bounds around the presets (cotton, silk,
# denim, leather) and HOOD's sampled training ranges (docs/references.md). young up to 1e7 Pa is 140x
# cotton's; a stiffer sheet is no longer cloth (and its reference drape fails: it cannot bend round the body).
RANGES = {
    "thickness": (1e-5, 1e-2, "m"),
    "bulk_density": (10.0, 3000.0, "kg/m^3"),
    "young": (1e3, 1e7, "Pa"),
    "bending_multiplier": (1e-3, 1e4, "-"),
    "collision_thickness": (0.0, 0.02, "m"),
    "friction": (0.0, 2.0, "-"),
    "dt": (1e-4, 1.0, "s"),
}
MAX_GRAVITY = 100.0  # m/s^2 (about 10 g)


def _fix(key: str) -> str:
    """The fix a message on Material's ``key`` ends with: cotton's value as an example, and the presets."""
    return f"e.g. material.{key}={Material.__dataclass_fields__[key].default:g} (cotton), or a preset: conf/material/"


@dataclass(frozen=True)
class Material:
    """A cloth material (defaults: the cotton of SNUG and Chen et al. 2024, ``docs/references.md``).

    Every value must be finite and within :data:`RANGES` (gravity at most :data:`MAX_GRAVITY` long), else
    ValueError naming the field, its range and the fix.
    Fields: name; thickness t (m); bulk_density (kg/m^3); young E (Pa); poisson nu (-, in [0, 0.5));
    bending_multiplier (-, ARCSim's factor on the plate stiffness, as Chen et al. 2024 use it); collision_thickness eps (m,
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
    gravity: tuple[float, float, float] = field(default=(0.0, 0.0, -9.81))
    dt: float = 1.0 / 30.0

    def __post_init__(self) -> None:
        for key in ("thickness", "bulk_density", "young", "poisson", "bending_multiplier", "collision_thickness", "friction", "dt"):
            value = getattr(self, key)
            if not is_finite_number(value):
                raise ValueError(f"Material.{key} must be a finite number, got {value!r}; {_fix(key)}")
        for key in ("thickness", "bulk_density", "young", "bending_multiplier", "dt"):
            if not getattr(self, key) > 0:
                raise ValueError(f"Material.{key} must be positive, got {getattr(self, key)}; {_fix(key)}")
        if not 0.0 <= self.poisson < 0.5:
            raise ValueError(f"Material.poisson must be in [0, 0.5), got {self.poisson}; {_fix('poisson')}")
        for key, (lo, hi, unit) in RANGES.items():
            if not lo <= getattr(self, key) <= hi:
                raise ValueError(f"Material.{key} = {getattr(self, key):g} {unit} is outside [{lo:g}, {hi:g}] {unit}, the range of "
                                 f"cloth (cotton: {Material.__dataclass_fields__[key].default:g}); give a value in it "
                                 f"(material.{key}=..., presets: conf/material/)")  # fmt: skip
        try:
            gravity = tuple(float(g) for g in self.gravity)
        except (TypeError, ValueError):
            raise ValueError(f"Material.gravity must be 3 numbers (m/s^2), got {self.gravity!r}") from None
        if len(gravity) != 3:
            raise ValueError(f"Material.gravity must have 3 components, got {self.gravity}")
        if not all(math.isfinite(g) for g in gravity) or math.hypot(*gravity) > MAX_GRAVITY:
            raise ValueError(f"Material.gravity must be finite and at most {MAX_GRAVITY:g} m/s^2 long, got {gravity}; "
                             "e.g. material.gravity=[0,0,-9.81]")  # fmt: skip
        object.__setattr__(self, "gravity", gravity)

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
        check_known(d, cls.__dataclass_fields__, "material key")
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
