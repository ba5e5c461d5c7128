"""The one check of given keys against the keys something reads: an unknown key is a ValueError naming it, the
closest valid key and every valid one, so a typo in a config or a parameter never passes silently."""

from __future__ import annotations

import difflib
from typing import Iterable


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
