"""The claims scoreboard: cell parsing, the verdict rules, and reports/claims.md kept in step with the CSVs."""

import math
from pathlib import Path

import pytest

from drapebench.claims import Claim, evaluate, parse_cell, read_table, render, verdict_class
from drapebench.claims_catalogue import CLAIMS

REPORTS = Path(__file__).resolve().parent.parent / "reports"


def test_cells_parse_to_mean_std_over_seeds_and_n():
    assert parse_cell("2.5 ± 0.5 (n=3)") == parse_cell("2.500 ± 0.500 (n=3)")
    v = parse_cell("2.5 ± 0.5 (n=3)")
    assert (v.mean, v.std, v.n) == (2.5, 0.5, 3)
    one = parse_cell("0.070 ± 0.154")  # one seed: the ± is over frames, not a seed spread
    assert one.n == 1 and math.isnan(one.std) and one.mean == 0.07
    assert parse_cell("–") is None and parse_cell("failed") is None and parse_cell("12") .mean == 12.0


def _table(tmp_path, rows: dict, name="t") -> object:
    """A grouped table CSV like the report writes: rows {method: [cells of group a, group b]} for metric m."""
    lines = ["# Produced by `x` from runs at commit(s) abc1234 on x86_64.", "garment,a,b", "metric,m,m", "method,,"]
    lines += [f"{k},{a},{b}" for k, (a, b) in rows.items()]
    (tmp_path / f"{name}.csv").write_text("\n".join(lines) + "\n")
    return read_table(tmp_path / f"{name}.csv")


ORDER = Claim("x", "P", "hi above lo", "-", "order", table="t", metrics=("m",), greater=[("hi", "lo")])


@pytest.mark.parametrize(
    "hi, lo, verdict",
    [
        (["5 ± 0.5 (n=3)", "6 ± 0.5 (n=3)"], ["1 ± 0.5 (n=3)", "2 ± 0.5 (n=3)"], "reproduced"),
        (["5 ± 2 (n=3)", "6 ± 0.5 (n=3)"], ["4 ± 2 (n=3)", "2 ± 0.5 (n=3)"], "holds, inside the spread"),
        (["5", "6"], ["1", "2"], "holds, one seed"),
        (["5 ± 0.5 (n=3)", "1 ± 0.5 (n=3)"], ["1 ± 0.5 (n=3)", "2 ± 0.5 (n=3)"], "partly"),
        (["1 ± 0.5 (n=3)", "1"], ["5 ± 0.5 (n=3)", "2"], "not reproduced"),
        (["5", "failed"], ["1", "2"], "not run"),
    ],
)
def test_an_ordering_is_reproduced_only_beyond_the_seeds_spread(tmp_path, hi, lo, verdict):
    t = _table(tmp_path, {"hi": hi, "lo": lo})
    assert verdict_class(evaluate(ORDER, t)[1]) == verdict


def test_levels_and_cross_group_orders(tmp_path):
    t = _table(tmp_path, {"r": ["0.1 ± 0.05 (n=3)", "0.3 ± 0.05 (n=3)"]})
    level = Claim("l", "P", "r low", "-", "level", table="t", metrics=("m",), row="r", bound=0.2, groups=("a",))
    assert evaluate(level, t)[1] == "reproduced"
    assert evaluate(Claim("l", "P", "r low", "-", "level", table="t", metrics=("m",), row="r", bound=0.12, groups=("a",)), t)[1] \
        == "holds, inside the spread"  # the mean is below the bound, mean + std is not
    assert evaluate(Claim("l", "P", "r", "-", "level", table="t", metrics=("m",), row="r", bound=0.2, comparable=False), t)[1] \
        .startswith("partly (1/2) (*indicative*")
    grows = Claim("g", "P", "b above a", "-", "order_groups", table="t", metrics=("m",), row="r", greater=[("b", "a")])
    ours, verdict = evaluate(grows, t)
    assert verdict == "reproduced" and "a 0.1 ± 0.05 (n=3) < b 0.3 ± 0.05 (n=3)" in ours
    assert evaluate(Claim("u", "P", "c", "-", "untested", why="needs a GPU"), None)[1] == "not testable here: needs a GPU"


def test_a_gpu_table_fills_its_own_column(tmp_path):
    _table(tmp_path, {"hi": ["5", "6"], "lo": ["1", "2"]})
    _table(tmp_path, {"hi": ["1", "2"], "lo": ["5", "6"]}, name="t_gpu")
    row = next(line for line in render([ORDER], tmp_path).splitlines() if line.startswith("| **x**"))
    cells = [c.strip() for c in row.split("|")]
    assert cells[4] == "holds, one seed" and cells[5].startswith("not reproduced")


def test_every_paper_table_and_figure_has_a_claim_and_ids_are_unique():
    sources = {c.source for c in CLAIMS}
    for s in ("GAPS Table 1", "GAPS Table 2", "GAPS Table 3", "GAPS Table 4", "GenSim Table 1", "GenSim Table 2",
              "GenSim Fig. 2", "GenSim Fig. 10", "GenSim Fig. 11", "VTO Table 1", "VTO Fig. 4", "VTO Table 2"):  # fmt: skip
        assert s in sources, s
    assert len({c.id for c in CLAIMS}) == len(CLAIMS)
    for c in CLAIMS:
        assert c.kind in ("order", "order_groups", "level", "runs", "untested") and (c.kind != "untested" or c.why)


def test_committed_claims_md_is_what_the_committed_csvs_give():
    committed = (REPORTS / "claims.md").read_text()
    assert committed == render(CLAIMS, REPORTS), "reports/claims.md drifted from reports/*.csv: run `python -m drapebench.report --claims`"


def test_a_claim_with_none_of_its_groups_is_not_run_and_an_unknown_kind_fails(tmp_path):
    t = _table(tmp_path, {"hi": ["5", "6"], "lo": ["1", "2"]})
    only_c = Claim("c", "P", "on c", "-", "order", table="t", metrics=("m",), greater={"c": [("hi", "lo")]})
    assert evaluate(only_c, t)[1].startswith("not run")
    with pytest.raises(ValueError, match="unknown kind 'ordr'"):
        evaluate(Claim("k", "P", "typo", "-", "ordr", table="t", metrics=("m",)), t)
