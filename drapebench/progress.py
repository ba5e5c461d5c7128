"""Progress bars on a terminal, progress lines in the log when stderr is not one (a log file, a pipe), quiet under CI."""

from __future__ import annotations

import logging
import os
import sys
import time
from typing import Iterable, TypeVar

from tqdm.auto import tqdm

T = TypeVar("T")
LOG_EVERY_S = 5.0  # s: the time between two logged progress lines (a stage shorter than this logs none)
LOG_FORMAT = "{desc}: {n_fmt}/{total_fmt} {unit} ({percentage:.0f} %) in {elapsed}, about {remaining} left ({rate_fmt})"


def progress_enabled() -> bool:
    """True unless ``CI`` is set, ``DRAPEBENCH_PROGRESS=0``, or stderr is not a TTY."""
    if os.environ.get("DRAPEBENCH_PROGRESS") == "1":
        return True
    if os.environ.get("CI") or os.environ.get("DRAPEBENCH_PROGRESS") == "0":
        return False
    return sys.stderr.isatty()


def progress_logged() -> bool:
    """True when no bar is drawn only because stderr is not a terminal: progress then goes to the log."""
    return not progress_enabled() and not (os.environ.get("CI") or os.environ.get("DRAPEBENCH_PROGRESS") == "0")


class _LogLines:
    """A file for tqdm that logs (logger ``drapebench``, INFO) a line at most every :data:`LOG_EVERY_S` seconds, none
    before the first such interval has passed (a short loop stays silent)."""

    def __init__(self) -> None:
        self.last = time.monotonic()

    def write(self, text: str) -> None:
        text = text.strip()
        if text and time.monotonic() - self.last >= LOG_EVERY_S:
            logging.getLogger("drapebench").info("%s", text)
            self.last = time.monotonic()

    def flush(self) -> None:
        pass


def progress(iterable: Iterable[T] | None = None, desc: str = "", total: int | None = None, unit: str = "it", **kw) -> tqdm:
    """A tqdm bar on a terminal; where stderr is none (:func:`progress_logged`), a log line with the count, the time
    spent and the estimate left every :data:`LOG_EVERY_S` s; nothing under CI or ``DRAPEBENCH_PROGRESS=0``. Use
    ``.set_postfix`` for live figures, ``.update(n)`` for chunks."""
    if progress_logged():
        return tqdm(iterable, desc=desc, total=total, unit=unit, file=_LogLines(), mininterval=1.0, miniters=1, bar_format=LOG_FORMAT, **kw)
    return tqdm(iterable, desc=desc, total=total, unit=unit, disable=not progress_enabled(), dynamic_ncols=True, **kw)
