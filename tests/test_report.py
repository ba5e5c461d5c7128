import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from drapebench.report import collect, provenance, table, training_note, write_summary, write_table

FIXTURES = Path(__file__).parent / "fixtures" / "runs"


def test_table_layout_and_cells():
    df = collect([FIXTURES])
    assert len(df) == 4
    t = table(df, ["eps_e", "eps_c"])
    assert list(t.index) == ["lbs", "pbs"]
    assert list(t.columns.get_level_values(0).unique()) == ["tshirt", "skirt"]
    assert t.loc["lbs", ("tshirt", "ε_e (%)")] == "4.000"
    assert t.loc["pbs", ("skirt", "ε_c (%)")] == "0.100 ± 0.020"  # mean +- std where the std exists
    only_lbs = df.assign(eps_c_canonical=np.where(df["method"] == "lbs", 0.25, np.nan))  # a metric one method reports
    t = table(only_lbs, ["eps_c_canonical"])
    assert t.loc["lbs", ("tshirt", "ε_c canon. (%)")] == "0.250" and t.loc["pbs", ("tshirt", "ε_c canon. (%)")] == "–"
    smooth = table(df.assign(smoothness=0.0028915), ["smoothness"])  # metres: printed to 10 um, not to 1 mm
    assert smooth.loc["lbs", ("tshirt", "smooth. (m)")] == "0.00289"
    assert table(df.assign(smoothness=0.0028915), ["smoothness"], decimals=3).loc["lbs", ("tshirt", "smooth. (m)")] == "0.003"


def test_write_table_outputs_with_provenance(tmp_path):
    paths = write_table([FIXTURES], "baseline", tmp_path / "baseline", command="pytest")
    md, tex, csv, png = paths
    text = md.read_text()
    assert "lbs" in text and "Produced by `pytest`" in text and "abc123" in text
    assert "\\begin{tabular}" in tex.read_text() and "abc123" in tex.read_text()
    assert pd.read_csv(csv, comment="#", header=[0, 1], index_col=0).shape == (2, 6)
    assert png.stat().st_size > 1000
    with pytest.raises(KeyError, match="no table 'nope'; tables: baseline"):
        write_table([FIXTURES], "nope", tmp_path / "x")


def test_a_failed_plot_leaves_the_tables_files_as_they_were(tmp_path, monkeypatch):
    """A table's .md, .tex, .csv and plot are replaced as a set: an error in the plot (written last) replaces none."""
    import drapebench.report as report

    before = write_table([FIXTURES], "baseline", tmp_path / "baseline", command="first")
    texts = {p: p.read_bytes() for p in before}

    def broken_plot(*args, **kwargs):
        raise RuntimeError("plot failed")

    monkeypatch.setattr(report, "runtime_plot", broken_plot)
    with pytest.raises(RuntimeError, match="plot failed"):
        write_table([FIXTURES], "baseline", tmp_path / "baseline", command="second")
    assert {p: p.read_bytes() for p in before} == texts
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(p.name for p in before)  # no temporary left behind



def test_a_rename_that_fails_partway_puts_the_set_back(tmp_path, monkeypatch):
    """A full disk on the third rename of a table's set: the two files already replaced get their old bytes back, a
    file that was new is removed, and no temporary or saved copy is left."""
    import os

    from drapebench.cache import atomic_write_set

    paths = [tmp_path / n for n in ("t.md", "t.tex", "t.csv", "t_runtime.png")]
    for p in paths[:3]:
        p.write_text("old")
    real, calls = os.replace, []

    def full_disk(src, dst):
        calls.append(dst)
        if len(calls) == 3:
            raise OSError(28, "No space left on device")
        real(src, dst)

    monkeypatch.setattr(os, "replace", full_disk)
    with pytest.raises(OSError, match="No space"):
        with atomic_write_set(paths[::-1]) as temporaries:  # the plot first: a new file among those replaced
            for t in temporaries:
                t.write_text("new")
    assert {p.name: p.read_text() for p in paths if p.exists()} == {"t.md": "old", "t.tex": "old", "t.csv": "old"}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.csv", "t.md", "t.tex"]


def test_a_set_that_cannot_be_begun_leaves_no_temporary(tmp_path):
    """The second path's folder is a file: its temporary cannot be made, and the first one's is removed."""
    from drapebench.cache import atomic_write_set

    (tmp_path / "afile").write_text("x")
    with pytest.raises(OSError):
        with atomic_write_set([tmp_path / "t.md", tmp_path / "afile" / "t.png"]):
            pass
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile"]

def test_the_provenance_names_the_runs_torch_threads(tmp_path):
    """runtime_vs_error's ms/frame depend on the threads each run drew with (``reproduce --jobs`` pins its share)."""
    import json
    import shutil

    shutil.copytree(FIXTURES, tmp_path / "runs")
    for i, f in enumerate(sorted((tmp_path / "runs").rglob("metrics.json"))):
        (f.parent / "env.json").write_text(json.dumps({"torch_threads": 1 + i % 2}))
    assert ", 1 or 2 torch threads per run (" in provenance(collect([tmp_path / "runs"]), "x")
    assert "torch thread" not in provenance(collect([FIXTURES]), "x")  # runs without env.json: nothing claimed


def test_summary_and_missing_runs(tmp_path):
    import shutil

    shutil.copytree(FIXTURES, tmp_path / "sweep")
    write_summary(tmp_path / "sweep")
    rows = pd.read_csv(tmp_path / "sweep" / "summary.csv")
    assert len(rows) == 4 and set(rows["method"]) == {"lbs", "pbs"}
    with pytest.raises(FileNotFoundError, match="no metrics.json"):
        collect([tmp_path / "empty"])


def test_shape_columns_for_the_body_shape_table(tmp_path):
    import json
    import shutil

    shutil.copytree(FIXTURES, tmp_path / "runs")
    for i, f in enumerate(sorted((tmp_path / "runs").rglob("metrics.json"))):
        rec = json.loads(f.read_text())
        rec["shape"] = "mean" if i % 2 == 0 else "b1=-2"
        f.write_text(json.dumps(rec))
    df = collect([tmp_path / "runs"])
    t = table(df, ["eps_e"], group="shape")
    assert list(t.columns.get_level_values(0).unique()) == ["mean", "b1=-2"] and t.columns.names == ["shape", "metric"]
    cases = table(df, ["eps_e"], group="case")  # one column group per motion and body shape
    assert set(cases.columns.get_level_values(0)) == {f"{m} {s}" for m, s in zip(df["motion"], df["shape"])}
    with pytest.raises(KeyError, match="no 'shape' column"):
        table(collect([FIXTURES]), ["eps_e"], group="shape")


def test_shape_label():
    from drapebench.experiment import shape_label

    assert shape_label(None) == "mean" == shape_label([0.0, 0.0])
    assert shape_label([0.0, -2.0, 0.5]) == "b1=-2,b2=0.5"


def test_failed_runs_show_as_failed_cells_in_tables_and_summaries(tmp_path):
    import json
    import shutil

    shutil.copytree(FIXTURES, tmp_path / "sweep")
    (tmp_path / "sweep" / "4_pbs_gown").mkdir()
    (tmp_path / "sweep" / "4_pbs_gown" / "failed.json").write_text(json.dumps(
        {"status": "failed", "method": "pbs", "garment": "gown", "motion": "kick", "body": "anny_lowres", "shape": "mean",
         "error": "SimulationDiverged", "message": "diverged at frame 12 of 105", "commit": "def456"}))  # fmt: skip
    md = write_table([tmp_path / "sweep"], "baseline", tmp_path / "t", command="pytest")[0].read_text()
    assert "failed" in md and "diverged at frame 12 of 105" in md and "def456" in md
    t = pd.read_csv(tmp_path / "t.csv", comment="#", header=[0, 1], index_col=0)
    assert t.loc["pbs", ("gown", "ε_c (%)")] == "failed" and t.loc["lbs", ("gown", "ε_c (%)")] == "–"
    assert float(t.loc["lbs", ("tshirt", "ε_e (%)")]) == 4.0  # finished cells are untouched
    write_summary(tmp_path / "sweep")
    rows = pd.read_csv(tmp_path / "sweep" / "summary.csv")
    assert len(rows) == 5 and list(rows["status"]).count("failed") == 1
    for k, method in ((5, "pbs"), (6, "lbs")):  # the same cause in more runs: one line naming them all
        (tmp_path / "sweep" / f"{k}_{method}_gown").mkdir()
        (tmp_path / "sweep" / f"{k}_{method}_gown" / "failed.json").write_text(
            (tmp_path / "sweep" / "4_pbs_gown" / "failed.json").read_text().replace('"pbs"', f'"{method}"'))
    grouped = write_table([tmp_path / "sweep"], "baseline", tmp_path / "g", command="pytest")[0].read_text()
    assert grouped.count("diverged at frame 12 of 105") == 1 and "- pbs on gown (x2), lbs on gown failed:" in grouped


def test_a_method_whose_every_run_failed_is_a_row_of_failed_cells(tmp_path):
    """A table that lists a method whose runs all diverged (recorded with on_failure=record) is still written, the
    method in its place with "failed" cells, not refused as a method no run has."""
    import json
    import shutil

    shutil.copytree(FIXTURES, tmp_path / "sweep")
    (tmp_path / "sweep" / "9_gaps_tshirt").mkdir()
    (tmp_path / "sweep" / "9_gaps_tshirt" / "failed.json").write_text(json.dumps(
        {"status": "failed", "method": "gaps", "garment": "tshirt", "motion": "kick", "body": "anny_lowres", "shape": "mean",
         "error": "SimulationDiverged", "message": "loss is NaN at step 3", "commit": "def456"}))  # fmt: skip
    write_table([tmp_path / "sweep"], "baseline", tmp_path / "t", command="pytest", methods=["gaps", "lbs"])
    t = pd.read_csv(tmp_path / "t.csv", comment="#", header=[0, 1], index_col=0)
    assert list(t.index) == ["gaps", "lbs"] and t.loc["gaps", ("tshirt", "ε_c (%)")] == "failed"
    with pytest.raises(ValueError, match="no run of method.s. snug_like"):  # a method with neither result nor failure
        write_table([tmp_path / "sweep"], "baseline", tmp_path / "u", command="pytest", methods=["snug_like", "lbs"])


def test_jobs_are_collected_in_job_order(tmp_path):
    import json
    import shutil

    for i, garment in [(2, "skirt"), (10, "gown"), (1, "tshirt")]:
        shutil.copytree(FIXTURES / "0_lbs_tshirt", tmp_path / f"{i}_lbs_{garment}")
        f = tmp_path / f"{i}_lbs_{garment}" / "metrics.json"
        f.write_text(json.dumps({**json.loads(f.read_text()), "garment": garment}))
    assert list(collect([tmp_path])["garment"]) == ["tshirt", "skirt", "gown"]


def test_loss_curve_plot_from_losses_csv(tmp_path):
    from drapebench.report import loss_curve_plot, main

    run = tmp_path / "run"
    run.mkdir()
    (run / "losses.csv").write_text("step,epoch,lr,loss,strain,gravity,grad_norm\n1,0,0.001,2.0,1.5,-0.5,3.0\n2,0,0.001,1.0,1.2,-0.2,2.0\n")
    path = loss_curve_plot(run / "losses.csv")
    assert path == run / "losses.png" and path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    path.unlink()
    main([str(tmp_path), "--loss-curves"])
    assert (run / "losses.png").exists()
    (run / "losses.csv").write_text("step,loss\n")
    with pytest.raises(ValueError, match="no steps"):
        loss_curve_plot(run / "losses.csv")


def test_the_report_command_leaves_the_committed_reports_untouched_by_default(tmp_path, monkeypatch, capsys):
    from drapebench.report import main

    monkeypatch.chdir(tmp_path)
    (tmp_path / "reports").mkdir()
    (tmp_path / "reports" / "baseline.md").write_text("committed\n")
    main([str(FIXTURES), "--table", "baseline"])
    main([str(FIXTURES), "--table", "baseline"])
    assert (tmp_path / "reports" / "baseline.md").read_text() == "committed\n"
    written = sorted((tmp_path / "outputs" / "reports").glob("*/baseline.md"))
    assert len(written) == 2  # each call its own folder
    assert str(written[0].relative_to(tmp_path)) in capsys.readouterr().out
    main([str(FIXTURES), "--table", "baseline", "--out", "reports/baseline"])  # replacing is an explicit choice
    assert (tmp_path / "reports" / "baseline.md").read_text() != "committed\n"


def test_tables_and_summaries_carry_the_scene_and_a_legend_of_their_metrics(tmp_path):
    import shutil

    md, tex, csv, _ = write_table([FIXTURES], "gaps_table2", tmp_path / "t2", command="pytest")
    text = md.read_text()
    assert "Scene: garments tshirt, skirt; body anny_lowres; motions walk; reference drape none." in text
    legend_line = next(line for line in text.splitlines() if line.startswith("Legend: "))
    assert "eps_c: garment vertices inside the body (%, lower" in legend_line and "docs/metrics.md" in legend_line
    assert "eps_e" not in legend_line  # only the metrics the table shows
    assert "% Legend: eps_c" in tex.read_text() and "# Scene: garments" in csv.read_text()
    shutil.copytree(FIXTURES, tmp_path / "sweep")
    summary = write_summary(tmp_path / "sweep").read_text()
    assert "eps_e: mean edge-length change (%" in summary.splitlines()[-1]


def test_legend_and_headline_come_from_one_catalogue():
    from drapebench.results import METRICS, SUMMARY_COLUMNS, headline, legend

    numeric = [c for c in SUMMARY_COLUMNS if c not in ("method", "garment", "motion", "body", "reference", "shape", "seed", "n_vertices", "n_frames")]
    assert not [c for c in numeric if c.removesuffix("_std") not in METRICS], "every summary metric needs a unit and direction"
    assert "nope" not in legend(["eps_c", "nope"]) and "eps_c: " in legend(["eps_c", "nope"])
    assert headline({"eps_e": 5.081, "eps_c": 0.0, "ms_per_frame": 7.03}) == "eps_e 5.08 %, eps_c 0 %, ms_per_frame 7.03 ms"


def test_runtime_plot_draws_stretch_or_vertex_error_never_collisions():
    from drapebench.report import runtime_error

    df = collect([FIXTURES])
    assert runtime_error(df) == "eps_e"
    assert runtime_error(df.assign(vertex_error_mm=[1.0, 2.0, 0.0, 0.0])) == "vertex_error_mm"
    assert runtime_error(df.assign(vertex_error_mm=float("nan"))) == "eps_e"


def test_committed_tables_name_the_command_and_commit_that_made_them():
    import re

    reports = Path(__file__).resolve().parent.parent / "reports"
    prov = re.compile(r"Produced by `python (?:-m drapebench\.(?:report|reproduce)|-m methods\.\w+\.\w+|benchmarks/bench_\w+\.py) [^`]+` from runs at commit\(s\) [0-9a-f]{7,40}")
    names = {p.stem for p in reports.glob("*.csv")}  # a table is its .md, .tex and .csv
    tables = sorted(p for p in reports.glob("*") if p.suffix in (".md", ".tex", ".csv") and p.stem in names)
    assert tables
    missing = [p.name for p in tables if not prov.search(p.read_text())]
    assert not missing, f"committed tables without their command and commit: {missing}"
    index = (reports / "README.md").read_text()
    unlisted = [p.stem for p in tables if p.suffix == ".md" and f"({p.name})" not in index]
    assert not unlisted, f"tables not in reports/README.md: {unlisted}"


def test_evaluation_plot_draws_the_runs_per_epoch_evaluations(tmp_path, monkeypatch):
    import shutil

    from drapebench.report import evaluation_plot, main

    shutil.copytree(FIXTURES, tmp_path / "runs")
    runs = sorted((tmp_path / "runs").rglob("metrics.json"))
    with pytest.raises(FileNotFoundError, match="no evaluations.csv"):
        evaluation_plot([tmp_path / "runs"], tmp_path / "fig.png")
    (runs[0].parent / "evaluations.csv").write_text("epoch,step,val_colliding_pct,sampled_colliding_pct\n0,8,1.5,3.0\n1,16,0.5,1.0\n")
    path = evaluation_plot([tmp_path / "runs"], tmp_path / "fig.png")
    import json

    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and path.stat().st_size > 5000
    from drapebench.claims import read_table

    curves = read_table(path.with_suffix(".csv"))  # what the scoreboard reads: a row per method, a group per quantity
    method = json.loads(runs[0].read_text())["method"]
    assert [curves.get(method, "validation reconstructions", f"epoch {e} (%)").mean for e in (1, 2)] == [1.5, 0.5]
    assert curves.get(method, "validation reconstructions", "last epoch (%)").mean == 0.5 and curves.commits
    main([str(tmp_path / "runs"), "--evaluations", "--out", str(tmp_path / "fig4")])
    assert (tmp_path / "fig4.png").exists()
    named = evaluation_plot([tmp_path / "runs"], tmp_path / "named.png", command="python -m drapebench.reproduce --tables fig4", methods=[method])
    footer = named.with_suffix(".csv").read_text()
    assert "Produced by `python -m drapebench.reproduce --tables fig4`" in footer and str(tmp_path) not in footer  # rerunnable anywhere
    with pytest.raises(ValueError, match="no_such_method"):
        evaluation_plot([tmp_path / "runs"], tmp_path / "none.png", methods=["no_such_method"])
    import json

    from drapebench import report

    seeded = json.loads(runs[1].read_text())
    seeded.update(method=json.loads(runs[0].read_text())["method"], train_seed=1)  # a second seed of the same method
    runs[1].write_text(json.dumps(seeded))
    (runs[1].parent / "evaluations.csv").write_text("epoch,step,val_colliding_pct,sampled_colliding_pct\n0,8,2.5,1.0\n1,16,1.5,1.0\n")
    bands, real = [], report.save_figure
    monkeypatch.setattr(report, "save_figure", lambda fig, p: (bands.extend(fig.axes[0].collections), real(fig, p))[1])
    evaluation_plot([tmp_path / "runs"], tmp_path / "bands.png")
    assert len(bands) == 2  # one min-max band per column over the two seeds


def test_runtime_vs_error_has_a_pareto_panel_per_garment_and_the_speed_up_over_the_reference(tmp_path):
    from drapebench.report import pareto_plot, speedups

    df = collect([FIXTURES]).assign(vertex_error_mm=[12.0, 20.0, 0.5, 0.7])
    assert speedups(df).splitlines()[1:] == ["- tshirt: lbs 500x", "- skirt: lbs 714x"]
    assert speedups(df[df["method"] == "lbs"]) == ""  # no reference run, no speed-up
    path = pareto_plot(df, tmp_path / "pareto.png", title="t")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    import matplotlib.image

    height, width = matplotlib.image.imread(path).shape[:2]
    assert width > 1.8 * height  # two panels side by side
    four = pd.concat([df, df.assign(garment=df["garment"] + "_b")])
    height, width = matplotlib.image.imread(pareto_plot(four, tmp_path / "four.png")).shape[:2]
    assert 0.8 * height < width < 1.5 * height  # four garments: two rows of two
    md = write_table([FIXTURES], "runtime_vs_error", tmp_path / "rve", command="pytest")[0]
    assert "ms/frame" in md.read_text() and "Speed-up over `pbs`" in md.read_text()


def test_methods_filter_orders_rows_and_names_a_missing_method(tmp_path, capsys):
    from drapebench.report import main

    main([str(FIXTURES), "--table", "baseline", "--methods", "pbs,lbs", "--out", str(tmp_path / "t")])
    rows = pd.read_csv(tmp_path / "t.csv", comment="#", header=[0, 1], index_col=0).index.tolist()
    assert rows == ["pbs", "lbs"]
    main([str(FIXTURES), "--table", "baseline", "--methods", "lbs", "--out", str(tmp_path / "u")])
    assert pd.read_csv(tmp_path / "u.csv", comment="#", header=[0, 1], index_col=0).index.tolist() == ["lbs"]
    with pytest.raises(SystemExit):  # argparse's message
        main([str(FIXTURES), "--table", "baseline", "--methods", "lbs,gensim", "--out", str(tmp_path / "v")])
    assert "no run of method(s) gensim" in capsys.readouterr().err


def test_garments_filter_keeps_the_runs_of_the_garments_named(tmp_path, capsys):
    from drapebench.report import main

    main([str(FIXTURES), "--table", "baseline", "--garments", "skirt", "--out", str(tmp_path / "t")])
    header = pd.read_csv(tmp_path / "t.csv", comment="#", header=[0, 1], index_col=0).columns.get_level_values(0)
    assert set(header) == {"skirt"}
    with pytest.raises(SystemExit):  # argparse's message
        main([str(FIXTURES), "--table", "baseline", "--garments", "gown", "--out", str(tmp_path / "u")])
    assert "no run of garment(s) gown" in capsys.readouterr().err


def test_generalisation_matrix_groups_columns_by_experiment_and_explains_empty_cells(tmp_path):
    import json
    import shutil

    from drapebench.report import write_table
    from drapebench.table_specs import specs

    for i, (method, experiment) in enumerate([("lbs", "unseen_motion"), ("gensim", "unseen_motion"), ("gensim", "other_body")]):
        d = tmp_path / f"{i}_{method}"
        shutil.copytree(FIXTURES / "0_lbs_tshirt", d)
        rec = {**json.loads((d / "metrics.json").read_text()), "method": method, "experiment": experiment, "vertex_error_mm": 10.0 + i}
        (d / "metrics.json").write_text(json.dumps(rec))
    md = write_table([tmp_path], "gensim_table1", tmp_path / "m")[0].read_text()
    header = next(line for line in md.splitlines() if line.startswith("| method"))
    assert "unseen_motion err. (mm)" in header and "other_body err. (mm)" in header
    lbs_row = next(line for line in md.splitlines() if line.startswith("| lbs"))
    assert lbs_row.rstrip(" |").endswith("–") and specs()["gensim_table1"].note in md


def test_energy_column_sums_the_physical_terms_and_scenes_split_motions(tmp_path):
    import json
    import shutil

    from drapebench.report import collect

    for i, (motion, parts) in enumerate([("walk", (0.1, 0.02, 0.3)), ("kick", (0.2, 0.01, 0.25))]):
        d = tmp_path / f"{i}_lbs"
        shutil.copytree(FIXTURES / "0_lbs_tshirt", d)
        rec = {**json.loads((d / "metrics.json").read_text()), "motion": motion,
               **dict(zip(("energy_stvk", "energy_bending", "energy_gravity"), parts)), "energy_collision": 5.0}
        (d / "metrics.json").write_text(json.dumps(rec))
    df = collect([tmp_path])
    assert df["energy_j"].tolist() == pytest.approx([0.42, 0.46])  # the collision penalty (m^3) is not added
    assert df["scene"].tolist() == ["tshirt walk", "tshirt kick"]
    md = write_table([tmp_path], "gaps_generalisation", tmp_path / "g")[0].read_text()
    assert "tshirt walk energy (J)" in md and "tshirt kick energy (J)" in md


def test_vertex_error_tables_print_the_reference_floor_or_how_to_measure_it(tmp_path):
    import json
    import shutil

    from drapebench.report import floor_methods

    runs = tmp_path / "runs"
    for i, (method, err) in enumerate([("lbs", 17.0), ("pbs_style3d", 9.3), ("pbs_half_dt", 2.5)]):
        d = runs / f"{i}_{method}"
        shutil.copytree(FIXTURES / "0_lbs_tshirt", d)
        (d / "metrics.json").write_text(json.dumps({**json.loads((d / "metrics.json").read_text()), "method": method, "vertex_error_mm": err}))
    md = write_table([runs], "runtime_vs_error", tmp_path / "t", command="pytest")[0].read_text()
    assert f"`pbs_style3d`, {floor_methods()['pbs_style3d']}: tshirt 9.3 mm" in md and "`pbs_half_dt`" in md and "tshirt 2.5 mm" in md
    md = write_table([runs / "0_lbs"], "runtime_vs_error", tmp_path / "u", command="pytest")[0].read_text()
    assert "Reference floor: not measured" in md and "method=pbs_style3d,pbs_half_dt" in md
    assert "Reference floor" not in write_table([runs / "0_lbs"], "baseline", tmp_path / "v", command="pytest")[0].read_text()


def test_a_table_names_the_runs_whose_training_the_time_guard_cut(tmp_path):
    import json
    import shutil

    runs = tmp_path / "runs"
    for i, stopped in enumerate(["done", "time", "clock"]):
        d = runs / f"{i}_lbs"
        shutil.copytree(FIXTURES / "0_lbs_tshirt", d)
        (d / "metrics.json").write_text(json.dumps({**json.loads((d / "metrics.json").read_text()), "seed": i, "train_stopped": stopped}))
    md = write_table([runs], "baseline", tmp_path / "t", command="pytest")[0].read_text()
    assert "**Time-cut training**: lbs tshirt seed 1:" in md and "seed 0" not in md.split("Time-cut")[1].split("\n")[0]
    assert "**Clock-scheduled training**: lbs tshirt seed 2:" in md and "seed 1" not in md.split("Clock-scheduled")[1].split("\n")[0]
    assert "Time-cut" not in write_table([runs / "0_lbs"], "baseline", tmp_path / "u", command="pytest")[0].read_text()


def test_the_stability_table_has_a_row_per_run_and_failed_runs_with_their_cause(tmp_path):
    import json
    import shutil

    runs = tmp_path / "runs"
    for i, (dtype, strain) in enumerate([("float32", 12.5), ("float64", 12.4)]):
        d = runs / f"{i}_lbs"
        shutil.copytree(FIXTURES / "0_lbs_tshirt", d)
        rec = {**json.loads((d / "metrics.json").read_text()), "dtype": dtype, "max_strain": strain, "max_penetration_mm": 3.0, "drift_mm": 0.5}
        (d / "metrics.json").write_text(json.dumps(rec))
    (runs / "2_gaps").mkdir()
    (runs / "2_gaps" / "failed.json").write_text(json.dumps({"status": "failed", "method": "gaps", "garment": "skirt", "motion": "stress",
                                                             "shape": "b0=2", "dtype": "float32", "message": "NaN/Inf in 3 of 300 frames"}))
    md = write_table([runs], "stability", tmp_path / "s", command="pytest")[0].read_text()
    rows = [line for line in md.splitlines() if line.startswith("| lbs") or line.startswith("| gaps")]
    assert len(rows) == 3 and "float64" in rows[1] and "12.400" in rows[1]
    assert rows[2].count("failed") == 4 and "gaps on skirt stress b0=2 float32 failed: NaN/Inf in 3 of 300 frames" in md
    assert "max strain (%)" in md and "drift (mm)" in md


def test_labels_of_crowded_points_stack_apart_and_a_lone_point_keeps_its_own():
    from drapebench.report import label_places

    ms = np.array([4.0, 4.5, 3.9, 400.0])
    err = np.array([17.7, 17.8, 16.7, 40.0])  # the crowd lies within 6 % of the 23.3 mm span
    places = label_places(ms, err)
    assert places[3] == (3, 3, 3.0)  # far from the rest: beside itself
    assert {p[:2] for p in places[:3]} == {(1, 1)}  # the crowd's labels start beside its highest, rightmost point
    assert sorted(p[2] for p in places[:3]) == [-15.0, -6.0, 3.0]  # 9 points apart, highest first
    assert places[1] == (1, 1, 3.0) and places[2][2] == -15.0
    # the highest point left of the other: the labels go right of the rightmost, not over its marker
    places = label_places(np.array([0.364, 0.417, 1000.0]), np.array([42.9, 41.6, 0.0]))
    assert places[0] == (1, 0, 3.0) and places[1] == (1, 0, -6.0)


def test_a_wide_grouped_table_is_written_as_one_markdown_table_per_group():
    from drapebench.report import MAX_MARKDOWN_COLUMNS, _markdown

    def grouped(n_groups: int) -> pd.DataFrame:
        cols = pd.MultiIndex.from_product([[f"g{i}" for i in range(n_groups)], ["ε_e (%)", "ε_c (%)", "err. (mm)"]])
        return pd.DataFrame([["1"] * len(cols)], index=pd.Index(["lbs"], name="method"), columns=cols)

    narrow = _markdown(grouped(2))
    assert narrow.count("| method") == 1 and "g1 ε_c (%)" in narrow
    n = MAX_MARKDOWN_COLUMNS // 3 + 1
    wide = _markdown(grouped(n))
    assert wide.count("| method") == n and f"**g{n - 1}**" in wide and "g1 ε_c" not in wide
    t = pd.concat([grouped(n), grouped(n).rename(index={"lbs": "gaps"})])
    t.loc["gaps", "g1"] = "–"  # not run on g1: left out of g1's table only
    per_group = _markdown(t).split("**")
    assert "| gaps" not in per_group[per_group.index("g1") + 1] and "| gaps" in per_group[per_group.index("g0") + 1]


def _seeded_runs(tmp_path, values, commits=("abc123",) * 3, skip=(), trained_at=None):
    """Copies of the lbs/tshirt fixture run, one per seed, with eps_e set from ``values``; ``skip``: seeds
    whose run is moved to the skirt (a seed that ran another scene); ``trained_at``: per seed, the commit that
    trained its model."""
    import json
    import shutil

    src = FIXTURES / "0_lbs_tshirt" / "metrics.json"
    for seed, (v, commit) in enumerate(zip(values, commits)):
        rec = json.loads(src.read_text())
        rec.update(method="gaps", eps_e=v, seed=seed, train_seed=seed, commit=commit)
        if trained_at is not None:
            rec["trained_at"] = trained_at[seed]
        if seed in skip:
            rec["motion"] = "kick"
        d = tmp_path / f"{seed}_gaps_tshirt"
        d.mkdir(parents=True)
        (d / "metrics.json").write_text(json.dumps(rec))
    shutil.copytree(FIXTURES / "2_pbs_tshirt", tmp_path / "9_pbs_tshirt")
    return collect([tmp_path])


def test_runs_that_differ_only_in_their_seed_give_mean_std_and_n(tmp_path):
    df = _seeded_runs(tmp_path, [1.0, 2.0, 4.0])
    t = table(df, ["eps_e", "eps_c"])
    std = np.std([1.0, 2.0, 4.0], ddof=1)
    assert t.loc["gaps", ("tshirt", "ε_e (%)")] == f"2.333 ± {std:.3f} (n=3)"
    assert t.loc["pbs", ("tshirt", "ε_c (%)")] == "0.200 ± 0.050"  # one seed: the frame spread, no n
    paths = write_table([tmp_path], "baseline", tmp_path / "out" / "t", command="pytest")
    text = paths[0].read_text()
    assert "(n=3)" in text and "Seeds: 0, 1, 2" in text and "over k training seeds" in text
    assert "Mixed commits" not in text
    csv = paths[2].read_text()
    assert "# Seeds: 0, 1, 2" in csv and f"2.333 ± {std:.3f} (n=3)" in csv


def test_a_seed_averages_its_scenes_first_and_a_seed_on_other_scenes_is_flagged(tmp_path):
    import json

    df = _seeded_runs(tmp_path, [1.0, 3.0, 5.0], skip=(2,))
    from drapebench.report import seeds_note, seed_stats, unbalanced_seeds

    assert unbalanced_seeds(df, "garment") == ["gaps on tshirt"]
    assert "Not comparable as seeds" in seeds_note(df, "garment")
    # a second scene for seed 0 is averaged into seed 0's value before the std over seeds
    rec = json.loads((tmp_path / "0_gaps_tshirt" / "metrics.json").read_text())
    rec.update(eps_e=3.0, motion="jump")
    (tmp_path / "5_gaps_tshirt").mkdir()
    (tmp_path / "5_gaps_tshirt" / "metrics.json").write_text(json.dumps(rec))
    mean, std, n = seed_stats(collect([tmp_path]).query("method == 'gaps'"), "eps_e")
    assert n == 3 and mean == pytest.approx((2.0 + 3.0 + 5.0) / 3) and std == pytest.approx(np.std([2.0, 3.0, 5.0], ddof=1))


def test_a_table_from_several_commits_says_so(tmp_path):
    _seeded_runs(tmp_path, [1.0, 2.0, 4.0], commits=("abc123", "def4567", "abc123"))
    text = write_table([tmp_path], "baseline", tmp_path / "out" / "t", command="pytest")[0].read_text()
    assert text.startswith("# baseline (rows from 2 commits)") and "**Mixed commits**: the rows come from 2 commits" in text and "gaps abc123, def4567" in text and "pbs abc123" in text


def test_the_mixed_commits_note_keeps_a_rows_uncommitted_code_apart_from_its_commit():
    import pandas as pd

    from drapebench.report import commits_note

    df = pd.DataFrame({"method": ["gaps", "lbs"], "commit": ["a" * 40 + "-dirty", "b" * 40]})
    assert "gaps aaaaaaa-dirty; lbs bbbbbbb." in commits_note(df)


def test_a_table_names_models_trained_by_another_commits_code(tmp_path):
    from drapebench.claims import read_table

    a, b = "a" * 40, "b" * 40
    _seeded_runs(tmp_path / "other", [1.0, 2.0, 4.0], commits=(a,) * 3, trained_at=(a, b, "unrecorded"))
    paths = write_table([tmp_path / "other"], "baseline", tmp_path / "out" / "t", command="pytest")
    assert "**Models trained at**" in paths[0].read_text() and "gaps bbbbbbb, unrecorded." in paths[0].read_text()
    assert "gaps bbbbbbb, unrecorded." in paths[1].read_text()  # the .tex header
    assert read_table(paths[2]).trained_at == {"gaps": ["bbbbbbb", "unrecorded"]}  # the CSV, as the scoreboard reads it
    _seeded_runs(tmp_path / "odd", [1.0, 2.0, 4.0], commits=(a,) * 3, trained_at=(f"{b}-dirty+{'c' * 12}", "unknown", a))
    odd = write_table([tmp_path / "odd"], "baseline", tmp_path / "out3" / "t", command="pytest")
    assert read_table(odd[2]).trained_at == {"gaps": ["bbbbbbb-dirty", "unknown"]}  # neither is a known commit: stale
    _seeded_runs(tmp_path / "same", [1.0, 2.0, 4.0], commits=(a,) * 3, trained_at=(a, a, a))
    assert "Models trained at" not in write_table([tmp_path / "same"], "baseline", tmp_path / "out2" / "t", command="pytest")[0].read_text()


def test_a_table_names_each_trained_methods_body_steps_and_minutes(tmp_path):
    import json
    import shutil

    df = _seeded_runs(tmp_path, [1.0, 2.0, 4.0])
    assert training_note(df) == ""  # no run loaded a trained model
    for seed, (steps, train_s) in enumerate([(3300, 600.0), (3300, 720.0), (2900, 660.0)]):
        path = tmp_path / f"{seed}_gaps_tshirt" / "metrics.json"
        rec = {**json.loads(path.read_text()), "checkpoint": f"gaps_{seed}.pt", "train_steps": steps, "train_s": train_s, "train_body": "anny_lowres"}
        path.write_text(json.dumps(rec))
    shutil.copytree(tmp_path / "0_gaps_tshirt", tmp_path / "5_gaps_tshirt")  # a second run of seed 0's model counts once
    note = training_note(collect([tmp_path]))
    assert "gaps on anny_lowres: 2,900-3,300 steps, 10.0-12.0 min (3 models)." in note and "pbs" not in note and "predate" not in note
    text = write_table([tmp_path], "baseline", tmp_path / "out" / "t", command="pytest")
    assert all("**Training**" in p.read_text() for p in text[:3])  # .md, .tex and .csv
    for seed in range(3):  # runs made before the body and steps were recorded
        path = tmp_path / f"{seed}_gaps_tshirt" / "metrics.json"
        path.write_text(json.dumps({k: v for k, v in json.loads(path.read_text()).items() if k not in ("train_steps", "train_body")}))
    shutil.rmtree(tmp_path / "5_gaps_tshirt")
    note = training_note(collect([tmp_path]))
    assert "gaps: 10.0-12.0 min (3 models)." in note and "the runs predate their recording" in note


def test_a_per_run_table_keeps_seeds_apart(tmp_path):
    from drapebench.report import run_table

    df = _seeded_runs(tmp_path, [1.0, 2.0, 4.0])
    t = run_table(df, pd.DataFrame(), ["eps_e"])
    assert list(t.loc["gaps", "seed"]) == ["0", "1", "2"] and list(t.loc["gaps", "eps_e"]) == ["1.000", "2.000", "4.000"]


def test_runs_on_a_gpu_write_a_gpu_table_beside_the_cpu_one(tmp_path):
    import json

    _seeded_runs(tmp_path, [1.0, 2.0, 4.0])
    for f in tmp_path.rglob("metrics.json"):
        f.write_text(json.dumps({**json.loads(f.read_text()), "device": "cuda"}))
    paths = write_table([tmp_path], "baseline", tmp_path / "out" / "gaps_table1", command="pytest")
    assert [p.name for p in paths] == ["gaps_table1_gpu.md", "gaps_table1_gpu.tex", "gaps_table1_gpu.csv", "gaps_table1_gpu_runtime.png"]
    f = next(tmp_path.rglob("0_gaps_tshirt/metrics.json"))
    f.write_text(json.dumps({**json.loads(f.read_text()), "device": "cpu"}))
    with pytest.raises(ValueError, match="mix devices"):
        write_table([tmp_path], "baseline", tmp_path / "out" / "t", command="pytest")


def test_fig10_table_draws_its_metrics_as_bars_over_seeds(tmp_path, monkeypatch):
    from drapebench import report

    df = collect([FIXTURES])
    df = df.assign(hem_drop_mm=[5.0, 7.0, 1.0, 2.0], seed=[0, 1, 0, 1])
    drawn = {}
    monkeypatch.setattr(report, "collect", lambda dirs: df)
    real = report.metric_bars_plot
    monkeypatch.setattr(report, "metric_bars_plot", lambda d, metrics, path, title="": drawn.setdefault("m", metrics) and real(d, metrics, path, title))
    paths = write_table([FIXTURES], "gensim_fig10", tmp_path / "fig10", command="pytest")
    bars = paths[-1]
    assert bars.name == "fig10_bars.png" and bars.read_bytes()[:4] == b"\x89PNG" and bars.stat().st_size > 5000
    assert drawn["m"] == ["hem_drop_mm", "eps_e"]
    assert report.seed_stats(df[df["method"] == df["method"].iloc[0]], "hem_drop_mm")[2] == 2


def test_loss_gap_closed_is_the_share_of_the_untrained_to_optimum_gap(tmp_path):
    import json
    import shutil

    from drapebench.report import collect

    runs = [("gaps", "1,-1", 2.0, 4.0), ("gaps_optimum", "1,-1", 1.0, 4.0), ("gaps", "2,0", 3.0, 3.5), ("gaps_kext1", "1,-1", 3.0, 4.0),
            ("gaps", "3,0", 3.0, 3.0), ("gaps_optimum", "3,0", 3.0, 3.0)]
    for i, (method, shape, loss, start) in enumerate(runs):
        d = tmp_path / f"{i}_{method}"
        shutil.copytree(FIXTURES / "0_lbs_tshirt", d)
        rec = {**json.loads((d / "metrics.json").read_text()), "method": method, "shape": shape, "gaps_loss": loss, "gaps_loss@untrained": start}
        (d / "metrics.json").write_text(json.dumps(rec))
    gap = collect([tmp_path])["loss_gap_closed"].tolist()
    assert gap[0] == pytest.approx(100 * (4.0 - 2.0) / (4.0 - 1.0))  # two thirds of the way from its start to the optimum
    assert np.isnan(gap[2]) and np.isnan(gap[3])  # no optimum of that scene / of that loss (gaps_kext1_optimum): no column value
    assert np.isnan(gap[4])  # the optimum is not below the start: no gap to close (not inf)
    md = write_table([tmp_path], "gaps_heldout_tshirt", tmp_path / "h")[0].read_text()
    assert "gap closed (%)" in md and "66.7" in md
    header = next(line for line in md.splitlines() if line.startswith("| method"))
    columns = [c.strip() for c in header.strip("|").split("|")]
    assert {"GAPS loss (J)", "GAPS loss (J) [untrained]"} <= set(columns)  # the loss the gap is read from, beside it


def test_the_scene_line_names_the_body_shapes_of_the_runs():
    from drapebench.report import scene

    df = pd.DataFrame({"garment": ["tshirt", "tshirt"], "body": ["anny"] * 2, "shape": ["mean", "b0=-1,b1=1.5"], "motion": ["kick"] * 2})
    assert scene(df) == "Scene: garments tshirt; body anny (shapes mean / b0=-1,b1=1.5); motions kick; reference drape none."
    assert "(shape b0=-1,b1=1.5);" in scene(df.iloc[1:])


def test_a_cell_of_two_seeds_gives_their_mean_std_and_n(tmp_path):
    t = table(_seeded_runs(tmp_path, [1.0, 2.0]), ["eps_e"])
    assert t.loc["gaps", ("tshirt", "ε_e (%)")] == f"1.500 ± {np.std([1.0, 2.0], ddof=1):.3f} (n=2)"


def test_a_table_names_its_runs_presets_and_the_scoreboard_judges_it_by_them(tmp_path):
    """A table written from runs records the training and reference-set presets their configs name; the scoreboard
    judges its rows by those presets' files (a _gpu table of train=cpu runs is on the cpu track), and a table that
    mixes presets says so."""
    from drapebench.claims import read_table
    from drapebench.report import presets_note

    _seeded_runs(tmp_path / "runs", [1.0, 2.0, 4.0])
    for seed in range(3):
        (tmp_path / "runs" / f"{seed}_gaps_tshirt" / "config.yaml").write_text("train:\n  name: cpu\ndata:\n  name: cpu\n")
    assert presets_note(collect([tmp_path / "runs"])) == ""  # pbs's run names none: not all runs say
    (tmp_path / "runs" / "9_pbs_tshirt" / "config.yaml").write_text("train:\n  name: cpu\ndata:\n  name: cpu\n")
    paths = write_table([tmp_path / "runs"], "baseline", tmp_path / "out" / "t_gpu", command="pytest")
    assert "**Presets**: train=cpu, data=cpu." in paths[2].read_text()
    assert read_table(paths[2]).track == "cpu"  # a _gpu name, but the runs read the cpu presets
    (tmp_path / "runs" / "0_gaps_tshirt" / "config.yaml").write_text("train:\n  name: paper\ndata:\n  name: cpu\n")
    assert presets_note(collect([tmp_path / "runs"])).startswith("**Mixed presets**")
    for seed in range(3):
        (tmp_path / "runs" / f"{seed}_gaps_tshirt" / "config.yaml").write_text("train:\n  name: paper\ndata:\n  name: cpu\n")
    (tmp_path / "runs" / "9_pbs_tshirt" / "config.yaml").write_text("train:\n  name: paper\ndata:\n  name: cpu\n")
    paths = write_table([tmp_path / "runs"], "baseline", tmp_path / "out2" / "t", command="pytest")
    assert read_table(paths[2]).track == "paper+cpu"


def test_a_model_whose_runs_read_two_trainings_of_it_is_named(tmp_path):
    """One checkpoint path, two trainings (a resumed one differs): the table says its cells mix models; one training
    read by every run, or runs that recorded no hash, say nothing."""
    from drapebench.report import mixed_models_note

    ckpt = "cache/checkpoints/vae_96d358058bc9a0f5.pt"
    df = pd.DataFrame({"method": ["vae", "vae", "lbs"], "checkpoint": [ckpt, ckpt, None], "model_hash": ["a" * 12, "b" * 12, None]})
    note = mixed_models_note(df)
    assert "vae (vae_96d358058bc9a0f5.pt): aaaaaaaaaaaa, bbbbbbbbbbbb" in note and "Mixed trainings" in note
    assert mixed_models_note(df.assign(model_hash=["a" * 12, "a" * 12, None])) == ""
    assert mixed_models_note(df.drop(columns="model_hash")) == ""



def test_two_trainings_are_named_when_one_run_came_from_the_archive():
    """The archive names a checkpoint from cache/checkpoints/ on, a local run by its machine's path: one model."""
    from drapebench.report import mixed_models_note

    name = "cache/checkpoints/vae_96d358058bc9a0f5.pt"
    df = pd.DataFrame({"method": ["vae", "vae"], "checkpoint": [name, f"/srv/me/drapebench/data/{name}"], "model_hash": ["a" * 12, "b" * 12]})
    assert "vae (vae_96d358058bc9a0f5.pt): aaaaaaaaaaaa, bbbbbbbbbbbb" in mixed_models_note(df)

def test_a_log_axis_labels_few_minor_ticks_where_they_would_crowd():
    """Over one decade and a half the minor ticks at 2, 3 and 5 are labelled, not 0.6, 0.7, 0.8 and 0.9 (which ran
    into each other and into 1); within a factor 3 every one; over several decades none."""
    from drapebench.report import _minor_labels

    ticks = [0.5, 0.6, 0.7, 0.8, 0.9, 2, 3, 4, 5, 6, 20, 30]
    assert [_minor_labels(20)(v, 0) for v in ticks] == ["0.5", "", "", "", "", "2", "3", "", "5", "", "20", "30"]
    assert _minor_labels(2)(0.7, 0) == "0.7" and _minor_labels(100)(2, 0) == ""


def _runs_of(tmp_path, experiment: str) -> Path:
    """A copy of the fixture runs that record ``experiment``."""
    import shutil

    runs = tmp_path / experiment
    shutil.copytree(FIXTURES, runs)
    for f in runs.rglob("metrics.json"):
        f.write_text(json.dumps({**json.loads(f.read_text()), "experiment": experiment}))
    return runs


def test_the_report_command_writes_the_table_the_runs_experiment_makes(tmp_path, capsys):
    from drapebench.report import main

    main([str(_runs_of(tmp_path, "gensim_pen")), "--out", str(tmp_path / "pen")])  # no --table: the runs' experiment's
    assert (tmp_path / "pen.md").read_text().startswith("# gensim_pen")
    main([str(FIXTURES), "--out", str(tmp_path / "plain")])  # plain runs (no experiment): the baseline layout
    assert (tmp_path / "plain.md").read_text().startswith("# baseline")
    with pytest.raises(SystemExit):  # two tables read vae_table1's runs: the user chooses
        main([str(_runs_of(tmp_path, "vae_table1")), "--out", str(tmp_path / "vae")])
    err = capsys.readouterr().err
    assert "pass --table" in err and "vae_table1_dress" in err and not (tmp_path / "vae.md").exists()
    main([str(FIXTURES.parent / "runs"), "--table", "baseline", "--out", str(tmp_path / "b")])
    assert "warning" not in capsys.readouterr().err
    main([str(tmp_path / "gensim_pen"), "--table", "baseline", "--out", str(tmp_path / "mismatch")])
    assert "warning: table baseline is made by experiment baseline; the runs are from gensim_pen" in capsys.readouterr().err
    main([str(_runs_of(tmp_path, "smoke")), "--out", str(tmp_path / "smoke")])  # an experiment no table reads
    assert (tmp_path / "smoke.md").read_text().startswith("# baseline") and "which no table reads" in capsys.readouterr().err
    main([str(_runs_of(tmp_path, "gensim_table1")), "--out", str(tmp_path / "t1")])  # the config's name, its sweeps rename
    assert (tmp_path / "t1.md").read_text().startswith("# gensim_table1")


def test_a_bug_behind_the_report_command_keeps_its_traceback(monkeypatch):
    """Only what the user asked of the runs is a usage error; a ValueError from the code is not disguised as one."""
    import drapebench.report as report

    monkeypatch.setattr(report, "write_table", lambda *a, **k: np.zeros(2) + np.zeros(3))
    with pytest.raises(ValueError, match="broadcast"):
        report.main([str(FIXTURES), "--table", "baseline"])


def test_the_bars_plot_draws_a_dot_per_seed_when_a_scene_s_runs_repeat(tmp_path):
    """The same scene and seed given twice (a sweep and its rerun) made the dots' x and y differ in length."""
    import shutil

    from drapebench.report import main

    shutil.copytree(FIXTURES, tmp_path / "again")
    main([str(FIXTURES), str(tmp_path / "again"), "--table", "gensim_fig10", "--out", str(tmp_path / "t")])
    assert (tmp_path / "t.md").exists()


@pytest.mark.parametrize("argv, says", [
    (["{tmp}/nope"], "not a folder: {tmp}/nope"),
    (["{fixtures}", "--table", "baseline", "--methods", "LBS"], "no run of method(s) LBS"),
    (["{tmp}/empty"], "no metrics.json below {tmp}/empty"),
    (["{tmp}/empty", "--loss-curves"], "no losses.csv below {tmp}/empty"),
    (["{tmp}/empty", "--loss-curves", "--out", "{tmp}/x"], "--out is not read with --loss-curves"),
    (["{fixtures}", "--evaluations", "--out", "{tmp}/x"], "no evaluations.csv in the runs below {fixtures}"),
    (["--claims", "{tmp}/nope"], "--claims reads the committed tables (*.csv) of a folder; {tmp}/nope is not a folder"),
    (["--claims", "{tmp}/empty"], "{tmp}/empty holds none"),
])  # fmt: skip
def test_the_report_command_stops_on_a_path_or_name_it_cannot_read_with_a_message(tmp_path, capsys, argv, says):
    from drapebench.report import main

    (tmp_path / "empty").mkdir()
    fill = {"tmp": str(tmp_path), "fixtures": str(FIXTURES)}
    with pytest.raises(SystemExit) as stop:
        main([a.format(**fill) for a in argv])
    assert stop.value.code == 2 and says.format(**fill) in capsys.readouterr().err  # argparse's usage error, not a traceback
    assert not (tmp_path / "nope").exists() and sorted(p.name for p in tmp_path.iterdir()) == ["empty"]  # nothing written
