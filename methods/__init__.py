"""Registry of draping methods: ``methods.get(name)`` returns the class, ``methods.available()`` the names.

Each method lives in its own sub-package, listed in :data:`_REGISTRY` (imported lazily). A method outside this
repository needs no entry: its ``conf/method/<name>.yaml`` names it by its import path, ``impl: package.module:Class``
(the package on the Python path), and :func:`get` imports it. Ablations that are configurations of the same code
(e.g. ``gaps_kext1``) are Hydra ``method=`` configs whose ``name`` labels the rows and whose ``impl`` names the class.
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


def target(name: str) -> str:
    """The import path ("package.module:Class") registered as ``name``; KeyError listing the registered names."""
    if name not in _REGISTRY:
        raise KeyError(f"unknown method {name!r}; available methods: {', '.join(available())}")
    return _REGISTRY[name]


def get(name: str) -> type[DrapingMethod]:
    """The method class registered as ``name``, or the class an import path "package.module:Class" names (a
    :class:`DrapingMethod` subclass). Raises KeyError listing the registered names for an unknown name, and
    ImportError / TypeError naming the path for a path that does not lead to a method class."""
    target = name if ":" in name else _REGISTRY.get(name)
    if target is None:
        raise KeyError(f"unknown method {name!r}; available methods: {', '.join(available())} "
                       "(or method.impl=package.module:Class for a method of your own)")  # fmt: skip
    module, _, cls_name = target.partition(":")
    try:
        cls = getattr(importlib.import_module(module), cls_name)
    except (ImportError, AttributeError) as err:
        raise ImportError(f"method.impl={target!r}: {err} (the package must be on the Python path, e.g. PYTHONPATH)") from err
    if not (isinstance(cls, type) and issubclass(cls, DrapingMethod)):
        raise TypeError(f"method.impl={target!r} is not a methods.base.DrapingMethod subclass")
    return cls


__all__ = ["DrapeResult", "DrapingMethod", "FitReport", "available", "get", "register", "target"]
