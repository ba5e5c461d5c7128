"""Progress bars on a terminal, progress lines in the log when stderr is not one (a log file, a pipe), quiet under CI."""

from __future__ import annotations

import logging
import os
import sys
import threading
import time
import weakref
from typing import Iterable, TypeVar

from tqdm.auto import tqdm

T = TypeVar("T")
LOG_EVERY_S = 5.0  # s: the least time between two logged progress lines (a run shorter than this logs none)
HEARTBEAT_S = 1.0  # s: how often a logged stage checks that the log has not gone silent while one of its steps runs
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
    """A file for tqdm that logs (logger ``drapebench``, INFO) a line at most every :data:`LOG_EVERY_S` seconds over
    all stages together, none before the first such interval has passed (a short run stays silent); a stage that ran
    that long logs its last line when it ends (``closing``), so the work after it starts from a fresh line."""

    last = time.monotonic()  # when any stage last logged a line (or this module was imported)

    def __init__(self) -> None:
        self.start, self.closing = time.monotonic(), False

    def write(self, text: str) -> None:
        text, now = text.strip(), time.monotonic()
        if text and (now - _LogLines.last >= LOG_EVERY_S or (self.closing and now - self.start >= LOG_EVERY_S)):
            logging.getLogger("drapebench").info("%s", text)
            _LogLines.last = now

    def flush(self) -> None:
        pass


class _LoggedBar(tqdm):
    """tqdm writing its lines to :class:`_LogLines`, which it tells when it closes. While it is open, a thread logs its
    line again (the same count, the time spent growing) whenever :data:`LOG_EVERY_S` has passed without a line, so a
    slow step (a large chunk, a loaded machine) does not leave the log silent until it ends."""

    def __init__(self, *args, **kw) -> None:
        self.lines = _LogLines()
        super().__init__(*args, file=self.lines, mininterval=1.0, miniters=1, bar_format=LOG_FORMAT, **kw)
        self.stopped = threading.Event()
        threading.Thread(target=_heartbeat, args=(weakref.ref(self), self.stopped), name=f"progress {self.desc}", daemon=True).start()

    def close(self) -> None:
        if hasattr(self, "stopped"):
            self.stopped.set()
        self.lines.closing = True
        super().close()


def _heartbeat(bar_ref: weakref.ref, stopped: threading.Event) -> None:
    """Every :data:`HEARTBEAT_S` until ``stopped`` is set or the bar is gone: the bar's line, marked as a step still
    running, when its count has not moved for :data:`LOG_EVERY_S` and no stage has logged a line for as long."""
    seen_n, seen_t = None, time.monotonic()
    while not stopped.wait(HEARTBEAT_S):
        bar = bar_ref()
        if bar is None:
            return
        now = time.monotonic()
        if bar.n != seen_n:
            seen_n, seen_t = bar.n, now
        elif now - seen_t >= LOG_EVERY_S and now - _LogLines.last >= LOG_EVERY_S:
            bar.lines.write(f"{bar} - a step still running")
        del bar


def progress(iterable: Iterable[T] | None = None, desc: str = "", total: int | None = None, unit: str = "it", **kw) -> tqdm:
    """A tqdm bar on a terminal; where stderr is none (:func:`progress_logged`), a log line with the count, the time
    spent and the estimate left at most every :data:`LOG_EVERY_S` s (over all stages: a new stage's first line comes
    as soon as that much time has passed since the last line) and the last line of a stage that ran that long;
    nothing under CI or ``DRAPEBENCH_PROGRESS=0``. Use ``.set_postfix`` for live figures, ``.update(n)`` for chunks."""
    if progress_logged():
        return _LoggedBar(iterable, desc=desc, total=total, unit=unit, **kw)
    return tqdm(iterable, desc=desc, total=total, unit=unit, disable=not progress_enabled(), dynamic_ncols=True, **kw)
