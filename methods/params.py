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
import math
import types
import typing
from typing import Any, Literal, Mapping

from drapebench.keys import check_known
from drapebench.schema import TrainConf

TRAIN_KEYS = tuple(f.name for f in dataclasses.fields(TrainConf))  # what a method's ``schedule`` may set


def typed_params(cls: type, cfg: Mapping[str, Any] | None, method: str, section: str = ""):
    """An instance of the frozen dataclass ``cls`` with ``cfg`` (``method.params``, or one ``section`` of it, e.g.
    "train") over its defaults, nested dataclass fields built the same way. Raises ValueError naming an unknown key
    (and the valid ones) or a value outside a ``Literal``'s choices, worded "<method> [<section>] parameter ..."."""
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
                hint = entry_hints.get(key, _hint_of(defaults.get(key)))
                if hint is not None:
                    check_type(entry, hint, method, f"{path}.{key}")
            value = {**defaults, **value}
        else:
            check_type(value, hint, method, path)
        values[f.name] = value
    return cls(**values)


def check_type(value, hint, method: str, path: str) -> None:
    """Raise ValueError unless ``value`` fits the type ``hint`` of the parameter ``path`` (e.g. "train.lr") of
    ``method``: a ``Literal``'s choices, bool, int (not a bool), float (an int too; not NaN), str, ``X | None``,
    ``tuple[X, ...]`` (a list too), dict (any mapping); the message names the key as typed and what it takes. A
    mapping field's entries are checked against ``metadata["types"]``, else against the type of their default."""
    if typing.get_origin(hint) is Literal:
        if value not in typing.get_args(hint):
            raise ValueError(f"{method} parameter {path} must be one of {', '.join(map(str, typing.get_args(hint)))}, not {value!r}")
        return
    if not _fits(value, hint):
        raise ValueError(f"{method} parameter {path} must be {_describe(hint)}, not {value!r} (method.params.{path}=...)")


def _fits(value, hint) -> bool:
    """Whether ``value`` fits the type ``hint`` (:func:`check_type`'s rules)."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (typing.Union, types.UnionType):
        return any(_fits(value, h) for h in args)
    if origin is Literal:
        return value in args
    if hint is type(None):
        return value is None
    if hint is bool:
        return isinstance(value, bool)
    if hint is int:
        return isinstance(value, int) and not isinstance(value, bool)
    if hint is float:
        return _is_number(value) and not math.isnan(value)
    if hint is tuple or origin is tuple:
        if not isinstance(value, (list, tuple)):
            return False
        if len(args) == 2 and args[1] is Ellipsis:
            return all(_fits(v, args[0]) for v in value)
        return not args or len(value) == len(args) and all(map(_fits, value, args))
    if hint is dict or origin is dict:
        return isinstance(value, Mapping)
    return isinstance(value, hint) if isinstance(hint, type) else True


def _hint_of(default):
    """The type a mapping entry whose default is ``default`` takes: float for a number, the default's own type for a
    bool or str, None (anything) otherwise."""
    return float if _is_number(default) else type(default) if isinstance(default, (bool, str)) else None


def _is_number(value) -> bool:
    """Whether ``value`` is an int or a float (not a bool)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _describe(hint) -> str:
    """The type ``hint`` in words: "an int", "a float or None", "a list of float values"."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (typing.Union, types.UnionType):
        return " or ".join(_describe(h) for h in args)
    if hint is type(None):
        return "None"
    if hint is tuple or origin is tuple:
        return f"a list of {_describe(args[0]).split(' ', 1)[1]} values" if len(args) == 2 and args[1] is Ellipsis else "a list"
    if hint is dict or origin is dict:
        return "a mapping of keys"
    name = getattr(hint, "__name__", str(hint))
    return f"{'an' if name[0] in 'aeiou' else 'a'} {name}"


def params_dict(cls: type, cfg: Mapping[str, Any] | None, method: str) -> dict:
    """:func:`typed_params` as the nested dict the methods read (``dataclasses.asdict``: sections as dicts, tuples
    kept as tuples, the field order as declared)."""
    return dataclasses.asdict(typed_params(cls, cfg, method))


def schedule(**defaults):
    """A ``schedule`` field: values of the training budget (``conf/train``, :class:`drapebench.schema.TrainConf`'s
    keys) that a method sets otherwise, ``defaults`` unless ``method.params`` changes some."""
    return dataclasses.field(default_factory=lambda: dict(defaults), metadata={"keys": TRAIN_KEYS, "types": TrainConf})
