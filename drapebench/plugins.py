"""What each method declares about its results, found through the method registry: the package of every
registered method (:func:`methods.available`; a method outside the repository joins the registry when its
import path is met, :func:`known_impl`) may hold the modules of :data:`DECLARATIONS`:

- ``metrics.py``: ``METRICS``, {name: :class:`drapebench.metric_info.MetricInfo`} of the diagnostics its
  :meth:`~methods.base.DrapingMethod.diagnostics` writes to ``metrics.json``;
- ``claims.py``: ``CLAIMS`` and ``MORE_CLAIMS`` (:class:`drapebench.claim.Claim` lists) of its paper, which the
  scoreboard lists as every method's ``CLAIMS``, then every method's ``MORE_CLAIMS``;
- ``tables.py``: ``TABLES`` (:class:`drapebench.table_specs.TableSpec` list) of the committed tables its paper's
  experiments make, and optionally ``SPEEDUP_REFERENCE`` (the row runtime tables give speed-ups over),
  ``REFERENCE_FLOOR`` ({row: what it is}: the rows that measure the reference's distance from itself) and
  ``QUICK`` (overrides that ``python -m drapebench.reproduce --quick`` adds to the runs of its methods: settings
  that only shorten a pipeline check, :func:`drapebench.reproduce.quick_extras`).

These modules describe results; they make none, so a method's code fingerprint leaves them out
(:mod:`drapebench.staleness`). The library itself names no method.
"""

from __future__ import annotations

import importlib
import importlib.util
import logging

DECLARATIONS = ("metrics", "claims", "tables")  # module names in a method's package
log = logging.getLogger(__name__)


def method_packages() -> list[str]:
    """The packages of the registered methods (the package of each registry target's module), each once, in the
    order of the registered names."""
    import methods

    modules = dict.fromkeys(methods.target(n).partition(":")[0] for n in methods.available())
    return list(dict.fromkeys(importlib.import_module(m).__package__ or m for m in modules))


def declared(module: str, attribute: str) -> list:
    """``[(package, value)]``: ``<package>.<module>.<attribute>`` of every method package that declares it (in
    :func:`method_packages` order)."""
    if module not in DECLARATIONS:
        raise ValueError(f"no declaration module {module!r}; they are {', '.join(DECLARATIONS)}")
    out = []
    for package in method_packages():
        name = f"{package}.{module}"
        try:
            found = importlib.util.find_spec(name)
        except ModuleNotFoundError:  # a method that is one module, not a package: it declares nothing
            found = None
        if found is None:
            continue
        value = getattr(importlib.import_module(name), attribute, None)
        if value is not None:
            out.append((package, value))
    return out


def known_impl(name: str, impl: str | None) -> None:
    """Register a run's method ``name`` under its import path ``impl`` ("package.module:Class") when it has one, so
    that its package's declarations are read beside the registered methods'; a registered name does nothing, and a
    path that does not import here is logged and left out (its diagnostics are then shown by their names)."""
    import methods

    if not impl or ":" not in impl or name in methods.available():
        return
    try:
        methods.get(impl)
    except (ImportError, TypeError) as err:
        log.warning("%s: %s; its declarations (labels of its diagnostics) are not read", name, err)
        return
    methods.register(name, impl)
