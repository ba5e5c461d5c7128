"""The claims scoreboard: each headline claim of the three papers, tested against the committed tables.

``python -m drapebench.report --claims`` reads the tables the claims name in ``reports/`` (and their ``_gpu``
twins, made with ``device=cuda train=paper``), strictly (:mod:`drapebench.table_file`), and writes
``reports/claims.md``: per claim the paper's figure, ours (mean ± std over seeds where a cell has several), the
claim's control, a verdict by the rules of :data:`RULES`, and the table and experiment behind it. The verdicts
depend on the CSVs and on the methods' code the rows were run with (:mod:`drapebench.staleness`); claims.md
records the code fingerprints it was judged against, so a test regenerates it and compares.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from decimal import Decimal
from pathlib import Path

import numpy as np
import pandas as pd

from drapebench.cache import PROJECT_ROOT, atomic_write
from drapebench.claim import Claim
from drapebench.staleness import current_code, stale_rows, track_of
from drapebench.table_file import read_csv
from drapebench.table_specs import owner, specs

CELL = re.compile(r"^\s*(-?[\d.]+(?:e[-+]?\d+)?)(?:\s*±\s*([\d.]+(?:e[-+]?\d+)?))?(?:\s*\(n=(\d+)\))?\s*$")
NO_SEEDS = 10**6  # the seed count of a paper's bound: exact, no spread


@dataclass(frozen=True)
class Value:
    """One table cell: its mean, the std over seeds (nan for one seed: a "± std" without n is over frames), the
    number of seeds and its resolution: half the last digit it was printed with (a cell "0.013 ± 0.000 (n=3)" is
    known to ± 0.0005; 0 for an exact bound; not part of its equality, which is the numbers')."""

    mean: float
    std: float
    n: int
    resolution: float = field(default=0.0, compare=False)

    def text(self) -> str:
        """The value as the claims table shows it: 3 significant digits, "± std (n=k)" over seeds."""
        mean = f"{self.mean:,.0f}" if abs(self.mean) >= 1000 else f"{self.mean:.3g}"
        return mean + (f" ± {self.std:.2g} (n={self.n})" if 1 < self.n < NO_SEEDS else "")

    def spread(self) -> float:
        """The half-width of the value's band: its std over seeds (0 for one seed or an exact bound), and at least
        its resolution (a std printed as 0 is under half the last digit, not zero)."""
        return max(self.std if 1 < self.n < NO_SEEDS else 0.0, self.resolution)


def _half_digit(number: str) -> float:
    """Half a unit of the last digit ``number`` (as printed) shows: "0.013" -> 0.0005, "12" -> 0.5."""
    return 0.5 * 10.0 ** Decimal(number).as_tuple().exponent


def parse_cell(cell) -> Value | None:
    """A table cell ("1.23", "1.23 ± 0.45", "1.23 ± 0.45 (n=3)") as a :class:`Value`; None for "–", "failed" or
    anything else that is not a number."""
    m = CELL.match(str(cell))
    if not m:
        return None
    n = int(m.group(3) or 1)
    resolution = min(_half_digit(x) for x in m.group(1, 2) if x is not None)  # report.py prints both with one precision
    return Value(float(m.group(1)), float(m.group(2)) if n > 1 else float("nan"), n, resolution)


@dataclass
class Table:
    """A committed table read from its CSV: cells keyed by (row, column group, metric label) (group "" for a
    table without groups), its groups in order, the commits of its provenance line and, where it names them, the
    commits of each row and those whose code trained a row's models when they are not its runs' ("unrecorded": a
    model cached before that was recorded), and the track its rows are judged on (its presets note, else its name's:
    :func:`drapebench.staleness.track_of`)."""

    name: str
    cells: dict
    groups: list
    commits: list
    row_commits: dict = field(default_factory=dict)
    trained_at: dict = field(default_factory=dict)
    track: str = "cpu"

    def get(self, row: str, group: str, metric: str) -> Value | None:
        """The parsed cell, None where the table lacks it or it holds no number."""
        return parse_cell(self.cells.get((row, group, metric), "–"))

    def rows(self) -> list:
        """The table's rows, in order."""
        return list(dict.fromkeys(r for r, _, _ in self.cells))


_COMMIT = r"[0-9a-f]{4,40}(?:-dirty)?"  # a commit as the tables write it (report.short_commit, or whole)
_TRAINED = rf"(?:{_COMMIT}|unrecorded|unknown)"  # a commit that trained a model, as report.trained_note writes it


def _provenance(comments: list, name: str) -> tuple[list, dict, dict, str]:
    """(the commits of a table's provenance line, {row: its commits} from its mixed-commits note, {row: the commits
    that trained its models} from its trained-at note, the track its rows are judged on: its presets note's, "cpu" or
    "<train>+<data>" where they differ, else its name's, :func:`track_of`) of the ``#`` lines of the table ``name``."""
    commits = re.search(rf"commit\(?s?\)? ({_COMMIT}(?:, {_COMMIT})*)(?: on | \(|\.|$)", comments[0]) if comments else None
    commits = [c.strip() for c in commits.group(1).split(",")] if commits else []
    mixed = next((c for c in comments if c.startswith("**Mixed commits**")), "")
    row_commits = {m.group(1): [c.strip() for c in m.group(2).split(",")]
                   for m in re.finditer(rf"([\w.-]+) ({_COMMIT}(?:, {_COMMIT})*)(?=;|\.$)", mixed.split(": ", 1)[-1])}  # fmt: skip
    cached = next((c for c in comments if c.startswith("**Models trained at**")), "")
    trained_at = {m.group(1): [c.strip() for c in m.group(2).split(",")]
                  for m in re.finditer(rf"([\w.-]+) ({_TRAINED}(?:, {_TRAINED})*)(?=;|\.$)", cached.rsplit(": ", 1)[-1])}  # fmt: skip
    presets = next((re.fullmatch(r"\*\*Presets\*\*: train=([\w.-]+), data=([\w.-]+)\.", c) for c in comments
                    if c.startswith("**Presets**")), None)  # fmt: skip
    track = track_of(name) if presets is None else presets.group(1) if presets.group(1) == presets.group(2) else "+".join(presets.groups())
    return commits, row_commits, trained_at, track


def read_table(path: Path) -> Table:
    """A table's CSV (``#`` provenance lines, a one- or two-row header, a checksum footer) as a :class:`Table`;
    raises :class:`drapebench.table_file.TableError` naming the file and line of anything it cannot trust."""
    f = read_csv(path)
    commits, row_commits, trained_at, track = _provenance(f.comments, Path(path).stem)
    metrics = f.header[-1]
    groups = f.header[0] if len(f.header) == 2 else [""] * len(metrics)
    cells = {(cells[0], groups[j], metrics[j]): cells[j] for _, cells in f.rows for j in range(1, len(cells))}
    return Table(Path(path).stem, cells, list(dict.fromkeys(groups[1:])), commits, row_commits, trained_at, track)


KINDS = ("order", "order_groups", "level", "within", "untested")
VERDICTS = ("reproduced", "holds, one seed", "holds, control not run", "partly", "scene-determined", "inside the spread",
            "too small to tell", "not reproduced, one seed", "not reproduced", "stale", "not run", "not testable here")  # fmt: skip
RULES = (
    "A claim is tested case by case (a group x metric x pair of rows; cases with the same numbers, a quantity that "
    "does not depend on the group, count once where their controls' numbers repeat too). A case **holds** when its "
    "relation holds on the means, the two bands "
    "mean ± std over seeds (at least ± half the last printed digit) do not overlap (a level: the band stays under the "
    "bound, itself a band where it scales or adds a measured value) and the difference is at least "
    "the metric's resolution floor (below); a case whose bands overlap is a **tie**, one whose difference is under the "
    "floor is **too small to tell**, and neither counts. Every claim names its **control** (lbs, the method's untrained "
    "or ARAP stage, or its loss's optimum, put in place of the row the claim credits); a case is credited to the "
    "method only where the control's means fail it: one the control holds, or meets on its means inside the bands "
    "or the floor, is credited to the scene. Verdicts: **reproduced**: every case holds for the method and "
    "not for the control, each cell over several seeds; **holds, one seed**: the same with a one-seed cell (spread "
    "unknown); **holds, control not run**: it holds but the table lacks a control the claim names (or its cells); "
    "**partly (k/m)**: k of m distinct cases hold (and the control fails them; \", control not run\" where a "
    "control is missing); **scene-determined**: the cases that hold, the control "
    "meets them too; **inside the spread**: no case holds or fails beyond the bands; **too small to tell**: every difference is "
    "under the floor; **not reproduced**: no case holds and one holds the other way (**not reproduced, one seed**: "
    "each such case on one-seed cells, spread unknown); **stale: ...**: a row it reads "
    "comes from another commit than its table's or from method code that has changed since, or its model was trained "
    "(and cached) by such code (what its rows "
    "would give follows, *holds* where they would reproduce it: a stale claim can hold, never reproduce); **not run**: a cell it needs is missing or failed; **not "
    "testable here**: no committed table can test it (what it needs is said). A level on a scene unlike the paper's "
    "is marked *indicative*."
)


def resolution_floors(tables: dict) -> dict:
    """{(table, metric label): (floor, cells, identical)} and {metric label: (...)}: a metric's floor in a table is
    the median seeds' std of its multi-seed cells there that have a spread (what two seeds of one method typically
    differ by on that scene), with the number of such cells and of cells whose seeds agree to the printed digit
    (their std prints as 0: deterministic rows, or a spread under the last digit). Untrained rows (``<m>_untrained``)
    are left out: their spread is that of random initialisations, not what a measurement can resolve. The metric's
    own entry pools every CPU table of ``tables`` (name -> :class:`Table`), for a table without multi-seed cells of
    it; a metric with none is absent (floor 0)."""
    spreads: dict = {}
    for name, t in tables.items():
        if name.endswith("_gpu"):
            continue
        for (row, _, metric), cell in t.cells.items():
            if row.endswith("_untrained"):
                continue
            v = parse_cell(cell)
            if v is not None and v.n > 1:
                for key in ((name, metric), metric):
                    spreads.setdefault(key, []).append(v.std)
    out = {}
    for key, s in spreads.items():
        moving = [x for x in s if x > 0]
        if moving:
            out[key] = (float(np.median(moving)), len(moving), len(s) - len(moving))
    return out


def floor_of(floors: dict, table: str, metric: str) -> float:
    """The resolution floor of ``metric`` in ``table`` (:func:`resolution_floors`; {key: floor}), 0 where none was
    measured."""
    return floors.get((table, metric), floors.get(metric, 0.0))


@dataclass(frozen=True)
class Case:
    """One comparison of a claim: ``hi`` (a row, or "bound") above ``lo``, at ``where``."""

    where: str
    metric: str
    hi: str
    lo: str
    vhi: Value
    vlo: Value

    def key(self) -> tuple:
        """What makes two cases the same numbers."""
        same = lambda v: (v.mean, v.std if 1 < v.n < NO_SEEDS else None, v.n)  # noqa: E731
        return (self.metric, self.hi, self.lo, same(self.vhi), same(self.vlo))

    def outcome(self, floor: float) -> str:
        """"holds", "against" (the other way, beyond bands and floor), "tie" (the bands overlap) or "small" (the
        difference is under ``floor``)."""
        d = self.vhi.mean - self.vlo.mean
        if abs(d) < floor or d == 0:
            return "small"
        apart = self.vhi.mean - self.vhi.spread() > self.vlo.mean + self.vlo.spread() if d > 0 else \
            self.vlo.mean - self.vlo.spread() > self.vhi.mean + self.vhi.spread()  # fmt: skip
        return ("holds" if d > 0 else "against") if apart else "tie"

    def seeds(self) -> int:
        """The fewest seeds behind the case's cells."""
        return min(self.vhi.n, self.vlo.n)


def _pairs(claim: Claim, group: str) -> list:
    return claim.greater.get(group, claim.greater.get("*", [])) if isinstance(claim.greater, dict) else list(claim.greater)


def _groups(claim: Claim, table: Table) -> list:
    """The groups a claim is tested on: its ``groups``, else those its ``greater`` dict names (in the table's order,
    then those the table lacks, which are then missing cells), else the table's; never a "within" claim's reference
    (a group compared with itself always holds)."""
    if claim.groups:
        groups = list(claim.groups)
    elif isinstance(claim.greater, dict):
        named = [g for g in claim.greater if g != "*"]
        groups = [g for g in table.groups if "*" in claim.greater or g in named] + [g for g in named if g not in table.groups]
    else:
        groups = table.groups
    return [g for g in groups if g != claim.reference] if claim.kind == "within" else groups


def cases(claim: Claim, table: Table, sub: dict | None = None) -> tuple[list, list]:
    """(the claim's :class:`Case` list on ``table``, the cells it needs that are missing), with the rows of
    ``sub`` ({row: row}) put in place of the claim's (a case whose two sides become one row is None, so that
    the list stays aligned with the claim's own)."""
    sub = sub or {}
    r = lambda x: sub.get(x, x)  # noqa: E731
    out, missing = [], []

    def get(row, group, metric):
        v = table.get(row, group, metric)
        if v is None:
            missing.append(f"{row} on {' '.join(x for x in (group, metric) if x) or 'the table'}")
        return v

    if claim.kind == "order_groups":
        for metric in claim.metrics:
            for a, b in claim.greater:
                va, vb = get(r(claim.row), a, metric), get(r(claim.row), b, metric)
                if va and vb:
                    out.append(Case(f"{r(claim.row)} {metric}", metric, a, b, va, vb))
        return out, missing
    for group in _groups(claim, table):
        for metric in claim.metrics:
            where = " ".join(x for x in (group, metric if len(claim.metrics) > 1 else "") if x)
            if claim.kind == "order":
                for a, b in _pairs(claim, group):
                    if r(a) == r(b):
                        out.append(None)
                        continue
                    va, vb = get(r(a), group, metric), get(r(b), group, metric)
                    if va and vb:
                        out.append(Case(where, metric, r(a), r(b), va, vb))
                continue
            v = get(r(claim.row), group, metric)
            bound = Value(claim.bound, 0.0, NO_SEEDS)
            if claim.kind == "within" or claim.bound_metric:
                ref = get(r(claim.row), claim.reference, metric) if claim.kind == "within" else get(r(claim.row), group, claim.bound_metric)
                if ref is None:
                    continue
                scale = claim.bound if claim.kind == "within" else 1.0  # a bound x ref, or the bound + ref: ref's band carries over
                bound = Value(claim.bound * ref.mean if claim.kind == "within" else claim.bound + ref.mean,
                              scale * ref.std, ref.n, scale * ref.resolution)  # fmt: skip
            if v:
                out.append(Case(where, metric, "bound", r(claim.row), bound, v))
    return out, missing


def _case_text(c: Case, claim: Claim, verdict: str) -> str:
    mark = {"tie": " [tie]", "small": " [too small]"}.get(verdict, "")
    if claim.kind == "order_groups":
        return f"{c.lo} {c.vlo.text()} {'<' if c.vhi.mean > c.vlo.mean else '≥'} {c.hi} {c.vhi.text()}{mark}"
    if c.hi == "bound":
        plus = f"{claim.bound:g} + " if claim.bound else ""
        how = f" ({claim.bound:g} x {claim.reference})" if claim.kind == "within" else f" ({plus}{claim.bound_metric})" if claim.bound_metric else ""
        bound = f"{c.vhi.text()}{how}"
        return f"{c.where} {c.vlo.text()} {'≤' if c.vlo.mean <= c.vhi.mean else '>'} {bound}{mark}".strip()
    return f"{c.hi} {c.vhi.text()} {'>' if c.vhi.mean > c.vlo.mean else '≤'} {c.lo} {c.vlo.text()}{mark}"


@dataclass
class Judgement:
    """A claim's reading: ``ours`` (the values per case), ``control`` (what the control gives), ``verdict`` and
    ``stale`` ({row: why})."""

    ours: str
    verdict: str
    control: str = "–"
    stale: dict = field(default_factory=dict)


def evaluate(claim: Claim, table: Table | None, floors: dict | None = None, code: dict | None = None) -> Judgement:
    """The :class:`Judgement` of ``claim`` on ``table`` by :data:`RULES`; ``floors``: {(table, metric label) or
    metric label: floor} (:func:`floor_of`); ``code``: {impl or impl@track: fingerprint, drapebench.staleness.code_key} the rows' code is judged against (default: the working
    tree's)."""
    if claim.kind not in KINDS:
        raise ValueError(f"claim {claim.id}: unknown kind {claim.kind!r}; kinds: {', '.join(KINDS)}")
    if claim.kind == "untested":
        return Judgement("–", f"not testable here: {claim.why}")
    if table is None:
        return Judgement("–", "not run")
    floors = floors or {}
    found, missing = cases(claim, table)
    if missing:
        return Judgement("–", f"not run ({', '.join(dict.fromkeys(missing))})")
    if not found:
        return Judgement("–", "not run (the table has none of the claim's groups)")
    controls = _control_cases(claim, table)
    # a copy (a case that repeats another's numbers) counts once, and only where its controls' cells repeat too
    keys = [(c.key(), *(None if theirs is None or theirs[i] is None else theirs[i].key() for _, theirs, _ in controls))
            for i, c in enumerate(found)]  # fmt: skip
    distinct = dict(zip(keys, found))
    outcome = {k: c.outcome(floor_of(floors, table.name, c.metric)) for k, c in distinct.items()}
    shown = _shown(found, claim, [outcome[k] for k in keys])
    if len(distinct) < len(found):
        shown += f" ({len(found)} cases, {len(distinct)} distinct: the others repeat the same numbers)"
    held = [k for k in distinct if outcome[k] == "holds"]
    control_held, control_complete, control_text = _control(claim, controls, keys, floors, table.name)
    k = len([x for x in held if x not in (control_held or set())])
    m = len(distinct)
    outcomes = list(outcome.values())
    if k == m and not control_complete:
        verdict = "holds, control not run"
    elif k == m:
        verdict = "reproduced" if all(c.seeds() > 1 for c in distinct.values()) else "holds, one seed"
    elif k > 0:
        verdict = f"partly ({k}/{m})" + ("" if control_complete else ", control not run")
    elif "against" in outcomes:  # on one seed both ways: a single run's spread is unknown
        verdict = "not reproduced" if any(c.seeds() > 1 for x, c in distinct.items() if outcome[x] == "against") else "not reproduced, one seed"
    elif held:
        verdict = f"scene-determined (the control meets {len(held)}/{m} as well)"
    elif all(o == "small" for o in outcomes):
        verdict = "too small to tell"
    else:
        verdict = "inside the spread"
    rows = {claim.row} if claim.kind == "order_groups" else {x for c in found for x in (c.hi, c.lo) if x != "bound"}  # order_groups: hi, lo are groups
    rows |= {r for c in claim.control for r in ([c] if isinstance(c, str) else c.values())}
    stale = stale_rows(sorted(rows & set(table.rows())), table.row_commits, table.commits, code, owner(table.name), table.trained_at,
                       table.track)  # fmt: skip
    if stale:  # it can hold, never reproduce
        verdict = f"stale: {'holds' if verdict == 'reproduced' else verdict}"
    if not claim.comparable:
        verdict += " (*indicative*: scene unlike the paper's)"
    return Judgement(shown, verdict, control_text, stale)


def _shown(found: list, claim: Claim, outcomes: list) -> str:
    parts: dict = {}
    for c, outcome in zip(found, outcomes):
        head = "" if claim.kind == "order_groups" or c.hi == "bound" else c.where
        parts.setdefault(c.where if claim.kind == "order_groups" else head, []).append(_case_text(c, claim, outcome))
    return "; ".join(f"{w}: {' ; '.join(t)}" if w else " ; ".join(t) for w, t in parts.items())


def _control_cases(claim: Claim, table: Table) -> list[tuple[str, list | None, str | None]]:
    """[(a control's name, its cases aligned with the claim's (:func:`cases` with its rows in place of the claim's),
    or None with why it cannot be compared: absent from the table, or missing a cell)] for each control the claim
    names."""
    out = []
    for sub in (c if isinstance(c, dict) else {claim.credited_row(): c} for c in claim.control):
        control = _names([sub]) if len(sub) > 1 else next(iter(sub.values()))
        absent = [row for row in sub.values() if row not in table.rows()]
        theirs, missing = cases(claim, table, sub) if not absent else ([], [])
        why = f"{control}: not in the table" if absent else f"{control}: not run ({missing[0]})" if missing else None
        out.append((control, None if why else theirs, why))
    return out


def _control(claim: Claim, controls: list, keys: list, floors: dict, table_name: str) -> tuple[set | None, bool, str]:
    """(the ``keys`` (one per case of the claim, in order; a copy shares its key) that a control meets as well: it
    holds them, or its means satisfy the relation inside the bands or the floor (a level the control passes by 0.07
    mm is no evidence that it fails; a mean at a level's bound meets it); None when no control of ``controls``
    (:func:`_control_cases`) has the cells to tell; whether every control the claim names was evaluated on at least
    one case; the control's cell text, naming the controls the table lacks)."""
    if not claim.control:
        return set(), True, f"none: {claim.control_why}"
    held, texts, evaluated, complete = set(), [], False, True
    for control, theirs, why in controls:
        outcomes: dict = {}  # a case's key -> (outcome, met on the means) of the control in each group it repeats in
        for key, t in zip(keys, theirs or []):
            if t is not None:
                on_means = t.vhi.mean >= t.vlo.mean if t.hi == "bound" else t.vhi.mean > t.vlo.mean
                outcomes.setdefault(key, []).append((t.outcome(floor_of(floors, table_name, t.metric)), on_means))
        if why or not outcomes:  # absent, missing a cell, or a side of every pair the claim compares
            complete = False
            texts.append(why or f"{control}: no case to compare (it is a side of each of the claim's pairs)")
            continue
        holds = {k for k, os in outcomes.items() if any(o == "holds" for o, _ in os)}
        on_means = {k for k, os in outcomes.items() if k not in holds and any(o in ("tie", "small") and met for o, met in os)}
        held |= holds | on_means
        evaluated = True
        texts.append(f"{control} holds {len(holds)}/{len(outcomes)}" + (f", meets on its means {len(on_means)}" if on_means else ""))
    return held if evaluated else None, complete, "; ".join(texts)


def _names(controls) -> str:
    return ", ".join(c if isinstance(c, str) else " and ".join(f"{v} for {k}" for k, v in c.items()) for c in controls)


def verdict_class(verdict: str) -> str:
    """The rule a verdict falls under (its first words, without the cases or the reason)."""
    return next(v for v in VERDICTS if verdict.startswith(v))


def claim_tables(claims: list, reports: Path) -> dict:
    """{name: :class:`Table`} of the committed tables ``claims`` name (and their ``_gpu`` twins) in ``reports``."""
    names = {c.table for c in claims if c.table}
    paths = [p for n in sorted(names) for p in (reports / f"{n}.csv", reports / f"{n}_gpu.csv") if p.exists()]
    return {p.stem: read_table(p) for p in paths}


def stale_tables(reports: Path, code: dict | None = None) -> dict:
    """{table: {row: why}} for every committed table in ``reports`` (its ``*.csv``, claimed or not) that has stale
    rows (:func:`drapebench.staleness.stale_rows`, judged against ``code`` as the claims are); a table whose rows are
    runs (names in its cells) is read by its first column. Raises :class:`drapebench.table_file.TableError` on a
    damaged table."""
    out = {}
    for path in sorted(Path(reports).glob("*.csv")):
        f = read_csv(path, check_cells=False)
        commits, row_commits, trained_at, track = _provenance(f.comments, path.stem)
        rows = sorted({cells[0] for _, cells in f.rows})
        stale = stale_rows(rows, row_commits, commits, code, owner(path.stem), trained_at, track)
        if stale:
            out[path.stem] = stale
    return out


def _stale_tables_text(stale: dict) -> list:
    """Markdown lines naming each table with stale rows, its rows grouped by why."""
    lines = []
    for table, rows in stale.items():
        by_why: dict = {}
        for row, why in rows.items():
            by_why.setdefault(why, []).append(row)
        lines.append(f"- {table}: " + "; ".join(f"{', '.join(r)} ({why})" for why, r in by_why.items()) + ".")
    return lines


def _judge(claims: list, reports: Path, code: dict | None):
    tables = claim_tables(claims, reports)
    floors = resolution_floors(tables)
    judged = [evaluate(c, tables.get(c.table), {k: f for k, (f, _, _) in floors.items()}, code) for c in claims]
    counts = pd.Series([verdict_class(j.verdict) for j in judged], dtype=object).value_counts()
    return judged, counts, tables, floors


def counts_line(counts: pd.Series, total: int) -> str:
    """"Verdicts: 3 reproduced; ...; 1 holds, one seed (of N claims)."."""
    return "Verdicts: " + "; ".join(f"{v} {k}" for k, v in counts.items()) + f" (of {total} claims)."


CODE_LINE = "Rows judged against the methods' code with fingerprints: "


def _table_file(reports: Path, table: str) -> str:
    """The file a scoreboard links for ``table``: its markdown in ``reports``, or its CSV where it has no markdown
    (a figure's data)."""
    return f"{table}.md" if (Path(reports) / f"{table}.md").exists() else f"{table}.csv"


def render(claims: list[Claim], reports: Path, code: dict | None = None) -> str:
    """``claims.md``'s text: the scoreboard over the tables in ``reports`` and their ``_gpu`` twins, staleness
    judged against ``code`` ({impl or impl@track: fingerprint}; default: the working tree's)."""
    code = code or current_code()
    judged, counts, tables, floors = _judge(claims, reports, code)
    lines = [
        "# Claims scoreboard",
        "",
        "Each headline claim of the three papers against this suite's committed tables. Generated by "
        "`python -m drapebench.report --claims` from `reports/*.csv`; do not edit by hand. *ours* is the CPU budget "
        "(`train=cpu`); *GPU* the same experiment with `device=cuda train=paper` (tables suffixed `_gpu`). "
        "A value \"m ± s (n=k)\" is a mean and std over k training seeds; a bare value is one seed.",
        "",
        "| claim | paper | ours (CPU budget) | control | verdict | GPU (`train=paper`) | table, command |",
        "|---|---|---|---|---|---|---|",
    ]
    notes = []
    fl = {k: f for k, (f, _, _) in floors.items()}
    table_specs = specs()
    for c, j in zip(claims, judged):
        gpu = tables.get(f"{c.table}_gpu")
        gpu_cell = "–"
        if gpu is not None and c.kind != "untested":
            g = evaluate(c, gpu, fl, code)
            gpu_cell = f"{g.verdict}: {g.ours}"
        src = tables.get(c.table)
        link = f"[{c.table}]({_table_file(reports, c.table)})" if src else (f"{c.table} (not committed)" if c.table else "–")
        if src and len(src.commits) > 1:
            link += f", rows from {len(src.commits)} commits"
        cmd = f"<br>`{table_specs[c.table].command()}`" if c.table in table_specs else ""
        lines.append(f"| **{c.id}** ({c.source}): {c.claim} | {c.paper} | {j.ours} | {j.control} | {j.verdict} | {gpu_cell} | {link}{cmd} |")
        notes += [f"- {c.id}: {n}" for n in c.notes]
        notes += [f"- {c.id}: stale row {row}: {why}." for row, why in j.stale.items()]
    lines += ["", counts_line(counts, len(claims)), "", f"Rules. {RULES}", "",
              "Resolution floors (per table and metric: the median seeds' std of its multi-seed cells with a spread, "
              "what two seeds of one method typically differ by on that scene, measured from the committed CPU tables "
              "each time this file is generated; a table without such cells uses the metric's median over all of them; "
              "in brackets the cells measured and the cells whose seeds agree to the printed digit, their std printed as "
              "0: deterministic rows, or a spread under the last digit): " + _floors_text(floors) + ".", "",
              CODE_LINE + ", ".join(f"{k} {v}" for k, v in sorted(code.items())) + " (drapebench.staleness).", ""]  # fmt: skip
    if notes:
        lines += ["Notes:", *notes, ""]
    stale = stale_tables(reports, code)
    lines += ["Tables with stale rows (every committed table, claimed or not, judged as the claims are: a row from "
              "another commit than its table's, or made or trained by method code or configs that have changed "
              "since)" + (":" if stale else ": none."), *_stale_tables_text(stale), ""]
    return "\n".join(lines)


def _floors_text(floors: dict) -> str:
    by_table: dict = {}
    for key, (f, n, z) in floors.items():
        table, metric = key if isinstance(key, tuple) else ("all tables", key)
        by_table.setdefault(table, []).append(f"{metric} {f:.2g} ({n}, {z})")
    return "; ".join(f"{t}: {', '.join(sorted(ms))}" for t, ms in sorted(by_table.items(), key=lambda x: (x[0] == "all tables", x[0])))


def recorded_code(text: str) -> dict:
    """The {impl or impl@track: fingerprint} a claims.md text was judged against (its :data:`CODE_LINE`)."""
    line = next((x for x in text.splitlines() if x.startswith(CODE_LINE)), None)
    if line is None:
        raise ValueError(f"no line starting {CODE_LINE!r}: regenerate claims.md")
    return dict(part.split() for part in line[len(CODE_LINE):].split(" (drapebench")[0].split(", "))


STATUS_START = "<!-- status: generated with reports/claims.md by `python -m drapebench.report --claims`; do not edit -->"
STATUS_END = "<!-- end of status -->"


def status_block(claims_md: str) -> str:
    """The README's "reproduction status at a glance" for a claims.md text: its verdict counts, between
    :data:`STATUS_START` and :data:`STATUS_END`."""
    counts = next(line for line in claims_md.splitlines() if line.startswith("Verdicts: "))
    return (f"{STATUS_START}\n{counts} Each claim, its control and the rules behind the verdicts: "
            f"[reports/claims.md](reports/claims.md).\n{STATUS_END}")


def with_status(readme: str, claims_md: str, path: Path) -> str:
    """``readme`` with its status block replaced by :func:`status_block` of ``claims_md``; raises ValueError naming
    ``path`` when it has no block."""
    start, end = readme.find(STATUS_START), readme.find(STATUS_END)
    if start < 0 or end < start:
        raise ValueError(f"{path} has no status block: put the lines {STATUS_START!r} and {STATUS_END!r} where the "
                         "reproduction status belongs")  # fmt: skip
    return readme[:start] + status_block(claims_md) + readme[end + len(STATUS_END):]


def write_claims(reports: Path, out: Path | None = None, readme: Path | None = None, note: str = "") -> Path:
    """Write the scoreboard of every method's claims (:func:`drapebench.claims_catalogue.claims`) over ``reports`` to ``out`` (default
    ``reports/claims.md``), ``note`` (a line) above it, and its verdict counts into ``readme``'s status block (default:
    the project's README.md when ``out`` is the committed claims.md), atomically; returns ``out``."""
    from drapebench.claims_catalogue import claims

    out = out or reports / "claims.md"
    text = (f"{note}\n\n" if note else "") + render(claims(), reports)
    with atomic_write(out, "w") as f:
        f.write(text)
    readme = readme or (PROJECT_ROOT / "README.md" if Path(out).resolve() == (PROJECT_ROOT / "reports" / "claims.md").resolve() else None)
    if readme is not None:
        updated = with_status(Path(readme).read_text(), text, readme)
        with atomic_write(readme, "w") as f:
            f.write(updated)
    return out
