"""Package exports imported at first use (PEP 562), so that importing one light submodule of a package (e.g.
``drapebench.physics.material`` for the config schema) does not import the package's heavy ones (torch)."""

from __future__ import annotations

import importlib


def exports(package: str, names: dict[str, str]):
    """A module-level ``__getattr__`` for ``package`` that returns each of ``names`` ({name: submodule name}) from
    its submodule, importing it the first time; AttributeError for any other name."""

    def __getattr__(name: str):
        if name not in names:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        return getattr(importlib.import_module(f"{package}.{names[name]}"), name)

    return __getattr__
