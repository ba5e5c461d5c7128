"""Progress bars that stay quiet under CI and when stderr is not a terminal."""

from __future__ import annotations

import os
import sys
from typing import Iterable, TypeVar

from tqdm.auto import tqdm

T = TypeVar("T")


def progress_enabled() -> bool:
    """True unless ``CI`` is set, ``DRAPEBENCH_PROGRESS=0``, or stderr is not a TTY."""
    if os.environ.get("DRAPEBENCH_PROGRESS") == "1":
        return True
    if os.environ.get("CI") or os.environ.get("DRAPEBENCH_PROGRESS") == "0":
        return False
    return sys.stderr.isatty()


def progress(iterable: Iterable[T] | None = None, desc: str = "", total: int | None = None, unit: str = "it", **kw) -> tqdm:
    """A tqdm bar (disabled per :func:`progress_enabled`); use ``.set_postfix`` for live figures."""
    return tqdm(iterable, desc=desc, total=total, unit=unit, disable=not progress_enabled(), dynamic_ncols=True, **kw)
