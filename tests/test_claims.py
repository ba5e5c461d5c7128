"""The claims scoreboard: cell parsing, the verdict rules (ties, controls, floors, copies, stale rows), strict
table reading, and reports/claims.md kept in step with the committed CSVs."""

import csv
import io
import math
import subprocess
from pathlib import Path

import pytest

from drapebench.claims import (KINDS, Claim, evaluate, parse_cell, read_table, recorded_code, render, resolution_floors,
                               status_block, verdict_class, with_status)  # fmt: skip
from drapebench.claims_catalogue import claims
from drapebench.staleness import current_code
from drapebench.table_file import TableError, read_csv, seal, verified_text

ROOT = Path(__file__).resolve().parent.parent
REPORTS = ROOT / "reports"
CLAIMS = claims()  # every method's, as the scoreboard lists them


def _git(*args) -> str:
    return subprocess.run(["git", "-C", str(ROOT), *args], capture_output=True, text=True, check=True).stdout.strip()


def test_cells_parse_to_mean_std_over_seeds_and_n():
    assert parse_cell("2.5 ± 0.5 (n=3)") == parse_cell("2.500 ± 0.500 (n=3)")
    v = parse_cell("2.5 ± 0.5 (n=3)")
    assert (v.mean, v.std, v.n) == (2.5, 0.5, 3)
    one = parse_cell("0.070 ± 0.154")  # one seed: the ± is over frames, not a seed spread
    assert one.n == 1 and math.isnan(one.std) and one.mean == 0.07
    assert parse_cell("–") is None and parse_cell("failed") is None and parse_cell("12").mean == 12.0


def _csv(tmp_path, rows: dict, name="t", commits=None, mixed="", trained="") -> Path:
    """A grouped table CSV as report.py writes it (sealed): rows {method: [cells of group a, group b]} of metric m."""
    commits = commits or [_git("rev-parse", "HEAD")]
    lines = [f"# Produced by `x` from runs at commit(s) {', '.join(commits)} on x86_64 / Linux (now)."]
    lines += [f"# **Mixed commits**: the rows come from {len(commits)} commits, so code changed between them: {mixed}."] if mixed else []
    lines += [f"# **Models trained at**: some models were trained (and cached) by the code of another commit than their runs': {trained}."] if trained else []
    lines += ["garment,a,a,b,b", "metric,m,c,m,c", "method,,,,"]
    lines += [f"{k},{a},{ca},{b},{cb}" for k, (a, b, *ctrl) in rows.items() for ca, cb in [ctrl or ["–", "–"]]]
    path = tmp_path / f"{name}.csv"
    path.write_text(seal("\n".join(lines) + "\n"))
    return path


def _table(tmp_path, rows: dict, **kw):
    return read_table(_csv(tmp_path, rows, **kw))


ORDER = Claim("x", "P", "hi above lo", "-", "order", table="t", metrics=("m",), greater=[("hi", "lo")], control_why="test")


@pytest.mark.parametrize(
    "hi, lo, verdict",
    [
        (["5 ± 0.5 (n=3)", "6 ± 0.5 (n=3)"], ["1 ± 0.5 (n=3)", "2 ± 0.5 (n=3)"], "reproduced"),
        (["5 ± 2 (n=3)", "6 ± 0.5 (n=3)"], ["4 ± 2 (n=3)", "2 ± 0.5 (n=3)"], "partly"),  # a tie does not count
        (["5 ± 2 (n=3)", "6 ± 2 (n=3)"], ["4 ± 2 (n=3)", "5 ± 2 (n=3)"], "inside the spread"),  # every band overlaps
        (["5", "6"], ["1", "2"], "holds, one seed"),
        (["1 ± 0.5 (n=3)", "1"], ["5 ± 0.5 (n=3)", "2"], "not reproduced"),
        (["1", "1"], ["5", "2"], "not reproduced, one seed"),  # the other way on single runs only: as uncertain as a hold there
        (["5", "failed"], ["1", "2"], "not run"),
    ],
)
def test_an_ordering_counts_only_cases_whose_bands_do_not_overlap(tmp_path, hi, lo, verdict):
    t = _table(tmp_path, {"hi": hi, "lo": lo})
    assert verdict_class(evaluate(ORDER, t).verdict) == verdict


def test_a_tie_earns_no_partial_credit(tmp_path):
    """The issue's gaps_t2_no_inext case: 0.023 ± 0.002 against 0.022 ± 0.002 is a tie, not a held case."""
    t = _table(tmp_path, {"hi": ["0.023 ± 0.002 (n=3)", "5 ± 0.1 (n=3)"], "lo": ["0.022 ± 0.002 (n=3)", "1 ± 0.1 (n=3)"]})
    j = evaluate(ORDER, t)
    assert j.verdict == "partly (1/2)" and "[tie]" in j.ours


def test_a_level_the_control_also_meets_is_scene_determined(tmp_path):
    level = Claim("l", "P", "r low", "-", "level", table="t", metrics=("m",), row="r", bound=0.2, control=("lbs",))
    t = _table(tmp_path, {"r": ["0.05 ± 0.01 (n=3)", "0.06 ± 0.01 (n=3)"], "lbs": ["0.1", "0.5"]}, name="t")
    assert evaluate(level, t).verdict == "partly (1/2)"  # lbs meets the bound on a only: only b counts for r
    t = _table(tmp_path, {"r": ["0.05 ± 0.01 (n=3)", "0.06 ± 0.01 (n=3)"], "lbs": ["0.1", "0.1"]}, name="t")
    j = evaluate(level, t)
    assert verdict_class(j.verdict) == "scene-determined" and j.control == "lbs holds 2/2"
    t = _table(tmp_path, {"r": ["0.05 ± 0.01 (n=3)", "0.06 ± 0.01 (n=3)"], "lbs": ["0.5", "0.5"]}, name="t")
    assert evaluate(level, t).verdict == "reproduced"
    assert verdict_class(evaluate(Claim("l2", "P", "r", "-", "level", table="t", metrics=("m",), row="r", bound=0.2,
                                        control=("gaps_untrained",)), t).verdict) == "holds, control not run"  # fmt: skip


def test_a_control_that_meets_a_case_on_its_means_credits_the_scene(tmp_path):
    """gensim_t1's case: lbs 0.075 under its bound (under the floor) is no evidence that the control fails."""
    level = Claim("l", "P", "r low", "-", "level", table="t", metrics=("m",), row="r", bound=0.2, control=("lbs",))
    t = _table(tmp_path, {"r": ["0.05 ± 0.01 (n=3)", "0.06 ± 0.01 (n=3)"], "lbs": ["0.19 ± 0.05 (n=3)", "0.1"]}, name="t")
    j = evaluate(level, t)  # lbs's band crosses the bound on a, and it holds b
    assert verdict_class(j.verdict) == "scene-determined" and j.control == "lbs holds 1/2, meets on its means 1"
    t = _table(tmp_path, {"r": ["0.05 ± 0.01 (n=3)", "0.06 ± 0.01 (n=3)"], "lbs": ["0.3 ± 0.05 (n=3)", "0.5"]}, name="t")
    assert evaluate(level, t).verdict == "reproduced"


def test_an_order_the_control_also_meets_credits_the_scene(tmp_path):
    """gaps_t3's case: the row without the term grows with the body as much: the body, not the term."""
    grows = Claim("g", "P", "b above a", "-", "order_groups", table="t", metrics=("m",), row="r", greater=[("b", "a")],
                  control=("r0",))  # fmt: skip
    t = _table(tmp_path, {"r": ["1 ± 0.1 (n=3)", "3 ± 0.1 (n=3)"], "r0": ["1 ± 0.1 (n=3)", "3 ± 0.1 (n=3)"]})
    assert verdict_class(evaluate(grows, t).verdict) == "scene-determined"
    t = _table(tmp_path, {"r": ["1 ± 0.1 (n=3)", "3 ± 0.1 (n=3)"], "r0": ["1 ± 0.1 (n=3)", "1 ± 0.1 (n=3)"]})
    assert evaluate(grows, t).verdict == "reproduced"


def test_a_difference_under_the_floor_is_too_small_to_tell(tmp_path):
    t = _table(tmp_path, {"hi": ["0.022", "0.140"], "lo": ["0.013", "0.135"]})  # deterministic rows, ε_c-like numbers
    assert verdict_class(evaluate(ORDER, t).verdict) == "holds, one seed"  # no floor measured: any difference counts
    j = evaluate(ORDER, t, floors={("t", "m"): 0.01})
    assert j.verdict == "too small to tell" and j.ours.count("[too small]") == 2
    assert evaluate(ORDER, t, floors={"m": 0.006}).verdict == "partly (1/2)"  # the metric's pooled floor


def test_floors_are_the_median_seed_spread_per_table_and_metric(tmp_path):
    t = _table(tmp_path, {"hi": ["5 ± 0.1 (n=3)", "6 ± 0.3 (n=3)"], "lo": ["1 ± 0.2 (n=3)", "2 ± 0 (n=3)"]})
    floors = resolution_floors({"t": t})
    assert floors[("t", "m")] == (pytest.approx(0.2), 3, 1) and floors["m"] == floors[("t", "m")]
    t = _table(tmp_path, {"hi": ["5 ± 0.1 (n=3)", "6 ± 0.3 (n=3)"], "lo": ["1 ± 0.2 (n=3)", "2 ± 0 (n=3)"],
                          "hi_untrained": ["9 ± 4 (n=3)", "9 ± 5 (n=3)"]})  # random initialisations' spread: no floor
    assert resolution_floors({"t": t})[("t", "m")] == (pytest.approx(0.2), 3, 1)


def test_cases_with_the_same_numbers_count_once(tmp_path):
    """vto_f4_selfsup_samples' case: a quantity that does not depend on the group repeats in every group."""
    t = _table(tmp_path, {"hi": ["5 ± 0.5 (n=3)", "5 ± 0.5 (n=3)"], "lo": ["1 ± 0.5 (n=3)", "1 ± 0.5 (n=3)"]})
    j = evaluate(ORDER, t)
    assert j.verdict == "reproduced" and "2 cases, 1 distinct" in j.ours
    t = _table(tmp_path, {"hi": ["5 ± 0.5 (n=3)", "5 ± 0.5 (n=3)"], "lo": ["1 ± 0.5 (n=3)", "9 ± 0.5 (n=3)"]})
    assert evaluate(ORDER, t).verdict == "partly (1/2)"



def test_a_std_printed_as_zero_is_half_a_digit_wide(tmp_path):
    """"0.013 ± 0.000 (n=3)" is a spread under 0.0005, not none: a one-digit difference is a tie, not a held case."""
    assert parse_cell("0.013 ± 0.000 (n=3)").spread() == pytest.approx(0.0005) and parse_cell("12").spread() == 0.5
    t = _table(tmp_path, {"hi": ["0.013 ± 0.000 (n=3)", "0.003 ± 0.000 (n=3)"], "lo": ["0.012 ± 0.000 (n=3)", "0.002 ± 0.000 (n=3)"]})
    assert evaluate(ORDER, t).verdict == "inside the spread"
    t = _table(tmp_path, {"hi": ["0.014 ± 0.000 (n=3)", "0.004 ± 0.000 (n=3)"], "lo": ["0.012 ± 0.000 (n=3)", "0.002 ± 0.000 (n=3)"]})
    assert evaluate(ORDER, t).verdict == "reproduced"


def test_a_bound_made_from_a_measured_value_keeps_its_band(tmp_path):
    """A "within" bound (factor x the reference group's cell) and a level's bound_metric (bound + a cell) carry the
    cell's spread: 14 against 1.5 x (10 ± 4) is a tie."""
    within = Claim("w", "P", "b near a", "-", "within", table="t", metrics=("m",), row="r", reference="a", bound=1.5, control_why="test")
    assert evaluate(within, _table(tmp_path, {"r": ["10 ± 4 (n=3)", "14 ± 0.1 (n=3)"]})).verdict == "inside the spread"
    assert evaluate(within, _table(tmp_path, {"r": ["10 ± 0.1 (n=3)", "14 ± 0.1 (n=3)"]})).verdict == "reproduced"
    level = Claim("l", "P", "m under c", "-", "level", table="t", metrics=("m",), row="r", bound=0.5, bound_metric="c",
                  control_why="test")  # fmt: skip
    t = _table(tmp_path, {"r": ["1.0 ± 0.1 (n=3)", "1.0 ± 0.1 (n=3)", "1.0 ± 0.5 (n=3)", "1.0 ± 0.5 (n=3)"]})
    assert evaluate(level, t).verdict == "inside the spread"
    t = _table(tmp_path, {"r": ["1.0 ± 0.1 (n=3)", "1.0 ± 0.1 (n=3)", "1.0 ± 0.05 (n=3)", "1.0 ± 0.05 (n=3)"]})
    assert evaluate(level, t).verdict == "reproduced"


def test_a_within_claim_never_compares_the_reference_group_with_itself(tmp_path):
    within = Claim("w", "P", "b near a", "-", "within", table="t", metrics=("m",), row="r", reference="a", bound=1.5,
                   groups=("a", "b"), control_why="test")  # fmt: skip
    j = evaluate(within, _table(tmp_path, {"r": ["10 ± 0.1 (n=3)", "30 ± 0.1 (n=3)"]}))
    assert j.verdict == "not reproduced" and not j.ours.startswith("a ")


def test_a_copy_counts_once_only_where_its_control_repeats_too(tmp_path):
    """Two groups with the same numbers are one case when the control's cells repeat as well (met in either, it is
    credited to the scene, whichever group comes first); where the control differs, the numbers are a coincidence
    (0.000 collisions on two garments) and each group is a case of its own."""
    level = Claim("l", "P", "r low", "-", "level", table="t", metrics=("m",), row="r", bound=0.2, control=("lbs",))
    r = ["0.05 ± 0.01 (n=3)", "0.05 ± 0.01 (n=3)"]
    j = evaluate(level, _table(tmp_path, {"r": r, "lbs": ["0.1", "0.1"]}))
    assert verdict_class(j.verdict) == "scene-determined" and j.control == "lbs holds 1/1" and "2 cases, 1 distinct" in j.ours
    for lbs in (["0.1", "0.5"], ["0.5", "0.1"]):
        j = evaluate(level, _table(tmp_path, {"r": r, "lbs": lbs}))
        assert j.verdict == "partly (1/2)" and j.control == "lbs holds 1/2", lbs


def test_a_control_at_a_level_s_bound_meets_it(tmp_path):
    """"At most 0.2": a control at 0.200 meets it on its means, as one at 0.199 does."""
    level = Claim("l", "P", "r low", "-", "level", table="t", metrics=("m",), row="r", bound=0.2, groups=("a",), control=("lbs",))
    for lbs in ("0.200 ± 0.010 (n=3)", "0.199 ± 0.010 (n=3)"):
        j = evaluate(level, _table(tmp_path, {"r": ["0.050 ± 0.010 (n=3)", "–"], "lbs": [lbs, "–"]}))
        assert verdict_class(j.verdict) == "scene-determined", lbs
    j = evaluate(level, _table(tmp_path, {"r": ["0.050 ± 0.010 (n=3)", "–"], "lbs": ["0.300 ± 0.010 (n=3)", "–"]}))
    assert j.verdict == "reproduced"


def test_a_control_that_is_a_side_of_every_pair_is_not_run(tmp_path):
    """A control that stands in for the credited row on every pair compares nothing: the claim cannot reproduce."""
    claim = Claim("c", "P", "a above b", "-", "order", table="t", metrics=("m",), greater=[("a", "b")], control=("a",))
    j = evaluate(claim, _table(tmp_path, {"a": ["5 ± 0.1 (n=3)", "6 ± 0.1 (n=3)"], "b": ["1 ± 0.1 (n=3)", "2 ± 0.1 (n=3)"]}))
    assert j.verdict == "holds, control not run" and "a: no case to compare" in j.control


def test_a_bound_metric_without_an_offset_reads_as_the_metric(tmp_path):
    level = Claim("l", "P", "m under c", "-", "level", table="t", metrics=("m",), row="r", bound=0.0, bound_metric="c",
                  control_why="test")  # fmt: skip
    j = evaluate(level, _table(tmp_path, {"r": ["1.0 ± 0.1 (n=3)", "1.0 ± 0.1 (n=3)", "2.0 ± 0.1 (n=3)", "2.0 ± 0.1 (n=3)"]}))
    assert j.verdict == "reproduced" and "(c)" in j.ours and "0 + c" not in j.ours


def test_a_group_a_claim_names_that_the_table_lacks_is_not_run(tmp_path):
    pairs = {g: [("hi", "lo")] for g in ("a", "b", "c")}
    j = evaluate(Claim("d", "P", "hi above lo", "-", "order", table="t", metrics=("m",), greater=pairs, control_why="test"),
                 _table(tmp_path, {"hi": ["5 ± 0.5 (n=3)", "6 ± 0.5 (n=3)"], "lo": ["1 ± 0.5 (n=3)", "2 ± 0.5 (n=3)"]}))  # fmt: skip
    assert j.verdict.startswith("not run") and "hi on c m" in j.verdict
    star = {"*": [("hi", "lo")], "c": [("hi", "lo")]}  # every group, and c named besides
    j = evaluate(Claim("s", "P", "hi above lo", "-", "order", table="t", metrics=("m",), greater=star, control_why="test"),
                 _table(tmp_path, {"hi": ["5 ± 0.5 (n=3)", "6 ± 0.5 (n=3)"], "lo": ["1 ± 0.5 (n=3)", "2 ± 0.5 (n=3)"]}))  # fmt: skip
    assert j.verdict.startswith("not run") and "hi on c m" in j.verdict


def test_a_group_without_pairs_is_refused():
    with pytest.raises(ValueError, match="groups b have no pairs"):
        Claim("d", "P", "hi above lo", "-", "order", table="t", metrics=("m",), groups=("a", "b"), greater={"a": [("hi", "lo")]},
              control_why="test")  # fmt: skip


def test_an_order_over_groups_reads_its_row_s_commit(tmp_path):
    """order_groups' cases name groups, not rows: its credited row's provenance still decides staleness."""
    head, parent = _git("rev-parse", "HEAD"), _git("rev-parse", "HEAD~1")
    grows = Claim("g", "P", "b above a", "-", "order_groups", table="t", metrics=("m",), row="r", greater=[("b", "a")],
                  control=("r0",))  # fmt: skip
    rows = {"r": ["1 ± 0.1 (n=3)", "3 ± 0.1 (n=3)"], "r0": ["1 ± 0.1 (n=3)", "1 ± 0.1 (n=3)"]}
    j = evaluate(grows, _table(tmp_path, rows, commits=[parent, head], mixed=f"r {parent[:7]}; r0 {head[:7]}"))
    assert j.verdict == "stale: holds" and list(j.stale) == ["r"]


def test_a_control_the_table_lacks_is_named_and_keeps_the_claim_from_reproducing(tmp_path):
    level = Claim("l", "P", "r low", "-", "level", table="t", metrics=("m",), row="r", bound=0.2, control=("r_untrained", "lbs"))
    t = _table(tmp_path, {"r": ["0.05 ± 0.01 (n=3)", "0.06 ± 0.01 (n=3)"], "lbs": ["0.5", "0.5"]})
    j = evaluate(level, t)
    assert j.verdict == "holds, control not run" and j.control == "r_untrained: not in the table; lbs holds 0/2"
    t = _table(tmp_path, {"r": ["0.05 ± 0.01 (n=3)", "0.6 ± 0.01 (n=3)"], "lbs": ["0.5", "0.5"]})
    assert evaluate(level, t).verdict == "partly (1/2), control not run"
    assert evaluate(Claim("l", "P", "r low", "-", "level", table="t", metrics=("m",), row="r", bound=0.2, control=("lbs",)),
                    t).verdict == "partly (1/2)"  # fmt: skip


def test_a_row_from_another_commit_or_changed_code_makes_the_claim_stale(tmp_path):
    head, parent = _git("rev-parse", "HEAD"), _git("rev-parse", "HEAD~1")
    rows = {"hi": ["5 ± 0.5 (n=3)", "6 ± 0.5 (n=3)"], "lo": ["1 ± 0.5 (n=3)", "2 ± 0.5 (n=3)"]}
    t = _table(tmp_path, rows, commits=[parent, head], mixed=f"hi {parent[:7]}; lo {head[:7]}")
    j = evaluate(ORDER, t)
    assert j.verdict == "stale: holds" and list(j.stale) == ["hi"] and "not the table's" in j.stale["hi"]
    t = _table(tmp_path, rows, commits=["0123456789abcdef0123456789abcdef01234567"])
    assert "not in this repository's history" in evaluate(ORDER, t).stale["hi"]
    # a row run on uncommitted code is read as such (its -dirty kept in the provenance and the mixed-commits note)
    t = _table(tmp_path, rows, commits=[parent, head + "-dirty"], mixed=f"hi {parent[:7]}; lo {head[:7]}-dirty")
    assert t.row_commits["lo"] == [head[:7] + "-dirty"] and t.commits == [parent, head + "-dirty"]
    assert "uncommitted" in evaluate(ORDER, t).stale["lo"]
    # a method's code that differs from the code the verdicts are judged against
    level = Claim("l", "P", "lbs low", "-", "level", table="t", metrics=("m",), row="lbs", bound=9, control_why="test")
    t = _table(tmp_path, {"lbs": ["1", "2"]})
    assert evaluate(level, t).verdict == "holds, one seed"
    assert evaluate(level, t, code={"lbs": "000000000000"}).verdict == "stale: holds, one seed"
    # a benchmark's rows are garments, not methods: its code is the method package that declares the table
    bench = Claim("b", "P", "tshirt fast", "-", "level", table="vae_table2", metrics=("m",), row="tshirt", bound=9, control_why="test")
    t = _table(tmp_path, {"tshirt": ["1", "2"]}, name="vae_table2")
    assert evaluate(bench, t).verdict == "holds, one seed"
    j = evaluate(bench, t, code={"vae": "000000000000"})
    assert j.verdict == "stale: holds, one seed" and "methods/vae" in j.stale["tshirt"]


def test_every_committed_table_with_stale_rows_is_listed_claimed_or_not(tmp_path):
    """The scoreboard lists each table of the folder with stale rows, a table whose rows are runs (names in its
    cells, a repeated key) included, and says "none" when no row is stale."""
    from drapebench.claims import stale_tables

    head = _git("rev-parse", "HEAD")
    _csv(tmp_path, {"lbs": ["1", "2"]}, name="fresh")
    runs = ["# Produced by `x` from runs at commit(s) 0123456789abcdef0123456789abcdef01234567 (a device's copy) on y.",
            "method,garment,max_strain", "lbs,tshirt,5", "lbs,skirt,6"]
    (tmp_path / "per_run.csv").write_text(seal("\n".join(runs) + "\n"))
    stale = stale_tables(tmp_path)
    assert list(stale) == ["per_run"] and "not in this repository's history" in stale["per_run"]["lbs"]
    assert list(stale_tables(tmp_path, code={"lbs": "000000000000"})) == ["fresh", "per_run"]
    (tmp_path / "per_run.csv").unlink()
    text = render([], tmp_path, current_code())
    assert "Tables with stale rows" in text and text.rstrip().endswith("since): none.")
    text = render([], tmp_path, {**current_code(), "lbs": "000000000000"})
    assert f"- fresh: lbs (methods/lbs or its configs changed since {head[:7]})." in text


def test_a_model_trained_by_older_code_makes_the_claim_stale(tmp_path, monkeypatch):
    """A cached model is keyed by its configuration, not its code: a row run at the table's commit whose model was
    trained by another version of its method's code is stale; one trained by the same code, or unrecorded, is not."""
    from drapebench import staleness

    level = Claim("l", "P", "lbs low", "-", "level", table="t", metrics=("m",), row="lbs", bound=9, control_why="test")
    parent = _git("rev-parse", "HEAD~1")
    code = {"lbs": "now"}
    monkeypatch.setattr(staleness, "fingerprint", lambda impl, commit=None, track=None: "then" if commit == parent else "now")
    t = _table(tmp_path, {"lbs": ["1", "2"]}, trained=f"lbs {parent[:7]}, unrecorded")
    assert t.trained_at == {"lbs": [parent[:7], "unrecorded"]}
    j = evaluate(level, t, code=code)
    assert j.verdict == "stale: holds, one seed" and f"trained by methods/lbs as of {parent[:7]}" in j.stale["lbs"]
    monkeypatch.setattr(staleness, "fingerprint", lambda impl, commit=None, track=None: "now")  # the same code trained it
    assert evaluate(level, t, code=code).verdict == "holds, one seed"
    j = evaluate(level, _table(tmp_path, {"lbs": ["1", "2"]}, trained="lbs 0123456"), code=code)
    assert j.verdict == "stale: holds, one seed" and "trained at 0123456" in j.stale["lbs"]
    assert evaluate(level, _table(tmp_path, {"lbs": ["1", "2"]}, trained="lbs unrecorded"), code=code).verdict == "holds, one seed"
    # a benchmark's garment rows read the models of every method of the package that declares the table
    monkeypatch.setattr(staleness, "fingerprint", lambda impl, commit=None, track=None: "then" if commit == parent else "now")
    bench = Claim("b", "P", "tshirt fast", "-", "level", table="vae_table2", metrics=("m",), row="tshirt", bound=9, control_why="test")
    j = evaluate(bench, _table(tmp_path, {"tshirt": ["1", "2"]}, name="vae_table2", trained=f"vae {parent[:7]}"), code={"vae": "now"})
    assert j.verdict == "stale: holds, one seed" and "methods/vae as of" in j.stale["tshirt"]


def test_within_compares_each_group_with_the_reference_group(tmp_path):
    within = Claim("w", "P", "b near a", "-", "within", table="t", metrics=("m",), row="r", reference="a", bound=1.5,
                   control=("lbs",))  # fmt: skip
    t = _table(tmp_path, {"r": ["10", "12"], "lbs": ["10", "20"]})
    assert evaluate(within, t).verdict == "holds, one seed"  # 12 <= 15; lbs 20 > 15
    t = _table(tmp_path, {"r": ["10", "30"], "lbs": ["10", "20"]})
    assert evaluate(within, t).verdict == "not reproduced, one seed"  # single runs: as uncertain as the hold above


def test_a_gpu_table_fills_its_own_column(tmp_path):
    _csv(tmp_path, {"hi": ["5", "6"], "lo": ["1", "2"]})
    _csv(tmp_path, {"hi": ["1", "2"], "lo": ["5", "6"]}, name="t_gpu")
    row = next(line for line in render([ORDER], tmp_path).splitlines() if line.startswith("| **x**"))
    cells = [c.strip() for c in row.split("|")]
    assert cells[5] == "holds, one seed" and cells[6].startswith("not reproduced")


def test_every_claim_can_fail_and_names_its_control():
    sources = {c.source for c in CLAIMS}
    for s in ("GAPS Table 1", "GAPS Table 2", "GAPS Table 3", "GAPS Table 4", "GenSim Table 1", "GenSim Table 2",
              "GenSim Fig. 2", "GenSim Fig. 10", "GenSim Fig. 11", "VTO Table 1", "VTO Fig. 4", "VTO Table 2"):  # fmt: skip
        assert s in sources, s
    assert len({c.id for c in CLAIMS}) == len(CLAIMS)
    for c in CLAIMS:
        assert c.kind in KINDS and (c.kind != "untested" or c.why), c.id
        assert c.kind == "untested" or c.control or c.control_why, f"{c.id} names no control"


def _flipped(tmp_path, claim: Claim, value: str) -> str:
    """The verdict of ``claim`` after every value of its credited row in the claim's metrics is made ``value`` (one
    cell alone cannot always move a verdict that several groups decide)."""
    src = REPORTS / f"{claim.table}.csv"
    metrics = read_csv(src).header[-1]
    row = claim.row or claim.credited_row()
    lines = src.read_text().rsplit("# sha256 ", 1)[0].splitlines(keepends=True)
    for i, line in enumerate(lines):
        fields = next(csv.reader([line])) if not line.startswith("#") and line.strip() else []
        if fields and fields[0] == row:
            fields = [value if j and metrics[j] in claim.metrics and parse_cell(v) else v for j, v in enumerate(fields)]
            out = io.StringIO()
            csv.writer(out, lineterminator="\n").writerow(fields)
            lines[i] = out.getvalue()
    assert "".join(lines) != src.read_text().rsplit("# sha256 ", 1)[0], f"{claim.id}: no cell of {row} to flip"
    (tmp_path / src.name).write_text(seal("".join(lines)))
    return evaluate(claim, read_table(tmp_path / src.name)).verdict


@pytest.mark.parametrize("kind", ["order", "order_groups", "level", "within"])
def test_flipping_one_committed_value_changes_a_verdict_of_every_kind(tmp_path, kind):
    claim = next(c for c in CLAIMS if c.kind == kind)
    before = evaluate(claim, read_table(REPORTS / f"{claim.table}.csv")).verdict
    after = [_flipped(tmp_path, claim, v) for v in ("1000000", "-1000000")]  # far above, far below
    assert not any(a.startswith("not run") for a in after) and any(a != before for a in after), (claim.id, before, after)


def test_committed_claims_md_is_what_the_committed_csvs_give():
    committed = (REPORTS / "claims.md").read_text()
    assert committed == render(CLAIMS, REPORTS, recorded_code(committed)), \
        "reports/claims.md drifted from reports/*.csv: run `python -m drapebench.report --claims`"  # fmt: skip
    assert recorded_code(committed) == current_code(), \
        "the methods' code changed since reports/claims.md was judged: run `python -m drapebench.report --claims`"  # fmt: skip


def test_every_table_the_scoreboard_links_exists():
    import re

    links = set(re.findall(r"\]\(([^)#:]+)\)", (REPORTS / "claims.md").read_text()))
    assert links, "reports/claims.md links no table"
    assert not sorted(link for link in links if not (REPORTS / link).exists()), "reports/claims.md links a file that does not exist"


def test_the_readme_status_is_the_committed_scoreboard_s_counts(tmp_path):
    claims_md = (REPORTS / "claims.md").read_text()
    assert status_block(claims_md) in (ROOT / "README.md").read_text(), \
        "README.md's status disagrees with reports/claims.md: run `python -m drapebench.report --claims`"  # fmt: skip
    assert "Verdicts: " in status_block(claims_md)
    with pytest.raises(ValueError, match="README.md has no status block"):
        with_status("# x\n", claims_md, Path("README.md"))


def test_a_claim_with_none_of_its_groups_is_not_run_and_an_unknown_kind_fails(tmp_path):
    t = _table(tmp_path, {"hi": ["5", "6"], "lo": ["1", "2"]})
    only_c = Claim("c", "P", "on c", "-", "order", table="t", metrics=("m",), greater={"c": [("hi", "lo")]})
    assert evaluate(only_c, t).verdict.startswith("not run")
    with pytest.raises(ValueError, match="unknown kind 'ordr'"):
        evaluate(Claim("k", "P", "typo", "-", "ordr", table="t", metrics=("m",)), t)


# strict reading (issue 59): a damaged table is an error naming the file and the line, never a different score


def test_every_committed_table_matches_its_checksum_and_every_scored_one_reads_strictly():
    for path in sorted(REPORTS.glob("*.csv")):
        verified_text(path)
    for name in {c.table for c in CLAIMS if c.table and (REPORTS / f"{c.table}.csv").exists()}:
        assert read_csv(REPORTS / f"{name}.csv").rows


def test_a_duplicated_row_is_an_error_naming_the_file_and_line(tmp_path):
    path = _csv(tmp_path, {"hi": ["5", "6"], "lo": ["1", "2"]})
    body = path.read_text().rsplit("# sha256 ", 1)[0] + "hi,–,–,–,–\n"
    path.write_text(seal(body))
    with pytest.raises(TableError, match=r"t\.csv: line 7: row 'hi' repeats line 5"):
        read_table(path)


def test_a_truncated_table_is_an_error_naming_the_file(tmp_path):
    path = _csv(tmp_path, {"hi": ["5", "6"], "lo": ["1", "2"]})
    path.write_bytes(path.read_bytes()[:-60])  # cut mid-line: the footer is gone
    with pytest.raises(TableError, match=r"t\.csv: line \d+: no checksum footer.*truncated"):
        read_table(path)
    path = _csv(tmp_path, {"hi": ["5", "6"], "lo": ["1", "2"]})
    path.write_text(path.read_text().replace("hi,5", "hi,7"))  # a value edited by hand
    with pytest.raises(TableError, match=r"t\.csv: line 7: the checksum does not match"):
        read_table(path)


def test_a_binary_file_is_an_error_naming_the_file(tmp_path):
    (tmp_path / "t.csv").write_bytes(b"garment,a\n\xff\xfe\x00\x01")
    with pytest.raises(TableError, match=r"t\.csv: line 2: a NUL byte"):
        read_table(tmp_path / "t.csv")
    (tmp_path / "t.csv").write_bytes(b"garment,a\n\xff\xfe")
    with pytest.raises(TableError, match=r"t\.csv: line 2: not UTF-8"):
        read_table(tmp_path / "t.csv")


@pytest.mark.parametrize("row, match", [("hi,5,6,7", "line 7: 4 cells where the header has 5"),
                                        ("x,5,abc,–,–", r"line 7: column 3 \('c'\) holds 'abc'")])  # fmt: skip
def test_wrong_widths_and_cells_that_are_no_number_are_errors(tmp_path, row, match):
    path = _csv(tmp_path, {"hi": ["5", "6"], "lo": ["1", "2"]})
    path.write_text(seal(path.read_text().rsplit("# sha256 ", 1)[0] + row + "\n"))
    with pytest.raises(TableError, match=match):
        read_table(path)


def test_the_claims_and_tables_are_each_method_s_own_and_one_id_is_one_claim(monkeypatch):
    from drapebench import claims_catalogue, plugins, table_specs

    owners = {package for package, _ in [*plugins.declared("claims", "CLAIMS"), *plugins.declared("tables", "TABLES")]}
    assert len(owners) >= 3 and all(p.startswith("methods.") for p in owners)  # the papers' claims live beside their methods
    again = CLAIMS[0]
    monkeypatch.setattr(claims_catalogue, "declared", lambda module, attr: [("a", [again]), ("b", [again])] if attr == "CLAIMS" else [])
    with pytest.raises(ValueError, match=f"claim ids declared twice: {again.id}"):
        claims_catalogue.claims()
    monkeypatch.setattr(plugins, "declared", lambda module, attr: [("a", table_specs.TABLES[:1])])
    with pytest.raises(ValueError, match=f"table '{table_specs.TABLES[0].name}' declared twice"):
        table_specs.specs()


def test_a_level_or_within_claim_without_its_bound_or_reference_is_refused():
    """Without a bound every value would hold: a claim that cannot fail is not a claim."""
    with pytest.raises(ValueError, match="claim lv: a 'level' claim needs a finite bound"):
        Claim("lv", "P", "low", "-", "level", table="t", metrics=("m",), row="a", control_why="test")
    with pytest.raises(ValueError, match="claim w: a 'within' claim needs reference="):
        Claim("w", "P", "near", "-", "within", table="t", metrics=("m",), row="a", bound=2, control_why="test")
