"""Method parameters: a method's defaults updated by ``method.params``, with unknown keys and invalid
choices rejected by name."""

from __future__ import annotations

from typing import Any, Mapping

from drapebench.keys import check_known


def method_params(method: str, cfg: Mapping[str, Any] | None, defaults: dict, nested: Mapping[str, dict] = (), choices: Mapping[str, tuple] = ()) -> dict:
    """``defaults`` updated by ``cfg``; each key of ``nested`` (e.g. "train") is a sub-dict that updates its own
    defaults. Raises ValueError naming an unknown key (and the valid ones) or a value outside ``choices``."""
    cfg = dict(cfg or {})
    check_known(cfg, defaults, f"{method} parameter")
    p = {**defaults, **cfg}
    for key, sub_defaults in dict(nested).items():
        sub = dict(cfg.get(key) or {})
        check_known(sub, sub_defaults, f"{method} {key} parameter", f"(method.params.{key})")
        p[key] = {**sub_defaults, **sub}
    for key, allowed in dict(choices).items():
        if p[key] not in allowed:
            raise ValueError(f"{method} parameter {key} must be one of {', '.join(allowed)}, not {p[key]!r}")
    return p
