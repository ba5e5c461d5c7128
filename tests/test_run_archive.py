"""A regeneration's archive of finished runs (drapebench/run_archive.py): what it keeps, what it restores, and that a
restored run counts as finished and reads as the original in a table."""

import json

import numpy as np
import pandas as pd
import pytest

from drapebench.report import collect
from drapebench.reproduce import Job, finished
from drapebench.run_archive import main, portable_checkpoint, sync
from drapebench.table_specs import Sweep

AT = "a" * 40


def _run(root, rel, overrides, train_s=None, failed=False):
    d = root / rel
    d.mkdir(parents=True)
    metrics = {"method": "gaps", "garment": "tshirt", "seed": 0, "eps_c": 0.1, "checkpoint": "/machine/data/cache/checkpoints/gaps_0.pt",
               **({"train_s": train_s} if train_s else {})}
    (d / ("failed.json" if failed else "metrics.json")).write_text(json.dumps(metrics))
    (d / "config.yaml").write_text("method:\n  name: gaps\n")
    (d / "env.json").write_text(json.dumps({"torch_threads": 1}))
    (d / "reproduce.json").write_text(json.dumps({"overrides": overrides, "commit": AT, "experiment": "gaps_table1"}))
    if train_s:
        loss = np.r_[np.linspace(10.0, 1.0, 50), np.ones(50)]
        pd.DataFrame({"step": np.arange(100), "loss": loss}).to_csv(d / "losses.csv", index=False)
    return d


def test_the_archive_keeps_the_records_and_a_new_machine_gets_them_back_as_finished_runs(tmp_path):
    root, archive, fresh = tmp_path / "runs", tmp_path / "archive", tmp_path / "new_machine"
    trained = _run(root, "gaps_table1/0/0_x", ["seed=0"], train_s=600.0)
    _run(root, "gaps_table1/0/1_y", ["seed=1"], failed=True)
    (root / "gaps_table1/0/2_z").mkdir(parents=True)  # unfinished: no stamp, nothing kept
    assert sync(root, archive) == (2, 0)
    kept = archive / "gaps_table1/0/0_x"
    assert not (kept / "losses.csv").exists() and (kept / "metrics.json").exists() and not (archive / "gaps_table1/0/2_z").exists()
    assert sync(root, archive) == (0, 0)  # level
    assert sync(fresh, archive) == (0, 2)
    job = Job("gaps_table1", Sweep("gaps_table1"), ("seed=0",), fresh / "gaps_table1/0/0_x")
    assert finished(job, AT) and not finished(job, "b" * 40)  # restored at its commit: finished there only
    before, after = collect([trained]).iloc[0], collect([job.dir]).iloc[0]
    assert before["converged_s"] == after["converged_s"] and 0 < after["converged_s"] < 600.0  # from losses.csv, then its record
    assert (fresh / "gaps_table1/0/1_y/failed.json").exists()


def test_where_both_hold_a_run_the_one_at_the_regenerations_commit_wins(tmp_path):
    """A run made again at the regeneration's commit replaces its archived record; an archived record at that commit
    replaces an older local run; runs at neither commit, or a sync that names none, leave both as they are."""
    root, archive = tmp_path / "runs", tmp_path / "archive"
    run = _run(root, "t/0/0_x", ["seed=0"])  # at AT
    sync(root, archive)
    new = "c" * 40
    (run / "reproduce.json").write_text(json.dumps({"overrides": ["seed=0"], "commit": new, "experiment": "t"}))
    (run / "metrics.json").write_text(json.dumps({"method": "gaps", "eps_c": 0.2}))
    assert sync(root, archive) == (0, 0) and sync(root, archive, "d" * 40) == (0, 0)  # no commit named, or neither at it
    assert sync(root, archive, new) == (1, 0) and json.loads((archive / "t/0/0_x/metrics.json").read_text())["eps_c"] == 0.2
    old = _run(tmp_path / "old_machine", "t/0/0_x", ["seed=0"])  # a stale local run at AT
    assert sync(old.parents[2], archive, new) == (0, 1)  # the archive's run at the regeneration's commit comes back
    assert json.loads((old / "metrics.json").read_text())["eps_c"] == 0.2


def test_the_archive_never_overwrites_an_unfinished_run_nor_keeps_a_half_copy(tmp_path):
    """A run folder without a stamp (running now, or crashed) is not replaced by its archived record; a leftover
    ``*.tmp`` copy is no run; a restored run recorded again keeps its time to convergence; a run that did not train
    reads none even with a stray converged.json."""
    root, archive = tmp_path / "runs", tmp_path / "archive"
    _run(archive, "t/0/0_x", ["seed=0"])
    _run(archive, "t/0/1_y.tmp", ["seed=1"])
    running = root / "t/0/0_x"
    running.mkdir(parents=True)
    (running / "losses.csv").write_text("step,loss\n0,1\n")
    assert sync(root, archive, AT) == (0, 0) and sorted(p.name for p in running.iterdir()) == ["losses.csv"]
    assert not (root / "t/0/1_y.tmp").exists()
    trained = _run(tmp_path / "first", "t/0/2_z", ["seed=2"], train_s=600.0)
    sync(tmp_path / "first", archive)
    restored = tmp_path / "second"
    sync(restored, archive)
    sync(restored, tmp_path / "archive2")
    assert collect([tmp_path / "archive2/t/0/2_z"]).iloc[0]["converged_s"] == collect([trained]).iloc[0]["converged_s"]
    untrained = _run(tmp_path / "u", "r", ["seed=0"])
    (untrained / "converged.json").write_text(json.dumps({"converged_s": 123.0}))
    assert pd.isna(collect([untrained]).iloc[0].get("converged_s"))


def test_a_regeneration_with_an_archive_records_each_run_as_it_finishes(tmp_path, monkeypatch):
    import drapebench.reproduce as reproduce

    root, archive = tmp_path / "runs", tmp_path / "archive"
    job = Job("t", Sweep("gaps_table1"), ("seed=0",), root / "t/0/0_x")

    def fake_run(job, at, cpus=None):
        _run(root, "t/0/0_x", list(job.overrides))
        return 0

    monkeypatch.setattr(reproduce, "run_job", fake_run)
    assert reproduce.run_all([job], AT, say=lambda *_: None, runner=reproduce._archiving(archive, root)) == []
    assert (archive / "t/0/0_x/reproduce.json").exists()


def test_a_commit_the_repository_does_not_know_or_an_archive_in_the_runs_folder_is_refused(tmp_path, capsys):
    """A mistyped --commit would never match a stamp: both runs would silently stay."""
    import pytest

    for argv, said in (([str(tmp_path / "runs"), str(tmp_path / "archive"), "--commit", "aaaaaaz"], "--commit aaaaaaz: not a commit"),
                       ([str(tmp_path / "runs"), str(tmp_path / "runs" / "archive")], "a folder apart from the runs folder")):
        with pytest.raises(SystemExit):
            main(argv)
        assert said in capsys.readouterr().err


def test_an_archived_record_names_its_checkpoint_without_the_machines_folders(tmp_path):
    """The archive is committed: nothing in it may point at a file outside the repository."""
    _run(tmp_path / "runs", "t/0/0_x", ["seed=0"])
    sync(tmp_path / "runs", tmp_path / "archive")
    kept = json.loads((tmp_path / "archive/t/0/0_x/metrics.json").read_text())
    assert kept["checkpoint"] == "cache/checkpoints/gaps_0.pt" and kept["eps_c"] == 0.1
    assert portable_checkpoint(None) is None and portable_checkpoint("elsewhere/x.pt") == "elsewhere/x.pt"


def test_a_run_made_again_at_the_same_commit_with_another_result_is_named_not_read_silently(tmp_path, capsys):
    """The runs folder and the archive hold one run (same commit and overrides) with different results: a table would
    read the local one, a clone the archived one. The sync names both and changes nothing; the command exits 1."""
    from drapebench import reproduce

    root, archive = tmp_path / "runs", tmp_path / "archive"
    rel = reproduce.plan(["baseline"], root)[0].dir.relative_to(root)  # a run a table plans
    run = _run(root, rel, ["seed=0"])
    assert sync(root, archive) == (1, 0) and sync(root, archive, AT) == (0, 0)  # the record's portable checkpoint is no difference
    (run / "metrics.json").write_text(json.dumps({**json.loads((run / "metrics.json").read_text()), "eps_c": 0.3}))
    with pytest.raises(ValueError, match="other results in the runs folder than in the archive") as err:
        sync(root, archive, AT)
    assert str(run) in str(err.value) and str(archive / rel) in str(err.value)
    assert json.loads((archive / rel / "metrics.json").read_text())["eps_c"] == 0.1  # nothing changed

    assert reproduce.main(["--tables", "baseline", "--write-only", "--runs", str(root), "--archive", str(archive),
                           "--out", str(tmp_path / "out")]) == 1
    assert "delete the stale copy" in capsys.readouterr().err


def test_runs_that_no_table_plans_any_longer_are_named(tmp_path, monkeypatch):
    """A sweep that changed leaves its old runs in the archive, which no table reads: they are named (and the
    committed archive holds none)."""
    from drapebench import results
    from drapebench.cache import PROJECT_ROOT
    from drapebench.reproduce import plan, unplanned

    monkeypatch.setattr(results, "uncommitted_code", lambda root=None: [])  # the plan is the commit's

    kept = plan(["baseline"], tmp_path)[0].dir
    gone = tmp_path / "baseline" / "9" / "0_0123456789"
    for d in (kept, gone):
        d.mkdir(parents=True)
        (d / "reproduce.json").write_text("{}")
    quick = plan(["baseline"], tmp_path, True)[0].dir  # a --quick run is planned too
    quick.mkdir(parents=True)
    (quick / "reproduce.json").write_text("{}")
    assert unplanned(tmp_path) == [gone]
    root = tmp_path / "runs"
    (root / "baseline" / "9" / "0_0123456789").mkdir(parents=True)  # an unplanned run in a runs folder is not recorded back
    for name in ("reproduce.json", "metrics.json"):
        (root / "baseline" / "9" / "0_0123456789" / name).write_text("{}")
    assert sync(root, tmp_path / "archive", planned={kept.relative_to(tmp_path)}) == (0, 0)
    assert unplanned(PROJECT_ROOT / "reports" / "runs") == []


def test_no_run_is_called_unplanned_while_uncommitted_code_may_change_the_plan(tmp_path, monkeypatch):
    """A scratch conf/method/x.yaml moves every later run of a glob(*) sweep to another folder, and an edited
    experiment reorders its runs: the plan is not the commit's, so no archived run is named for deletion."""
    from drapebench import results
    from drapebench.reproduce import plan, unplanned

    gone = tmp_path / "baseline" / "9" / "0_0123456789"
    gone.mkdir(parents=True)
    (gone / "reproduce.json").write_text("{}")
    monkeypatch.setattr(results, "uncommitted_code", lambda root=None: [])
    assert unplanned(tmp_path) == [gone]
    for scratch in ("conf/method/scratch.yaml", "conf/experiment/baseline.yaml"):
        monkeypatch.setattr(results, "uncommitted_code", lambda root=None, s=scratch: [s])
        assert unplanned(tmp_path) is None
    assert plan(["baseline"], tmp_path)  # planning itself is unaffected


@pytest.mark.parametrize("runs, archive, says", [
    ("afile", "archive", "runs {tmp}/afile: a file; give the runs folder"),
    ("runs", "afile", "archive {tmp}/afile: a file; give the archive folder"),
])  # fmt: skip
def test_the_sync_command_refuses_a_file_for_a_folder(tmp_path, runs, archive, says, capsys):
    from drapebench.run_archive import main

    (tmp_path / "runs").mkdir()
    (tmp_path / "afile").write_text("mine\n")
    with pytest.raises(SystemExit):
        main([str(tmp_path / runs), str(tmp_path / archive)])
    assert says.format(tmp=tmp_path) in capsys.readouterr().err and (tmp_path / "afile").read_text() == "mine\n"


def test_the_sync_command_restores_into_a_runs_folder_a_new_machine_lacks(tmp_path):
    from drapebench.run_archive import main

    _run(tmp_path / "old_runs", "t/0/0_x", ["method=lbs"])
    assert main([str(tmp_path / "old_runs"), str(tmp_path / "archive")]) == 0  # recorded
    assert main([str(tmp_path / "new_runs"), str(tmp_path / "archive")]) == 0  # the folder is made and the run restored
    assert (tmp_path / "new_runs" / "t/0/0_x" / "metrics.json").exists()
