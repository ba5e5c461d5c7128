"""The MLflow tracker: a sweep's runs read back through MLflow's client; history, failures and tracker=none."""

import json
import logging
import os
import subprocess
import sys
from pathlib import Path

import pytest
from omegaconf import OmegaConf

from drapebench.tracker import artifact_location, flat_params, log_run, metric_name, track_run, tracking_uri

ROOT = Path(__file__).resolve().parents[1]
TINY = ["body=anny_lowres", "motion.n_frames=4", "motion.transition=1", "viz=none"]


def _compose(overrides):
    from hydra import compose, initialize_config_dir

    from drapebench.schema import register

    register()
    with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
        return compose("config", overrides=overrides)


def test_a_sweep_is_one_experiment_whose_runs_mlflow_reads_back(tmp_path):
    from mlflow.tracking import MlflowClient

    uri = f"sqlite:///{tmp_path / 'mlflow.db'}"
    sweep = tmp_path / "sweep"
    env = dict(os.environ, MLFLOW_TRACKING_URI=uri, DRAPEBENCH_PROGRESS="0", HYDRA_FULL_ERROR="1")
    p = subprocess.run([sys.executable, str(ROOT / "run.py"), "-m", "method=lbs", "seed=0,1", *TINY, "experiment_name=tracked",
                        f"hydra.sweep.dir={sweep}"], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)  # fmt: skip
    assert p.returncode == 0, p.stderr[-3000:]
    client = MlflowClient(uri)
    experiment = client.get_experiment_by_name("tracked")
    runs = client.search_runs([experiment.experiment_id])
    assert sorted(r.data.tags["seed"] for r in runs) == ["0", "1"]
    for run in runs:
        folder = Path(run.data.tags["run_dir"])
        record = json.loads((folder / "metrics.json").read_text())
        assert folder.parent == sweep.resolve() and run.data.tags["sweep"] == str(sweep.resolve())
        assert run.info.status == "FINISHED" and run.info.run_name == folder.name
        tags = run.data.tags
        assert (tags["method"], tags["garment"], tags["body"], tags["motion"]) == ("lbs", "tshirt", "anny_lowres", "walk")
        assert tags["commit"] == record["commit"] == tags["mlflow.source.git.commit"]
        assert run.data.params["seed"] == tags["seed"] and run.data.params["method.name"] == "lbs"
        assert run.data.params["motion.n_frames"] == "4" and run.data.params["tracker.name"] == "mlflow"
        for key in ("eps_e", "eps_a", "eps_c", "penetration_mm", "ms_per_frame"):
            assert run.data.metrics[key] == pytest.approx(record[key], rel=1e-12), key
        shipped = {a.path for a in client.list_artifacts(run.info.run_id)}
        assert {"metrics.json", "frames.csv", "config.yaml", "prediction.h5", "env.json"} <= shipped
        copy = Path(client.download_artifacts(run.info.run_id, "metrics.json", str(tmp_path / run.info.run_id)))
        assert json.loads(copy.read_text()) == record


def test_training_losses_are_metric_history_and_a_failed_run_is_marked_failed(tmp_path):
    from mlflow.tracking import MlflowClient

    uri = f"sqlite:///{tmp_path / 'mlflow.db'}"
    cfg = _compose(["method=gaps", "experiment_name=history"])
    out = tmp_path / "run"
    out.mkdir()
    (out / "losses.csv").write_text("step,epoch,loss,strain\n1,0,3.0,2.0\n2,0,2.5,\n3,1,2.0,1.0\n")  # a term missing at step 2
    (out / "evaluations.csv").write_text("epoch,step,colliding\n0,2,5.0\n")
    record = {"method": "gaps", "seed": 0, "eps_e": 2.5, "eps_e@untrained": 3.5, "vertex_error_mm": float("nan"), "commit": "abc"}
    run_id = log_run(cfg, out, record, uri)
    client = MlflowClient(uri)
    assert client.get_run(run_id).info.artifact_uri.startswith((tmp_path / "mlartifacts").as_uri())
    assert [(m.step, m.value) for m in client.get_metric_history(run_id, "train/loss")] == [(1, 3.0), (2, 2.5), (3, 2.0)]
    assert [(m.step, m.value) for m in client.get_metric_history(run_id, "train/strain")] == [(1, 2.0), (3, 1.0)]
    assert [(m.step, m.value) for m in client.get_metric_history(run_id, "eval/colliding")] == [(2, 5.0)]
    run = client.get_run(run_id)
    assert run.data.metrics["eps_e"] == 2.5 and run.data.metrics["eps_e/untrained"] == 3.5
    assert "vertex_error_mm" not in run.data.metrics and "seed" not in run.data.metrics  # NaN: no reference; the seed is a tag
    assert run.data.params["method.params.canonical"] == "relaxed" and run.info.status == "FINISHED"
    failed = log_run(cfg, out, {"status": "failed", "error": "TrainingDiverged", "seed": 0}, uri)
    assert client.get_run(failed).info.status == "FAILED" and client.get_run(failed).data.tags["status"] == "failed"


def test_a_tracker_that_cannot_log_warns_and_tracker_none_logs_nothing(tmp_path, caplog):
    bad = tmp_path / "a_file"
    bad.write_text("not a folder")
    cfg = _compose([f"tracker.uri=sqlite:///{bad}/mlflow.db"])
    with caplog.at_level(logging.WARNING, logger="drapebench"):
        assert track_run(cfg, tmp_path, {"eps_e": 1.0}) is None
    assert "the run was not logged to MLflow" in caplog.text and "tracker=none" in caplog.text
    assert track_run(_compose(["tracker=none", f"tracker.uri=sqlite:///{tmp_path / 'x.db'}"]), tmp_path, {"eps_e": 1.0}) is None
    assert not (tmp_path / "x.db").exists()


def test_the_default_store_is_the_projects_and_the_environment_overrides_it(monkeypatch):
    from drapebench.cache import data_dir

    monkeypatch.delenv("MLFLOW_TRACKING_URI", raising=False)
    assert tracking_uri() == f"sqlite:///{(data_dir() / 'mlflow.db').resolve()}"
    monkeypatch.setenv("MLFLOW_TRACKING_URI", "http://tracking.example:5000")
    assert tracking_uri() == "http://tracking.example:5000" and tracking_uri("sqlite:///x.db") == "sqlite:///x.db"


def test_params_and_metric_names_are_what_mlflow_accepts():
    params = flat_params(OmegaConf.create({"a": {"b": [1, 2], "c": None, "d": {}}, "e": "x" * 7000}))
    assert params == {"a.b": "[1, 2]", "a.c": "null", "a.d": "{}", "e": "x" * 6000}
    assert metric_name("eps_e@untrained") == "eps_e/untrained" and metric_name("energy [J]") == "energy _J_"


def test_a_local_sqlite_store_keeps_its_artifacts_beside_it(tmp_path):
    assert artifact_location(f"sqlite:///{tmp_path / 'm.db'}") == (tmp_path / "mlartifacts").as_uri()
    assert artifact_location("http://tracking.example:5000") is None


def test_a_store_another_job_is_creating_is_opened_again(tmp_path, monkeypatch):
    import drapebench.tracker as tracker
    from mlflow.tracking import MlflowClient
    from sqlalchemy.exc import OperationalError

    monkeypatch.setattr(tracker.time, "sleep", lambda s: None)
    real, calls = tracker._experiment_id, []

    def racing(*args):  # the first open meets the other job's half-made schema, as in a parallel sweep's first jobs
        calls.append(args[1])
        if len(calls) == 1:
            raise OperationalError("CREATE TABLE secrets", {}, Exception("table secrets already exists"))
        return real(*args)

    monkeypatch.setattr(tracker, "_experiment_id", racing)
    uri = f"sqlite:///{tmp_path / 'mlflow.db'}"
    (tmp_path / "run").mkdir()
    run_id = log_run(_compose(["experiment_name=race"]), tmp_path / "run", {"eps_e": 1.0}, uri)
    assert len(calls) == 2 and MlflowClient(uri).get_run(run_id).data.metrics["eps_e"] == 1.0
