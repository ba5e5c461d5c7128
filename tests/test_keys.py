"""drapebench.keys.check_known: the one check of given keys against the keys something reads."""

import pytest

from drapebench.keys import check_known


def test_an_unknown_key_is_named_with_the_closest_valid_one_and_every_valid_one():
    with pytest.raises(ValueError, match=r"^unknown material key\(s\) \['thicknes'\] \(did you mean 'thickness'\?\); valid: \['dt', 'thickness'\]$"):
        check_known({"thicknes": 1.0}, ("thickness", "dt"), "material key")
    with pytest.raises(ValueError, match=r"^unknown parameter\(s\) \['zzz'\] for motion 'walk'; valid: \['speed'\]$"):
        check_known(["zzz"], ["speed"], "parameter", "for motion 'walk'")
    check_known({"dt": 1.0}, ("thickness", "dt"), "material key")  # known keys pass
    check_known({}, (), "material key")


def test_a_config_node_is_made_from_its_domain_dataclass_and_checks_its_types():
    import typing
    from dataclasses import dataclass, field, fields

    from omegaconf import OmegaConf
    from omegaconf.errors import ConfigAttributeError, ValidationError

    from drapebench.data.reference_spec import ReferenceSetSpec
    from drapebench.physics.material import Material
    from drapebench.reference.settings import SimSettings
    from drapebench.schema import DataConf, MaterialConf, ReferenceConf, node

    for conf, domain in ((MaterialConf, Material), (ReferenceConf, SimSettings), (DataConf, ReferenceSetSpec)):
        assert [f.name for f in fields(conf)] == [f.name for f in fields(domain)]  # one declaration of the fields
    assert OmegaConf.structured(DataConf).name == "cpu" and typing.get_type_hints(DataConf)["motions"] == typing.List[str]

    @dataclass(frozen=True)
    class Toy:
        size: float = 1.5
        axes: tuple[int, ...] = (1, 2)
        label: str | None = None
        extra: dict = field(default_factory=dict)

    conf = OmegaConf.structured(node(Toy, "ToyConf"))
    assert OmegaConf.to_container(conf) == {"size": 1.5, "axes": [1, 2], "label": None, "extra": {}}
    with pytest.raises(ValidationError):
        conf.size = "big"
    with pytest.raises(ValidationError):
        conf.axes = ["x"]
    with pytest.raises(ConfigAttributeError, match="Key 'sise' not in 'ToyConf'"):
        conf.sise = 2.0
    loose = OmegaConf.structured(node(Toy, "ToyOverrides", optional=True))
    assert all(v is None for v in OmegaConf.to_container(loose).values())  # None: the code's default


def test_composing_a_config_imports_no_torch():
    """run.py registers the schema before Hydra composes: a bad override fails before the pipeline's imports."""
    import subprocess
    import sys
    from pathlib import Path

    probe = "import sys, drapebench.schema; print(sorted(m for m in ('torch', 'numpy', 'warp') if m in sys.modules))"
    p = subprocess.run([sys.executable, "-c", probe], cwd=Path(__file__).resolve().parent.parent, capture_output=True, text=True, timeout=120)
    assert p.returncode == 0 and p.stdout.strip() == "[]", p.stdout + p.stderr[-2000:]
