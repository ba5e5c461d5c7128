"""The committed table CSV: ``#`` provenance lines, a one- or two-row header, one row per method (or per run),
and a last line ``# sha256 <hex>``: the checksum of every byte above it.

:func:`write_csv` writes that footer (report.py and the benchmarks write their CSVs through it);
:func:`read_csv` reads a table strictly, so that a damaged table is an error naming the file and the line,
never a silently different score: bytes that are not UTF-8 text, a missing or wrong checksum (a truncated or
hand-edited file), a row of another width than the header, a row key that repeats, or a cell that is neither a
number (``1.2``, ``1.2 ± 0.3``, ``1.2 ± 0.3 (n=3)``) nor a placeholder of :data:`PLACEHOLDERS`.
"""

from __future__ import annotations

import csv
import hashlib
import io
import re
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from drapebench.cache import atomic_write

FOOTER = "# sha256 "
PLACEHOLDERS = ("–", "failed")  # not run / the run failed (report.py writes nothing else in a value cell)
NUMBER = re.compile(r"^\s*-?[\d.]+(?:e[-+]?\d+)?(?:\s*±\s*[\d.]+(?:e[-+]?\d+)?)?(?:\s*\(n=\d+\))?\s*$")


class TableError(ValueError):
    """A table file that cannot be trusted; the message names the file, the line and what to do."""


def seal(text: str) -> str:
    """``text`` (complete lines) with its checksum footer appended."""
    if text and not text.endswith("\n"):
        text += "\n"
    return f"{text}{FOOTER}{hashlib.sha256(text.encode()).hexdigest()}\n"


def write_csv(path: Path, comments, frame: pd.DataFrame, **to_csv) -> Path:
    """Write ``frame`` to ``path`` (atomically) under one ``# line`` per entry of ``comments``, sealed with its
    checksum footer; ``to_csv``: pandas' ``DataFrame.to_csv`` options. Returns ``path``."""
    buf = io.StringIO()
    buf.write("".join(f"# {line}\n" for line in comments))
    frame.to_csv(buf, **to_csv)
    with atomic_write(path, "w") as f:
        f.write(seal(buf.getvalue()))
    return Path(path)


def verified_text(path: Path) -> str:
    """The text of table ``path`` above its checksum footer, after checking the footer; raises
    :class:`TableError` naming the file (and the line) when it is not text, lacks its footer (truncated or written
    by hand) or does not match it (damaged or edited)."""
    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as err:
        raise TableError(f"{path}: cannot be read ({err.strerror})") from err
    if b"\0" in raw:
        line = raw[: raw.index(b"\0")].count(b"\n") + 1
        raise TableError(f"{path}: line {line}: a NUL byte: a binary file, not a table CSV")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as err:
        line = raw[: err.start].count(b"\n") + 1
        raise TableError(f"{path}: line {line}: not UTF-8 text (a binary or damaged file)") from err
    lines = text.splitlines(keepends=True)
    last = lines[-1] if lines else ""
    regenerate = "regenerate it (python -m drapebench.reproduce --tables " + path.stem.removesuffix("_gpu") + ")"
    if not last.startswith(FOOTER) or not last.endswith("\n"):
        raise TableError(f"{path}: line {len(lines)}: no checksum footer ('{FOOTER}<hex>' as the last line): the file is "
                         f"truncated or was not written by drapebench; {regenerate}")  # fmt: skip
    body = "".join(lines[:-1])
    if hashlib.sha256(body.encode()).hexdigest() != last[len(FOOTER):].strip():
        raise TableError(f"{path}: line {len(lines)}: the checksum does not match the {len(lines) - 1} lines above it: the "
                         f"file was damaged or edited by hand; {regenerate}")  # fmt: skip
    return body


@dataclass
class CsvTable:
    """A table file's parts: its ``#`` lines (without the ``# ``), its header rows, and its rows as
    (line number, cells) with the row key first."""

    path: Path
    comments: list
    header: list
    rows: list


def read_csv(path: Path, key_columns: int = 1, check_cells: bool = True) -> CsvTable:
    """Read table ``path`` strictly (checksum, widths, unique row keys: the first ``key_columns`` cells, the other
    cells a number or a placeholder); raises :class:`TableError` naming the file and the line. ``check_cells=False``
    checks the checksum and widths only: a table with a row per run, whose cells hold names and whose key repeats."""
    path = Path(path)
    body = verified_text(path)
    comments, header, rows = [], [], []
    for line, text in enumerate(body.splitlines(), start=1):
        if text.startswith("#"):
            comments.append(text[1:].strip())
            continue
        cells = next(csv.reader([text]))  # one record per line: report.py writes no line breaks inside cells
        if not header or (len(header) == 1 and cells[:1] == ["metric"]):  # a header, or a grouped table's metric row
            header.append(cells)
        elif len(header) == 2 and cells[:1] == ["method"] and not any(cells[1:]) and not rows:
            continue  # pandas' line naming the index under a two-row header
        else:
            rows.append((line, cells))
    if not header:
        raise TableError(f"{path}: no header line: the file holds no table")
    width = len(header[0])
    seen = {}
    for line, row in rows:
        if len(row) != width:
            raise TableError(f"{path}: line {line}: {len(row)} cells where the header has {width}")
        if not check_cells:
            continue
        key = ",".join(row[:key_columns])
        if key in seen:
            raise TableError(f"{path}: line {line}: row {key!r} repeats line {seen[key]}")
        seen[key] = line
        for j, cell in enumerate(row[key_columns:], start=key_columns):
            if cell not in PLACEHOLDERS and not NUMBER.match(cell):
                raise TableError(f"{path}: line {line}: column {j + 1} ({header[-1][j]!r}) holds {cell!r}, neither a number "
                                 f"nor one of {', '.join(PLACEHOLDERS)}")  # fmt: skip
    return CsvTable(path, comments, header, rows)

