"""The one check of given keys against the keys something reads: an unknown key is a ValueError naming it, the
closest valid key and every valid one, so a typo in a config or a parameter never passes silently; and the check of
a given value against its field's type (:func:`check_type`), so a string for an int fails where it is read."""

from __future__ import annotations

import difflib
import math
import numbers
import types
import typing
from collections.abc import Iterable, Mapping, Sequence
from typing import Literal


def check_known(given: Iterable, valid: Iterable, what: str, where: str = "") -> None:
    """Raise ValueError when ``given`` (keys) holds one not in ``valid``, worded "unknown <what>(s) [...] <where>
    (did you mean '...'?); valid: [...]" (``what`` e.g. "material key", ``where`` e.g. "for motion 'walk'")."""
    valid = sorted(valid, key=str)
    unknown = sorted(set(given) - set(valid), key=str)
    if not unknown:
        return
    close = difflib.get_close_matches(str(unknown[0]), [str(v) for v in valid], n=1)
    hint = f" (did you mean {close[0]!r}?)" if close else ""
    raise ValueError(f"unknown {what}(s) {unknown}{' ' + where if where else ''}{hint}; valid: {valid}")


def check_type(value, hint, what: str, key: str, where: str = "") -> None:
    """Raise ValueError unless ``value`` fits the type ``hint`` of ``key`` (e.g. "train.lr"): a ``Literal``'s
    choices, bool, int (not a bool), float (an int too; not NaN, inf allowed), str, ``X | None``, ``tuple[X, ...]``,
    ``list[X]`` and ``Sequence[X]`` (a list or tuple), dict and ``Mapping[K, V]`` (any mapping), ``Any``. Worded
    "<what> <key> must be <type in words>, not <value> [(<where><key>=...)]" (``what`` e.g. "toy parameter",
    ``where`` the key's config prefix, e.g. "method.params.")."""
    if not _fits(value, hint):
        raise ValueError(f"{what} {key} must be {_describe(hint)}, not {value!r}{f' ({where}{key}=...)' if where else ''}")


def _fits(value, hint) -> bool:
    """Whether ``value`` fits the type ``hint`` (:func:`check_type`'s rules)."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if hint is typing.Any:
        return True
    if origin in (typing.Union, types.UnionType):
        return any(_fits(value, h) for h in args)
    if origin is Literal:
        return value in args
    if hint is type(None):
        return value is None
    if hint is bool:
        return isinstance(value, bool)
    if hint is int:
        return isinstance(value, numbers.Integral) and not isinstance(value, bool)
    if hint is float:
        return is_number(value) and not math.isnan(value)
    if hint in (tuple, list) or origin in (tuple, list, Sequence):
        if not isinstance(value, (list, tuple)):
            return False
        if origin is tuple and not (len(args) == 2 and args[1] is Ellipsis):
            return not args or len(value) == len(args) and all(map(_fits, value, args))
        return not args or all(_fits(v, args[0]) for v in value)
    if hint is dict or origin in (dict, Mapping):
        typed = len(args) == 2
        return isinstance(value, Mapping) and (not typed or all(_fits(k, args[0]) and _fits(v, args[1]) for k, v in value.items()))
    return isinstance(value, hint) if isinstance(hint, type) else True


def hint_of(default):
    """The type an entry whose default is ``default`` takes (for :func:`check_type`): float for a number, the
    default's own type for a bool or str, None (anything) otherwise."""
    return float if is_number(default) else type(default) if isinstance(default, (bool, str)) else None


def is_number(value) -> bool:
    """Whether ``value`` is a real number: an int or a float, numpy's included (not a bool)."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def is_finite_number(value) -> bool:
    """Whether ``value`` is a finite real number: an int or a float, numpy's included (not a bool, NaN or inf)."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool) and math.isfinite(value)


def _describe(hint) -> str:
    """The type ``hint`` in words: "an int", "a float or None", "a list of float values"."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (typing.Union, types.UnionType):
        return " or ".join(_describe(h) for h in args)
    if origin is Literal:
        return f"one of {', '.join(map(str, args))}"
    if hint is type(None):
        return "None"
    if hint in (tuple, list) or origin in (tuple, list, Sequence):
        of_one = args and (origin is not tuple or len(args) == 2 and args[1] is Ellipsis)
        return f"a list of {_describe(args[0]).split(' ', 1)[1]} values" if of_one else "a list"
    if hint is dict or origin in (dict, Mapping):
        return "a mapping of keys"
    name = getattr(hint, "__name__", str(hint))
    return f"{'an' if name[0] in 'aeiou' else 'a'} {name}"
