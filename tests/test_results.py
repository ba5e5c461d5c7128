"""prediction.h5 round trip and atomic writes; the report reads run records without the pipeline."""

import ast
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest
import torch

from drapebench.results import StoredFrames, prediction_writer, read_prediction, write_prediction


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



def test_a_prediction_written_in_chunks_is_the_whole_one_and_reads_back_a_chunk_at_a_time(tmp_path):
    x, faces = torch.rand(10, 7, 3), torch.tensor([[0, 1, 2]])
    write_prediction(tmp_path / "whole.h5", x, faces, method="lbs")
    with prediction_writer(tmp_path / "chunks.h5", 10, faces, 7, method="lbs") as writer:
        for a in range(0, 10, 3):
            writer.append(x[a : a + 3])
        assert not (tmp_path / "chunks.h5").exists()  # a temporary file until the block ends
    (v, f, attrs), (v_whole, f_whole, attrs_whole) = read_prediction(tmp_path / "chunks.h5"), read_prediction(tmp_path / "whole.h5")
    assert np.array_equal(v, v_whole) and np.array_equal(f, f_whole) and attrs == attrs_whole
    stored = StoredFrames(tmp_path / "chunks.h5", writer.digest)
    assert stored.shape == x.shape and len(stored) == 10 and stored.dtype == torch.float32
    assert torch.equal(stored[4:9], x[4:9]) and torch.equal(stored[8:20], x[8:])
    other = tmp_path / "other.h5"
    with prediction_writer(other, 10, faces, 7) as again:
        again.append(x.clone())
    y = x.clone()
    y[9, 6, 2] += 1e-3
    with prediction_writer(other, 10, faces, 7) as changed:
        changed.append(y)
    assert again.digest == writer.digest != changed.digest  # the frames' content, however they were written


def test_a_prediction_missing_frames_is_not_kept(tmp_path):
    path = tmp_path / "p.h5"
    with pytest.raises(ValueError, match="8 of 10 frames were written"):
        with prediction_writer(path, 10, torch.tensor([[0, 1, 2]]), 7) as writer:
            writer.append(torch.zeros(8, 7, 3))
    with pytest.raises(ValueError, match="do not fit"):
        with prediction_writer(path, 10, torch.tensor([[0, 1, 2]]), 7) as writer:
            writer.append(torch.zeros(11, 7, 3))
    assert list(tmp_path.iterdir()) == []


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


def test_progress_lines_come_across_stages_so_no_set_up_between_them_goes_silent(monkeypatch, caplog):
    """Where no bar is drawn: a new stage logs its first line as soon as LOG_EVERY_S has passed since the last line of
    any stage, and a stage that ran that long logs its last line when it ends (a clock that the test moves)."""
    import logging
    from types import SimpleNamespace

    import drapebench.progress as progress_module

    clock = SimpleNamespace(t=100.0)
    monkeypatch.delenv("CI", raising=False)
    monkeypatch.delenv("DRAPEBENCH_PROGRESS", raising=False)
    monkeypatch.setattr(sys.stderr, "isatty", lambda: False)
    monkeypatch.setattr(progress_module, "time", SimpleNamespace(monotonic=lambda: clock.t))
    monkeypatch.setattr(progress_module._LogLines, "last", 100.0)
    with caplog.at_level(logging.INFO, logger="drapebench"):
        drape = progress_module.progress(total=4, desc="drape", unit="chunk")  # 0 s since the last line: silent
        for dt in (6.0, 1.0):
            clock.t += dt
            drape.update(1)
            drape.refresh()
        clock.t += 1.0
        drape.close()  # ran 8 s: its last line
        clock.t += 6.0  # set-up between the stages
        metrics = progress_module.progress(total=3, desc="metrics", unit="frames")  # 6 s since the last line: at once
        clock.t += 1.0
        metrics.update(3)
        metrics.close()  # 1 s since the last line and a short stage: silent
    assert [r.getMessage().split(" (")[0] for r in caplog.records] == ["drape: 1/4 chunk", "drape: 2/4 chunk", "metrics: 0/3 frames"]


def test_a_step_slower_than_the_log_interval_still_logs_lines_and_a_closed_stage_none(monkeypatch, caplog):
    """Where no bar is drawn: a stage whose steps each take longer than LOG_EVERY_S (a large chunk on a loaded
    machine) logs its line again while a step runs, so the log never goes silent longer than about LOG_EVERY_S;
    once the stage is closed, its thread logs nothing more; a stage of fast steps logs only its own lines."""
    import logging
    import time

    import drapebench.progress as progress_module

    monkeypatch.delenv("CI", raising=False)
    monkeypatch.delenv("DRAPEBENCH_PROGRESS", raising=False)
    monkeypatch.setattr(progress_module, "LOG_EVERY_S", 0.2)
    monkeypatch.setattr(progress_module, "HEARTBEAT_S", 0.02)
    monkeypatch.setattr(sys.stderr, "isatty", lambda: False)
    with caplog.at_level(logging.INFO, logger="drapebench"):
        bar = progress_module.progress(total=2, desc="metrics", unit="frames")
        for _ in range(2):
            time.sleep(1.5)  # one slow chunk
            bar.update(1)
        bar.close()
        n_closed = len(caplog.records)
        time.sleep(0.5)
    times = [r.created for r in caplog.records]
    assert any(r.getMessage().endswith("a step still running") and r.getMessage().startswith("metrics: 0/2") for r in caplog.records)
    assert max(b - a for a, b in zip(times, times[1:])) < 1.0  # s: without the thread, 1.5 between the updates' lines
    assert len(caplog.records) == n_closed  # nothing after the stage closed
    caplog.clear()
    monkeypatch.setattr(progress_module, "LOG_EVERY_S", 0.5)
    with caplog.at_level(logging.INFO, logger="drapebench"):
        fast = progress_module.progress(total=60, desc="fast", unit="frames")
        for _ in range(60):
            time.sleep(0.02)  # steps faster than the interval: the bar's own lines, none marked as a step still running
            fast.update(1)
        fast.close()
    assert caplog.records and not any("still running" in r.getMessage() for r in caplog.records), [r.getMessage() for r in caplog.records]


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


def test_a_training_preset_is_part_of_a_learning_method_s_code_on_its_own_track_only():
    """A cached model is keyed by its configuration: a changed training or reference-set preset (conf/train,
    conf/data) retrains it, so rows from before the change are stale for the methods that train and not for lbs;
    only for the tables made with that preset, though (train=cpu: the CPU tables; train=paper: the _gpu ones), and
    a cached model's own stored code leaves presets out (its key holds them)."""
    from drapebench.staleness import budget_files, code_files, known, learns, track_of

    assert learns("gaps") and learns("gensim") and learns("vae") and not learns("lbs") and not learns("pbs")
    presets = ("conf/train/", "conf/data/")
    for impl in ("gaps", "gensim", "vae"):
        assert {"conf/train/cpu.yaml", "conf/data/cpu.yaml"} <= set(code_files(impl, "cpu"))
        assert not any(f.endswith("/paper.yaml") for f in code_files(impl, "cpu"))
        assert {"conf/train/paper.yaml", "conf/data/paper.yaml"} <= set(code_files(impl, "paper"))
        assert not any(f.startswith(presets) or f.count("/") > 2 for f in code_files(impl))  # a checkpoint's code: no presets
    assert budget_files("gaps", "cpu") == ["conf/method/gaps_budget/cpu.yaml"] == budget_files("gaps", "cpu", known("HEAD"))
    assert budget_files("vae", "paper") == ["conf/method/vae_data/paper.yaml"]  # listed though absent: its creation counts
    mixed = code_files("vae", "paper+cpu")  # train=paper with data=cpu: each preset its own file
    assert "conf/train/paper.yaml" in mixed and "conf/data/cpu.yaml" in mixed and "conf/data/paper.yaml" not in mixed
    assert budget_files("gaps", "paper+cpu") == ["conf/method/gaps_budget/paper.yaml", "conf/method/gaps_budget/cpu.yaml"]
    assert not any(f.startswith(presets) for f in code_files("lbs", "cpu") + code_files("pbs", "paper"))
    assert (track_of("vae_table2"), track_of("vae_table2_gpu")) == ("cpu", "paper")


def test_a_row_is_judged_by_its_own_track_s_code(tmp_path):
    """A _gpu table's rows are judged by the paper presets' fingerprint, a CPU table's by the cpu ones'."""
    from drapebench.staleness import current_code, known, stale_rows

    head = known("HEAD")
    code = {**current_code(), "vae@paper": "000000000000"}  # the GPU presets changed; the CPU ones did not
    assert stale_rows(["vae"], {}, [head], code) == {}
    assert "methods/vae" in stale_rows(["vae"], {}, [head], code, track="paper")["vae"]


def test_a_row_beside_a_dirty_one_is_stale_for_that_row_s_commit_not_for_history():
    """A table with one row run on uncommitted changes: the clean rows name that label as the cause, not a history
    that is in fact one line."""
    from drapebench.staleness import current_code, known, stale_rows

    head, dirty = known("HEAD"), known("HEAD")[:7] + "-dirty"
    why = stale_rows(["lbs", "pbs"], {"lbs": [head], "pbs": [dirty]}, [head, dirty], current_code())
    assert f"{dirty} is not in this repository's history" in why["lbs"] and "one line of history" not in why["lbs"]


def test_an_untracked_file_in_a_method_s_folder_leaves_its_fingerprint_alone():
    """A scratch file beside a method's code is not its code (runs' labels leave untracked files out too)."""
    from drapebench import staleness
    from drapebench.cache import PROJECT_ROOT

    scratch = PROJECT_ROOT / "methods" / "lbs" / "_scratch_untracked_test.py"
    before = staleness.fingerprint("lbs")
    try:
        scratch.write_text("x = 1\n")
        staleness.fingerprint.cache_clear()
        assert staleness.fingerprint("lbs") == before
    finally:
        scratch.unlink(missing_ok=True)
        staleness.fingerprint.cache_clear()


def test_tables_written_by_a_regeneration_do_not_make_its_runs_dirty(tmp_path, monkeypatch):
    """reproduce writes reports/ and README.md's status into the tree: the runs after it still name the clean commit;
    a changed source file, or an untracked one where runs read code, makes them "-dirty"."""
    import subprocess

    from drapebench import results

    git = lambda *a: subprocess.run(["git", "-C", str(tmp_path), *a], check=True, capture_output=True)  # noqa: E731
    git("init", "-q")
    (tmp_path / "reports").mkdir()
    for name, text in (("code.py", "x = 1\n"), ("README.md", "status\n"), ("reports/t.md", "table\n")):
        (tmp_path / name).write_text(text)
    git("add", "-A")
    git("-c", "user.name=t", "-c", "user.email=t@t", "commit", "-qm", "c")
    monkeypatch.setattr(results, "PROJECT_ROOT", tmp_path)
    (tmp_path / "reports" / "t.md").write_text("regenerated\n")
    (tmp_path / "README.md").write_text("new status\n")
    clean = results._head_commit()
    assert len(clean) == 40 and not clean.endswith("-dirty")
    (tmp_path / "notes.txt").write_text("not code\n")  # an untracked file that no run reads
    assert results._head_commit() == clean
    (tmp_path / "conf" / "method").mkdir(parents=True)
    (tmp_path / "conf" / "method" / "scratch.yaml").write_text("name: scratch\n")  # one a sweep's glob(*) would run
    assert results._head_commit() == clean + "-dirty" and results.untracked_code() == ["conf/method/scratch.yaml"]
    assert results.uncommitted_code() == ["conf/method/scratch.yaml"]
    (tmp_path / "conf" / "method" / "scratch.yaml").unlink()
    (tmp_path / "code.py").write_text("x = 2\n")
    assert results._head_commit() == clean + "-dirty" and results.uncommitted_code() == []  # not under CODE
    (tmp_path / "run.py").write_text("y = 1\n")
    git("add", "run.py")
    git("-c", "user.name=t", "-c", "user.email=t@t", "commit", "-qm", "run.py")
    (tmp_path / "run.py").write_text("y = 2\n")  # a tracked file under CODE, edited
    assert results.uncommitted_code() == ["run.py"]


def test_an_ignored_config_a_sweep_would_run_is_code(tmp_path, monkeypatch):
    """Hydra's ``glob(*)`` sweeps an ignored ``conf/method/x.local.yaml`` too: it makes the label dirty; an ignored
    compiled file does not."""
    import subprocess

    from drapebench import results

    git = lambda *a: subprocess.run(["git", "-C", str(tmp_path), *a], check=True, capture_output=True)  # noqa: E731
    git("init", "-q")
    (tmp_path / ".gitignore").write_text("*.local.yaml\n__pycache__/\n")
    (tmp_path / "run.py").write_text("x = 1\n")
    git("add", "-A")
    git("-c", "user.name=t", "-c", "user.email=t@t", "commit", "-qm", "c")
    monkeypatch.setattr(results, "PROJECT_ROOT", tmp_path)
    (tmp_path / "conf" / "method" / "__pycache__").mkdir(parents=True)
    (tmp_path / "conf" / "method" / "__pycache__" / "x.cpython-311.pyc").write_bytes(b"\0")
    assert results.untracked_code() == [] and not results._head_commit().endswith("-dirty")
    (tmp_path / "conf" / "method" / "scratch.local.yaml").write_text("name: scratch\n")
    assert results.untracked_code() == ["conf/method/scratch.local.yaml"] and results._head_commit().endswith("-dirty")
