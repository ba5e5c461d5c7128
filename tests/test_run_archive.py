"""A regeneration's archive of finished runs (drapebench/run_archive.py): what it keeps, what it restores, and that a
restored run counts as finished and reads as the original in a table."""

import json

import numpy as np
import pandas as pd

from drapebench.report import collect
from drapebench.reproduce import Job, finished
from drapebench.run_archive import sync
from drapebench.table_specs import Sweep

AT = "a" * 40


def _run(root, rel, overrides, train_s=None, failed=False):
    d = root / rel
    d.mkdir(parents=True)
    metrics = {"method": "gaps", "garment": "tshirt", "seed": 0, "eps_c": 0.1, **({"train_s": train_s} if train_s else {})}
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


def test_a_run_made_again_replaces_its_record_and_a_finished_run_is_not_overwritten(tmp_path):
    root, archive = tmp_path / "runs", tmp_path / "archive"
    run = _run(root, "t/0/0_x", ["seed=0"])
    sync(root, archive)
    (run / "reproduce.json").write_text(json.dumps({"overrides": ["seed=0"], "commit": "c" * 40, "experiment": "t"}))
    (run / "metrics.json").write_text(json.dumps({"method": "gaps", "eps_c": 0.2}))
    assert sync(root, archive) == (1, 0)  # made again at another commit: its new record replaces the old
    assert json.loads((archive / "t/0/0_x/metrics.json").read_text())["eps_c"] == 0.2
    (archive / "t/0/0_x/metrics.json").write_text(json.dumps({"method": "gaps", "eps_c": 9.9}))
    (archive / "t/0/0_x/reproduce.json").write_text((run / "reproduce.json").read_text())
    assert sync(root, archive) == (0, 0) and json.loads((run / "metrics.json").read_text())["eps_c"] == 0.2  # the live run stays


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
