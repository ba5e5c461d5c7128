"""prediction.h5 round trip and atomic writes; the report reads run records without the pipeline."""

import ast
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest
import torch

from drapebench.results import read_prediction, write_prediction


def test_prediction_round_trip(tmp_path):
    x = torch.rand(5, 7, 3)
    faces = torch.tensor([[0, 1, 2], [2, 3, 4]])
    write_prediction(tmp_path / "p.h5", x, faces, method="lbs", fps=30.0)
    v, f, attrs = read_prediction(tmp_path / "p.h5")
    assert v.dtype == np.float32 and np.array_equal(v, x.numpy())
    assert np.array_equal(f, faces.numpy()) and attrs["method"] == "lbs" and attrs["fps"] == 30.0


def test_failed_write_keeps_the_old_file(tmp_path):
    path = tmp_path / "p.h5"
    write_prediction(path, torch.zeros(2, 3, 3), torch.tensor([[0, 1, 2]]))
    with pytest.raises(TypeError):
        write_prediction(path, torch.ones(2, 3, 3), torch.tensor([[0, 1, 2]]), bad=object())  # unstorable attribute
    with h5py.File(path) as f:
        assert f["vertices"][()].max() == 0  # the earlier, complete file
    assert [p.name for p in tmp_path.iterdir()] == ["p.h5"]



def test_report_does_not_import_the_pipeline():
    """report.py reads run records through drapebench.results, never through drapebench.experiment (no import circle)."""
    import drapebench.report

    tree = ast.parse(Path(drapebench.report.__file__).read_text())
    imported = {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
    imported |= {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    assert "drapebench.results" in imported and "drapebench.experiment" not in imported


def test_a_run_records_the_commit_its_process_started_with(monkeypatch):
    import subprocess

    from drapebench import results

    started = results.git_commit()
    monkeypatch.setattr(subprocess, "run", lambda *a, **k: subprocess.CompletedProcess(a, 0, stdout="f" * 40, stderr=""))
    assert results._head_commit().startswith("f" * 40)  # the repository moved on (a commit during a sweep) ...
    assert results.git_commit() == started  # ... the runs of this process still name the code they run


def test_a_long_stage_logs_its_progress_with_an_estimate_where_no_bar_is_drawn(monkeypatch, caplog):
    """stderr not a terminal (a log file): a line at most every LOG_EVERY_S with the count and the time left; a stage
    shorter than that logs nothing; under CI nothing."""
    import logging
    import time

    import drapebench.progress as progress_module

    monkeypatch.delenv("CI", raising=False)
    monkeypatch.delenv("DRAPEBENCH_PROGRESS", raising=False)
    monkeypatch.setattr(progress_module, "LOG_EVERY_S", 0.05)
    monkeypatch.setattr(sys.stderr, "isatty", lambda: False)
    with caplog.at_level(logging.INFO, logger="drapebench"):
        for _ in progress_module.progress(range(6), desc="metrics", unit="frames"):
            time.sleep(0.03)
    lines = [r.getMessage() for r in caplog.records]
    assert 1 <= len(lines) <= 4 and all(m.startswith("metrics: ") and "/6 frames" in m and " left (" in m for m in lines)
    caplog.clear()
    with caplog.at_level(logging.INFO, logger="drapebench"):
        list(progress_module.progress(range(3), desc="short"))  # done before the first interval
        monkeypatch.setenv("CI", "1")
        for _ in progress_module.progress(range(3), desc="ci"):
            time.sleep(0.03)
    assert not caplog.records


def test_prediction_h5_keeps_a_float64_drape_float64(tmp_path):
    far = torch.full((3, 4, 3), 30000.0, dtype=torch.float64) + torch.rand(3, 4, 3, dtype=torch.float64) * 1e-3
    write_prediction(tmp_path / "p64.h5", far, torch.tensor([[0, 1, 2]]))
    v, _, _ = read_prediction(tmp_path / "p64.h5")
    assert v.dtype == np.float64 and np.array_equal(v, far.numpy())  # float32 would round it to 2 mm
    write_prediction(tmp_path / "p32.h5", far.float(), torch.tensor([[0, 1, 2]]))
    assert read_prediction(tmp_path / "p32.h5")[0].dtype == np.float32


def test_a_method_s_diagnostics_are_described_by_its_own_declaration_not_the_library_s():
    from drapebench.results import METRICS, legend, metric_catalogue, metric_label

    catalogue = metric_catalogue()
    declared = set(catalogue) - set(METRICS)
    assert declared and not declared & set(METRICS)  # the methods' diagnostics live beside their code only
    name = sorted(declared)[0]
    assert metric_label(name) == catalogue[name].label and catalogue[name].meaning in legend([name])
    assert sum(info.own_loss for info in catalogue.values()) >= 1  # the report's loss_gap_closed reads it


def test_a_method_redeclaring_a_library_metric_is_refused_naming_it(monkeypatch):
    from drapebench import plugins, results

    monkeypatch.setattr(plugins, "declared", lambda module, attr: [("somepkg", {"eps_c": results.METRICS["eps_c"]})])
    results._catalogue.cache_clear()
    try:
        with pytest.raises(ValueError, match="somepkg.metrics declares 'eps_c'"):
            results._catalogue(("somepkg",))
    finally:
        results._catalogue.cache_clear()


def test_a_method_s_declarations_are_not_part_of_its_code_fingerprint():
    from drapebench.staleness import makes_numbers

    assert makes_numbers("methods/gaps/method.py") and makes_numbers("methods/gaps/sub/metrics.py")
    assert not any(makes_numbers(f"methods/gaps/{m}.py") for m in ("metrics", "claims", "tables"))
