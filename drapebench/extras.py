"""The optional dependencies (pyproject's extras) and the one way to import them.

The core install (``pip install drapebench``) imports the package, builds bodies, sequences and training
data, trains and drapes every learned method and computes every metric (the signed distance on libigl's
exact path without warp, :mod:`drapebench.geometry.sdf`). Heavier packages are imported by the code that
needs them, through :func:`require`, which names the extra to install when one is missing:

- ``sim``: warp-lang and newton, the physics-based reference simulator (and the fast warp BVH path of the
  signed distance);
- ``viz``: rerun-sdk, the ``drape.rrd`` recordings of ``viz=rerun``;
- ``mesh``: pymeshlab, the remesher that makes a parametric garment (once per garment; the result is cached
  in ``data/cache/garments``) and the garment validator's self-intersection check;
- ``export``: usd-core, ``export=usd``.
"""

from __future__ import annotations

import importlib
from types import ModuleType

# top-level module -> (extra, the pip distribution)
EXTRAS: dict[str, tuple[str, str]] = {
    "warp": ("sim", "warp-lang"),
    "newton": ("sim", "newton"),
    "rerun": ("viz", "rerun-sdk"),
    "pymeshlab": ("mesh", "pymeshlab"),
    "pxr": ("export", "usd-core"),
}


class MissingExtra(ImportError):
    """An optional dependency is not installed; the message names the extra that installs it."""


def require(module: str, purpose: str) -> ModuleType:
    """Import and return ``module`` (e.g. "rerun.blueprint"), whose top-level package is one of :data:`EXTRAS`;
    raise :class:`MissingExtra` naming ``purpose`` (what needs it) and the ``pip install`` that brings it
    when that package is missing. An ImportError raised inside an installed package is not masked."""
    top = module.split(".")[0]
    extra, dist = EXTRAS[top]
    try:
        return importlib.import_module(module)
    except ImportError as err:
        if err.name not in (top, module):  # the package is there and failed to import: its own error
            raise
        raise MissingExtra(f"{purpose} needs {dist}, which is not installed: pip install 'drapebench[{extra}]' "
                           f"(from a checkout: pip install -e '.[{extra}]')") from err  # fmt: skip

