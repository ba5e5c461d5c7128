import dataclasses

import pytest
import yaml

from drapebench.physics import Material
from drapebench.physics.material import CONF_DIR
from drapebench.schema import MaterialConf

PRESETS = sorted(p.stem for p in CONF_DIR.glob("*.yaml"))


def test_default_is_the_gaps_snug_cotton():
    m = Material()
    assert m.area_density == pytest.approx(0.2002, rel=1e-3)
    assert m.lame_mu == pytest.approx(2.357e4, rel=1e-3)
    assert m.lame_lambda == pytest.approx(4.439e4, rel=1e-3)
    assert m.bending == pytest.approx(3.96e-5, rel=1e-3)
    assert m.collision_thickness == 2e-3 and m.gravity == (0.0, 0.0, -9.81) and m.dt == pytest.approx(1 / 30)
    # ARCSim relations: E = 2 mu (1 + nu) and lambda / mu = 2 nu / (1 - nu)
    assert 2 * m.lame_mu * (1 + m.poisson) == pytest.approx(m.young)
    assert m.lame_lambda / m.lame_mu == pytest.approx(2 * m.poisson / (1 - m.poisson))
    assert Material.preset("cotton") == m


@pytest.mark.parametrize("name", PRESETS)
def test_presets_are_valid_and_inside_hoods_sampled_ranges(name):
    raw = yaml.safe_load((CONF_DIR / f"{name}.yaml").read_text())
    assert set(raw) == {f.name for f in dataclasses.fields(Material)}  # every field spelled out
    assert set(raw) == {f.name for f in dataclasses.fields(MaterialConf)}  # composes through Hydra
    m = Material.preset(name)
    assert m.name == name
    assert 15909 <= m.lame_mu <= 63636 and 3535 <= m.lame_lambda <= 93334
    assert 6.37e-8 <= m.bending <= 1.31e-3 and 0.0434 <= m.area_density <= 0.7
    assert Material.from_config(m.to_dict()) == m


def test_presets_cover_the_expected_fabrics():
    assert {"cotton", "silk", "denim", "leather"} <= set(PRESETS)
    silk, denim = Material.preset("silk"), Material.preset("denim")
    assert silk.area_density < Material().area_density < denim.area_density
    assert silk.bending < Material().bending < denim.bending


def test_bad_materials_are_named():
    with pytest.raises(KeyError, match="presets: .*cotton"):
        Material.preset("chainmail")
    with pytest.raises(ValueError, match=r"unknown material key.*; valid: \["):
        Material.from_config({"densty": 1.0})
    with pytest.raises(ValueError, match="poisson"):
        Material(poisson=0.5)
    with pytest.raises(ValueError, match="thickness"):
        Material(thickness=0.0)
    with pytest.raises(ValueError, match="gravity"):
        Material(gravity=(0.0, -9.81))


@pytest.mark.parametrize("changes, message", [
    ({"young": float("inf")}, r"Material.young must be a finite number, got inf; e\.g\. material\.young=70000 \(cotton\), or a preset"),
    ({"thickness": 0.0}, r"Material.thickness must be positive, got 0.0; e\.g\. material\.thickness=0\.00047 \(cotton\)"),
    ({"poisson": 0.5}, r"Material.poisson must be in \[0, 0.5\), got 0.5; e\.g\. material\.poisson="),
    ({"friction": float("nan")}, r"Material.friction must be a finite number, got nan"),
    ({"collision_thickness": float("nan")}, r"Material.collision_thickness must be a finite number"),
    ({"gravity": (0.0, 0.0, float("nan"))}, r"Material.gravity must be finite and at most 100 m/s\^2"),
    ({"gravity": (0.0, 0.0, float("-inf"))}, r"Material.gravity must be finite"),
    ({"gravity": (0.0, 0.0, -1000.0)}, r"at most 100 m/s\^2 long"),
    ({"young": 1e9}, r"Material.young = 1e\+09 Pa is outside \[1000, 1e\+07\] Pa, the range of cloth \(cotton: 70000\)"),
    ({"thickness": 0.5}, r"Material.thickness = 0.5 m is outside"),
    ({"friction": 50.0}, r"Material.friction = 50 - is outside \[0, 2\]"),
    ({"dt": 30.0}, r"Material.dt = 30 s is outside"),
])  # fmt: skip
def test_non_finite_or_out_of_range_material_values_are_named_with_their_range(changes, message):
    with pytest.raises(ValueError, match=message):
        Material(**changes)
    with pytest.raises(ValueError, match=message):
        Material.from_config({**Material().to_dict(), **changes})
