"""Method parameters, typed: a method declares its settings as one frozen dataclass (its sections, e.g. ``train``,
nested dataclasses) and :func:`typed_params` builds it from ``method.params``, the one check of every method's keys.

Given keys update the defaults: a nested section key by key, a mapping field (a dict default such as a ``schedule``)
key by key as well. An unknown key, at any depth, is a ValueError naming it and the valid keys; a value of another
type than its field's (a string for an int, a scalar for a section, NaN for a float) or outside a ``Literal`` field's
choices names the key and what it takes. Values are kept as given (no conversion; an int stands for a float): the
parameters hash into checkpoint keys as before. A field's ``metadata["keys"]`` lists the keys its mapping may hold,
``metadata["types"]`` a dataclass whose fields type them."""

from __future__ import annotations

import dataclasses
import typing
from typing import Any, Mapping

from drapebench.keys import check_known, check_type, hint_of, is_number
from drapebench.schema import TrainConf

TRAIN_KEYS = tuple(f.name for f in dataclasses.fields(TrainConf))  # what a method's ``schedule`` may set


def typed_params(cls: type, cfg: Mapping[str, Any] | None, method: str, section: str = ""):
    """An instance of the frozen dataclass ``cls`` with ``cfg`` (``method.params``, or one ``section`` of it, e.g.
    "train") over its defaults, nested dataclass fields built the same way. Raises ValueError naming an unknown key
    (and the valid ones), a value of another type than its field (:func:`drapebench.keys.check_type`; a section
    given as a scalar or null) or outside a ``Literal``'s choices, worded "<method> [<section>] parameter ..."."""
    if cfg is not None and not isinstance(cfg, Mapping) or cfg is None and section:
        raise ValueError(f"{method} parameter {section or 'params'} is a section of keys ({', '.join(f.name for f in dataclasses.fields(cls))}), "
                         f"not {cfg!r}: set its keys one by one (method.params.{section + '.' if section else ''}<key>=...)")
    cfg = dict(cfg or {})
    hints = typing.get_type_hints(cls)
    what = f"{method} {section} parameter" if section else f"{method} parameter"
    check_known(cfg, [f.name for f in dataclasses.fields(cls)], what, f"(method.params.{section})" if section else "")
    values = {}
    for f in dataclasses.fields(cls):
        if f.name not in cfg:
            continue
        value, hint, path = cfg[f.name], hints[f.name], f"{section}.{f.name}" if section else f.name
        if dataclasses.is_dataclass(hint):
            value = typed_params(hint, value, method, path)
        elif isinstance(value, Mapping) and f.default_factory is not dataclasses.MISSING:
            check_known(value, f.metadata.get("keys", value), f"{method} {path} parameter", f"(method.params.{path})")
            defaults = f.default_factory()
            entry_hints = typing.get_type_hints(f.metadata["types"]) if "types" in f.metadata else {}
            for key, entry in value.items():
                hint = entry_hints.get(key, hint_of(defaults.get(key)))
                if hint is not None:
                    check_type(entry, hint, f"{method} parameter", f"{path}.{key}", "method.params.")
            value = {**defaults, **value}
        else:
            check_type(value, hint, f"{method} parameter", path, "method.params.")
        values[f.name] = value
    return cls(**values)


def params_dict(cls: type, cfg: Mapping[str, Any] | None, method: str, section: str = "") -> dict:
    """:func:`typed_params` as the nested dict the methods read (``dataclasses.asdict``: sections as dicts, tuples
    kept as tuples, the field order as declared); ``section``: the section of ``method.params`` that ``cfg`` is."""
    return dataclasses.asdict(typed_params(cls, cfg, method, section))


def schedule(**defaults):
    """A ``schedule`` field: values of the training budget (``conf/train``, :class:`drapebench.schema.TrainConf`'s
    keys) that a method sets otherwise, ``defaults`` unless ``method.params`` changes some."""
    return dataclasses.field(default_factory=lambda: dict(defaults), metadata={"keys": TRAIN_KEYS, "types": TrainConf})


def at_least(method: str, section: str, params, **least) -> None:
    """Raise ValueError naming ``method.params.<section><key>`` for the first key of ``least`` whose value in
    ``params`` (a parameters dataclass) is not a number at least its bound (NaN included). ``section``: "" or
    e.g. "train."."""
    for key, bound in least.items():
        value = getattr(params, key)
        if not is_number(value) or not value >= bound:
            raise ValueError(f"{method} parameter method.params.{section}{key} must be >= {bound}, got {value!r}")


def positive(method: str, section: str, params, *keys: str) -> None:
    """Raise ValueError naming ``method.params.<section><key>`` for the first of ``keys`` whose value in ``params``
    is not a positive number."""
    for key in keys:
        value = getattr(params, key)
        if not is_number(value) or not value > 0:
            raise ValueError(f"{method} parameter method.params.{section}{key} must be > 0, got {value!r}")
