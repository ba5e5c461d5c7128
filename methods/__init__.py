"""Registry of draping methods: ``methods.get(name)`` returns the class, ``methods.available()`` the names.

Each method lives in its own sub-package and registers with :func:`register`. Ablations that are
configurations of the same code (e.g. ``gaps_kext1``) are Hydra ``method=`` configs whose
``name`` field selects the class registered under their ``impl`` name.
"""

from __future__ import annotations

import importlib

from methods.base import DrapeResult, DrapingMethod, FitReport

_REGISTRY: dict[str, str] = {
    # name -> "module:Class"; imported lazily so one method's heavy deps never load for another.
    "lbs": "methods.lbs:LBSMethod",
    "gaps": "methods.gaps:GAPS",
    "gaps_optimum": "methods.gaps:GapsOptimum",
    "pbs": "methods.pbs:PBSMethod",
    "gensim": "methods.gensim:GenSim",
    "gensim_optimum": "methods.gensim:GensimOptimum",
    "vae": "methods.vae:VAEModel",
}


def register(name: str, target: str) -> None:
    """Register ``target`` ("package.module:Class") under ``name``."""
    _REGISTRY[name] = target


def available() -> list[str]:
    """Sorted names of registered methods."""
    return sorted(_REGISTRY)


def get(name: str) -> type[DrapingMethod]:
    """The method class registered as ``name``; raises KeyError listing valid names."""
    try:
        target = _REGISTRY[name]
    except KeyError:
        raise KeyError(f"unknown method {name!r}; available methods: {', '.join(available())}") from None
    module, cls = target.split(":")
    return getattr(importlib.import_module(module), cls)


__all__ = ["DrapeResult", "DrapingMethod", "FitReport", "available", "get", "register"]
