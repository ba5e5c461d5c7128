"""drapebench.keys: check_known, the one check of given keys against the keys something reads, and check_type, the
one check of a given value against its field's type."""

import typing

import numpy as np
import pytest

from drapebench.keys import check_known, check_type


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


@pytest.mark.parametrize("value, hint, message", [
    ("abc", int, r"^toy setting n must be an int, not 'abc' \(method.params.n=...\)$"),
    (True, int, "must be an int, not True"),  # a bool is not a count
    (np.bool_(True), int, "must be an int, not"),  # numpy's neither
    (2.5, int, "must be an int, not 2.5"),
    (float("nan"), float, "must be a float, not nan"),
    ([1, "x"], tuple[int, ...], "must be a list of int values"),
    (None, float, "must be a float, not None"),
    ("big", float | None, "must be a float or None, not 'big'"),
    ("c", typing.Literal["a", "b"], r"^toy setting n must be one of a, b, not 'c' \(method.params.n=...\)$"),
    (3, dict, "must be a mapping of keys, not 3"),
    (5, list[int], "must be a list of int values, not 5"),
    (["x"], typing.Sequence[int], "must be a list of int values"),
    ({"a": "x"}, typing.Mapping[str, int], "must be a mapping of keys"),
])
def test_a_value_of_another_type_is_named_with_its_key_and_what_it_takes(value, hint, message):
    with pytest.raises(ValueError, match=message):
        check_type(value, hint, "toy setting", "n", "method.params.")


@pytest.mark.parametrize("value, hint", [(3, float), (2, int), (None, float | None), ([1, 2], tuple[int, ...]), ((1.0,), tuple[float, ...]),
                                         ("a", typing.Literal["a", "b"]), ({"k": 1}, dict), (False, bool), (float("inf"), float),
                                         (object(), typing.Any), ([1, 2], list[int]), ((1,), typing.Sequence[int]), ({"a": 1}, typing.Mapping[str, int]),
                                         (np.int64(2), int), (np.float32(0.5), float), (np.int32(3), float)])  # numpy's numbers
def test_a_value_of_its_type_passes(value, hint):
    check_type(value, hint, "toy setting", "n")


def test_a_reference_or_pbs_setting_of_another_type_is_named_before_a_simulation():
    """``method=pbs method.params.substeps=abc`` said only "invalid literal for int()"; the simulator's settings
    now name the key (the pbs method builds them as it starts)."""
    from drapebench.reference.settings import SimSettings

    with pytest.raises(ValueError, match="^reference setting substeps must be an int, not 'abc'$"):
        SimSettings.for_solver("vbd", substeps="abc")
    with pytest.raises(ValueError, match="reference setting retry_substeps must be a list of int values, not 5"):
        SimSettings.for_solver("vbd", retry_substeps=5)
    assert SimSettings.for_solver("style3d", retry_substeps=[8]).retry_substeps == (8,)  # a list stands for a tuple
    with pytest.raises(ValueError, match="unknown reference solver None; available: vbd, style3d"):  # the choices, not "must be a str"
        SimSettings(solver=None)
