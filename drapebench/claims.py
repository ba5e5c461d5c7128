"""The claims scoreboard: each headline claim of the three papers, tested against the committed tables.

``python -m drapebench.report --claims`` reads the CSVs in ``reports/`` (and their ``_gpu`` twins, made with
``device=cuda train=paper``) and writes ``reports/claims.md``: per claim the paper's figure, ours (mean ± std
over seeds where a cell has several), a verdict by the rules in :data:`RULES`, and the table and experiment
behind it. The output depends on the CSVs alone, so a test regenerates it and compares.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from drapebench.cache import atomic_write
from drapebench.claim import Claim

CELL = re.compile(r"^\s*(-?[\d.]+(?:e-?\d+)?)(?:\s*±\s*([\d.]+(?:e-?\d+)?))?(?:\s*\(n=(\d+)\))?\s*$")


@dataclass(frozen=True)
class Value:
    """One table cell: its mean, the std over seeds (nan for one seed: a "± std" without n is over frames) and
    the number of seeds."""

    mean: float
    std: float
    n: int

    def text(self) -> str:
        """The value as the claims table shows it: 3 significant digits, "± std (n=k)" over seeds."""
        mean = f"{self.mean:,.0f}" if abs(self.mean) >= 1000 else f"{self.mean:.3g}"
        return mean + (f" ± {self.std:.2g} (n={self.n})" if self.n > 1 else "")


def parse_cell(cell) -> Value | None:
    """A table cell ("1.23", "1.23 ± 0.45", "1.23 ± 0.45 (n=3)") as a :class:`Value`; None for "–", "failed" or
    anything else that is not a number."""
    m = CELL.match(str(cell))
    if not m:
        return None
    n = int(m.group(3) or 1)
    return Value(float(m.group(1)), float(m.group(2)) if n > 1 else float("nan"), n)


@dataclass
class Table:
    """A committed table read from its CSV: cells keyed by (row, column group, metric label) (group "" for a
    table without groups), its groups in order and its provenance line."""

    name: str
    cells: dict
    groups: list
    commits: list

    def get(self, row: str, group: str, metric: str) -> Value | None:
        """The parsed cell, None where the table lacks it or it holds no number."""
        return parse_cell(self.cells.get((row, group, metric), "–"))


def read_table(path: Path) -> Table:
    """A table's CSV (``#`` provenance lines, then a one- or two-row header) as a :class:`Table`."""
    lines = path.read_text().splitlines()
    comments = [line for line in lines if line.startswith("#")]
    commits = re.search(r"commit\(?s?\)? ([0-9a-f, -]+?)(?: on |\.|$)", comments[0]) if comments else None
    commits = [c.strip()[:7] for c in commits.group(1).split(",")] if commits else []
    grouped = len(lines) > len(comments) + 1 and lines[len(comments) + 1].startswith("metric,")
    df = pd.read_csv(path, comment="#", header=[0, 1] if grouped else 0, index_col=0, dtype=str)
    cells, groups = {}, []
    for col in df.columns:
        group, metric = col if grouped else ("", col)
        groups.append(group)
        for row, v in df[col].items():
            cells[(str(row), group, metric)] = v
    return Table(path.stem, cells, list(dict.fromkeys(groups)), commits)


KINDS = ("order", "order_groups", "level", "runs", "untested")
RULES = (
    "**reproduced**: the relation holds in every case (group x metric) and, where a cell has several seeds, the "
    "two mean ± std bands do not overlap (a level: mean + std within the bound); "
    "**holds, inside the spread**: it holds on the means but some bands overlap; "
    "**holds, one seed**: it holds but a cell has a single seed, so its spread is unknown; "
    "**partly (k/m)**: it holds in k of m cases; **not reproduced**: it holds in none; "
    "**not run**: a cell it needs is missing or failed; **not testable here**: no committed table can test it "
    "(what it needs is said). A level on a scene unlike the paper's is marked *indicative*."
)


def _pairs(claim: Claim, group: str) -> list:
    return claim.greater.get(group, claim.greater.get("*", [])) if isinstance(claim.greater, dict) else list(claim.greater)


def _groups(claim: Claim, table: Table) -> list:
    if claim.groups:
        return list(claim.groups)
    if isinstance(claim.greater, dict):
        return [g for g in table.groups if g in claim.greater] if "*" not in claim.greater else table.groups
    return table.groups


def evaluate(claim: Claim, table: Table | None) -> tuple[str, str]:
    """(ours, verdict) of ``claim`` on ``table``: the values per case and the verdict by :data:`RULES`."""
    if claim.kind not in KINDS:
        raise ValueError(f"claim {claim.id}: unknown kind {claim.kind!r}; kinds: {', '.join(KINDS)}")
    if claim.kind == "untested":
        return "–", f"not testable here: {claim.why}"
    if table is None:
        return "–", "not run"
    cases, shown = [], []
    if claim.kind == "order_groups":  # one row's value compared across column groups
        for metric in claim.metrics:
            vals = {g: table.get(claim.row, g, metric) for p in claim.greater for g in p}
            if any(v is None for v in vals.values()):
                return "–", f"not run ({claim.row} on {', '.join(g for g, v in vals.items() if v is None)})"
            for a, b in claim.greater:
                holds = vals[a].mean > vals[b].mean
                cases.append((holds, holds and vals[a].mean - _s(vals[a]) > vals[b].mean + _s(vals[b]), min(vals[a].n, vals[b].n)))
            shown.append(f"{claim.row} {metric}: " + " ; ".join(f"{b} {vals[b].text()} {'<' if vals[a].mean > vals[b].mean else '≥'} {a} {vals[a].text()}"
                                                               for a, b in claim.greater))  # fmt: skip
        return "; ".join(shown), _verdict(cases, claim)
    for group in _groups(claim, table):
        for metric in claim.metrics:
            where = " ".join(x for x in (group, metric if len(claim.metrics) > 1 else "") if x)
            if claim.kind == "order":
                pairs = _pairs(claim, group)
                vals = {r: table.get(r, group, metric) for p in pairs for r in p}
                if any(v is None for v in vals.values()):
                    return "–", f"not run ({', '.join(r for r, v in vals.items() if v is None)} on {where or 'the table'})"
                for a, b in pairs:
                    va, vb = vals[a], vals[b]
                    holds = va.mean > vb.mean
                    apart = holds and va.mean - _s(va) > vb.mean + _s(vb)
                    cases.append((holds, apart, min(va.n, vb.n)))
                chain = " ; ".join(f"{a} {vals[a].text()} {'>' if vals[a].mean > vals[b].mean else '≤'} {b} {vals[b].text()}" for a, b in pairs)
                shown.append(f"{where}: {chain}" if where else chain)
            else:
                v = table.get(claim.row, group, metric)
                if v is None:
                    return "–", f"not run ({claim.row} on {where or 'the table'})"
                if claim.kind == "runs":
                    cases.append((True, True, v.n))
                    shown.append(f"{where} {v.text()}")
                    continue
                holds = v.mean <= claim.bound
                cases.append((holds, holds and v.mean + _s(v) <= claim.bound, v.n))
                shown.append(f"{where} {v.text()}".strip())
    if not cases:
        return "–", "not run (the table has none of the claim's groups)"
    return "; ".join(shown), _verdict(cases, claim)


def _s(v: Value) -> float:
    return v.std if v.n > 1 else 0.0


def _verdict(cases: list, claim: Claim) -> str:
    held = sum(h for h, _, _ in cases)
    if held == 0:
        verdict = "not reproduced"
    elif held < len(cases):
        verdict = f"partly ({held}/{len(cases)})"
    elif any(n < 2 for _, _, n in cases):
        verdict = "holds, one seed"
    elif all(a for _, a, _ in cases):
        verdict = "reproduced"
    else:
        verdict = "holds, inside the spread"
    return verdict if claim.comparable else f"{verdict} (*indicative*: scene unlike the paper's)"


VERDICTS = ("reproduced", "holds, inside the spread", "holds, one seed", "partly", "not reproduced", "not run", "not testable here")


def verdict_class(verdict: str) -> str:
    """The rule a verdict falls under (its first words, without the cases or the reason)."""
    return next(v for v in VERDICTS if verdict.startswith(v))


def render(claims: list[Claim], reports: Path) -> str:
    """``claims.md``'s text: the scoreboard over the CSVs in ``reports`` and their ``_gpu`` twins."""
    tables = {p.stem: read_table(p) for p in sorted(reports.glob("*.csv"))}
    lines = [
        "# Claims scoreboard",
        "",
        "Each headline claim of the three papers against this suite's committed tables. Generated by "
        "`python -m drapebench.report --claims` from `reports/*.csv`; do not edit by hand. *ours* is the CPU budget "
        "(`train=cpu`); *GPU* the same experiment with `device=cuda train=paper` (tables suffixed `_gpu`). "
        "A value \"m ± s (n=k)\" is a mean and std over k training seeds; a bare value is one seed.",
        "",
        "| claim | paper | ours (CPU budget) | verdict | GPU (`train=paper`) | table, command |",
        "|---|---|---|---|---|---|",
    ]
    notes = []
    for c in claims:
        ours, verdict = evaluate(c, tables.get(c.table))
        gpu = tables.get(f"{c.table}_gpu")
        gpu_cell = "–"
        if gpu is not None and c.kind != "untested":
            gpu_ours, gpu_verdict = evaluate(c, gpu)
            gpu_cell = f"{gpu_verdict}: {gpu_ours}"
        src = tables.get(c.table)
        link = f"[{c.table}]({c.table}.md)" if src else (f"{c.table} (not committed)" if c.table else "–")
        if src and len(src.commits) > 1:
            link += f", rows from {len(src.commits)} commits"
        cmd = f"<br>`{c.command}`" if c.command else ""
        lines.append(f"| **{c.id}** ({c.source}): {c.claim} | {c.paper} | {ours} | {verdict} | {gpu_cell} | {link}{cmd} |")
        notes += [f"- {c.id}: {n}" for n in c.notes]
    counts = pd.Series([verdict_class(evaluate(c, tables.get(c.table))[1]) for c in claims]).value_counts()
    lines += ["", "Verdicts: " + ", ".join(f"{v} {k}" for k, v in counts.items()) + f" (of {len(claims)} claims).", "",
              f"Rules. {RULES}", ""]  # fmt: skip
    if notes:
        lines += ["Notes:", *notes, ""]
    return "\n".join(lines)


def write_claims(reports: Path, out: Path | None = None) -> Path:
    """Write the scoreboard of :data:`drapebench.claims_catalogue.CLAIMS` over ``reports`` to ``out``
    (default ``reports/claims.md``), atomically; returns the path."""
    from drapebench.claims_catalogue import CLAIMS

    out = out or reports / "claims.md"
    with atomic_write(out, "w") as f:
        f.write(render(CLAIMS, reports))
    return out
