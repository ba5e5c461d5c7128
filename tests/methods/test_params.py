"""methods.params.typed_params: the one check of every method's parameters (unknown keys and choices named at any
depth), given keys over the defaults (sections and mappings key by key), values kept as given."""

from dataclasses import dataclass, field
from typing import Literal

import pytest

from methods.params import schedule, typed_params


@dataclass(frozen=True)
class Inner:
    mode: Literal["a", "b"] = "a"
    size: float = 1.5
    schedule: dict = schedule(epochs=3, lr=1e-3)


@dataclass(frozen=True)
class Outer:
    kind: Literal["x", "y"] = "x"
    grid: tuple[float, ...] = (1.0, 2.0)
    free: dict = field(default_factory=dict)
    inner: Inner = field(default_factory=Inner)


def test_given_keys_update_the_defaults_at_every_depth_and_keep_their_values():
    p = typed_params(Outer, {"kind": "y", "free": {"any": 1}, "inner": {"size": 2, "schedule": {"lr": 0.5}}}, "toy")
    assert p == Outer(kind="y", free={"any": 1}, inner=Inner(size=2, schedule={"epochs": 3, "lr": 0.5}))
    assert type(p.inner.size) is int  # kept as given: the parameters hash into checkpoint keys as they were typed
    assert typed_params(Outer, None, "toy") == Outer() and typed_params(Outer, {"inner": {}}, "toy") == Outer()


def test_unknown_keys_and_choices_are_named_with_their_path_and_the_valid_ones():
    with pytest.raises(ValueError, match=r"unknown toy parameter\(s\) \['knid'\] \(did you mean 'kind'\?\); valid: \['free', 'grid', 'inner', 'kind'\]"):
        typed_params(Outer, {"knid": "x"}, "toy")
    with pytest.raises(ValueError, match=r"unknown toy inner parameter\(s\) \['sise'\] \(method.params.inner\) \(did you mean 'size'\?\)"):
        typed_params(Outer, {"inner": {"sise": 1.0}}, "toy")
    with pytest.raises(ValueError, match=r"unknown toy inner.schedule parameter\(s\) \['epoch'\] \(method.params.inner.schedule\) \(did you mean 'epochs'\?\); valid: \['batch_size'"):
        typed_params(Outer, {"inner": {"schedule": {"epoch": 1}}}, "toy")  # a schedule holds the budget's (conf/train) keys
    with pytest.raises(ValueError, match=r"^toy parameter kind must be one of x, y, not 'z' \(method.params.kind=...\)$"):
        typed_params(Outer, {"kind": "z"}, "toy")
    with pytest.raises(ValueError, match=r"^toy parameter inner.mode must be one of a, b, not 'c' \(method.params.inner.mode=...\)$"):
        typed_params(Outer, {"inner": {"mode": "c"}}, "toy")


def test_a_partial_schedule_changes_only_the_keys_given():
    """``method.params.vae.schedule={epochs: 5}`` keeps the VAE's other schedule values (it replaced them all before)."""
    from methods.vae.config import vae_params

    default = vae_params(None)["vae"]["schedule"]
    changed = vae_params({"vae": {"schedule": {"epochs": 5}}})["vae"]["schedule"]
    assert changed == {**default, "epochs": 5} and default["batch_size"] == 32 and default["epochs"] == 60


@pytest.mark.parametrize("given, message", [
    ({"inner": {"size": "abc"}}, r"toy parameter inner.size must be a float, not 'abc' \(method.params.inner.size=...\)"),
    ({"inner": {"size": float("nan")}}, r"inner.size must be a float, not nan"),
    ({"inner": {"size": True}}, r"inner.size must be a float, not True"),
    ({"grid": 2.0}, r"grid must be a list of float values, not 2.0"),
    ({"grid": [1.0, "a"]}, r"grid must be a list of float values"),
    ({"inner": {"schedule": {"epochs": 2.5}}}, r"inner.schedule.epochs must be an int, not 2.5"),  # typed as conf/train's keys
    ({"inner": {"schedule": {"lr": "fast"}}}, r"inner.schedule.lr must be a float, not 'fast'"),
    ({"inner": {"schedule": None}}, r"inner.schedule must be a mapping of keys, not None"),
    ({"inner": 5}, r"toy parameter inner is a section of keys \(mode, size, schedule\), not 5: set its keys one by one \(method.params.inner.<key>=...\)"),
    ({"inner": None}, r"toy parameter inner is a section of keys"),  # not silently the defaults: a preset's keys would be lost
])
def test_a_value_of_another_type_than_its_field_is_named_with_its_key_and_what_it_takes(given, message):
    with pytest.raises(ValueError, match=message):
        typed_params(Outer, given, "toy")


def test_a_mapping_entry_takes_the_type_of_its_default_and_steps_may_be_none():
    from methods.gensim.config import gensim_params

    assert gensim_params({"weights": {"bending": 2}})["weights"]["bending"] == 2  # an int stands for a float
    with pytest.raises(ValueError, match=r"gensim parameter weights.bending must be a float, not 'abc'"):
        gensim_params({"weights": {"bending": "abc"}})
    assert typed_params(Outer, {"inner": {"schedule": {"steps": None, "grad_clip": 1}}}, "toy").inner.schedule["steps"] is None


@pytest.mark.parametrize("given, message", [
    ({"rbf_k": 0}, r"^gaps parameter method.params.rbf_k must be > 0, got 0$"),  # every RBF weight 0/0: NaN skinning
    ({"hidden": 0}, r"method.params.hidden must be >= 1, got 0"),
    ({"collision_eps": -0.001}, r"method.params.collision_eps must be >= 0"),
    ({"relax_inextensibility_weight": -1.0}, r"method.params.relax_inextensibility_weight must be >= 0"),
    ({"relax_grid": []}, r"method.params.relax_grid lists the shape-offset values"),
    ({"train": {"window": 2}}, r"method.params.train.window must be >= 3, got 2"),  # inertia reads two frames before the last
    ({"train": {"kext_ramp_epochs": 0}}, r"method.params.train.kext_ramp_epochs must be >= 1, got 0"),  # the ramp divides by it
    ({"train": {"output_adam_eps": 0.0}}, r"method.params.train.output_adam_eps must be > 0"),
    ({"train": {"beta_range": [2.0, -1.0]}}, r"method.params.train.beta_range holds the half-widths \(>= 0\)"),
])
def test_a_gaps_value_out_of_its_range_is_named_before_the_scene_is_built(given, message):
    from methods.gaps.config import gaps_params

    with pytest.raises(ValueError, match=message):
        gaps_params(given)
    assert gaps_params({"collision_eps": 0, "relax_inextensibility_weight": None})["collision_eps"] == 0  # the bounds themselves pass


def test_a_section_of_method_params_is_named_with_its_path():
    """gaps_optimum's solver settings are ``method.params.optimum``: a bad key names that path, and a section set
    to null is refused instead of silently taking the defaults."""
    from methods.gaps.config import optimum_params

    with pytest.raises(ValueError, match=r"optimum.iterations must be an int, not 'x' \(method.params.optimum.iterations=...\)"):
        optimum_params({"iterations": "x"})
    with pytest.raises(ValueError, match=r"gaps_optimum parameter optimum is a section of keys"):
        optimum_params(None)
    assert optimum_params({})["solver"] == "lbfgs"
