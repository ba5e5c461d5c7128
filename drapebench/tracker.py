"""Every run logged to an experiment tracker, MLflow, on by default (``tracker=mlflow``; ``tracker=none``: off).

A run (and each run of a sweep) becomes one MLflow run, in the MLflow experiment named after the experiment config
(``experiment=<name>`` -> ``<name>``; ``default`` without one), once its folder is complete:

- parameters: the resolved config, flattened (``method.params.train.lr``; lists as JSON);
- metrics: the numbers of ``metrics.json`` (or of ``failed.json``), a scored variant's ``eps_e@untrained`` as
  ``eps_e/untrained`` (MLflow's names have no ``@``);
- metric history: each training step's columns of ``losses.csv`` as ``train/<column>`` and the per-epoch
  evaluations of ``evaluations.csv`` as ``eval/<column>``, at their ``step``;
- tags: commit, method, garment, body, motion, seed, train_seed, dtype, device, experiment, status, the run folder
  and, in a sweep, the sweep folder (``mlflow.source.git.commit`` and the run name too);
- artifacts: every file of the run folder (``drape.rrd``, ``metrics.json``, ``frames.csv``, ``losses.csv``, plots,
  ``config.yaml``, ``prediction.h5``, Hydra's ``.hydra/`` and ``run.log``).

The store is ``tracker.uri``, else ``$MLFLOW_TRACKING_URI`` (a team's server), else the project's own SQLite file
``data/mlflow.db`` with the artifacts in ``data/mlartifacts/`` (both under ``$DRAPEBENCH_DATA`` when set; any SQLite
store keeps its artifacts in ``mlartifacts/`` beside it); browse it
with ``mlflow ui --backend-store-uri sqlite:///data/mlflow.db`` (the ``ui`` extra). A failure to log (no store,
a locked database, a full disk) is a warning: the run's own files are complete before the tracker starts.
"""

from __future__ import annotations

import json
import logging
import math
import os
import re
import time
from pathlib import Path

from omegaconf import DictConfig, OmegaConf

from drapebench.cache import data_dir
from drapebench.keys import is_number
from drapebench.schema import choice

log = logging.getLogger("drapebench")

STORE_ATTEMPTS = 5  # tries to open a store that another job is creating at the same moment
PARAM_CHARS = 6000  # MLflow's limit on a parameter's value
TAG_KEYS = ("commit", "method", "garment", "body", "motion", "shape", "seed", "train_seed", "dtype", "device", "experiment")
HISTORIES = {"losses.csv": "train", "evaluations.csv": "eval"}  # run-folder file -> metric prefix of its columns


def tracking_uri(uri: str | None = None) -> str:
    """The store runs are logged to: ``uri``, else ``$MLFLOW_TRACKING_URI``, else ``sqlite:///<data>/mlflow.db``."""
    return uri or os.environ.get("MLFLOW_TRACKING_URI") or f"sqlite:///{(data_dir() / 'mlflow.db').resolve()}"


def artifact_location(uri: str) -> str | None:
    """Where a new experiment of the store ``uri`` keeps its artifacts: beside a local SQLite file
    (``<its folder>/mlartifacts``; MLflow's own default would be ``./mlruns`` under whatever folder the run started
    in); None, the server's choice, for any other store."""
    if not uri.startswith("sqlite:///"):
        return None
    return (Path(uri.removeprefix("sqlite:///")).parent / "mlartifacts").resolve().as_uri()


def metric_name(key: str) -> str:
    """An MLflow metric name for a record key: ``@`` (a scored variant) becomes ``/``, any other character MLflow
    refuses becomes ``_``."""
    return re.sub(r"[^\w.\-/ :]", "_", key.replace("@", "/"))


def flat_params(cfg: DictConfig) -> dict[str, str]:
    """The resolved config as MLflow parameters: nested keys joined with ``.``, lists and dicts inside lists as
    JSON, None as "null", each value cut to :data:`PARAM_CHARS`."""
    out: dict[str, str] = {}

    def walk(node, prefix: str) -> None:
        if isinstance(node, dict) and node:
            for k, v in node.items():
                walk(v, f"{prefix}{k}.")
        else:
            text = json.dumps(node) if isinstance(node, (list, dict)) or node is None else str(node)
            out[prefix[:-1]] = text[:PARAM_CHARS]

    walk(OmegaConf.to_container(cfg, resolve=True, enum_to_str=True), "")
    return out


def _tags(cfg: DictConfig, out: Path, record: dict) -> dict[str, str]:
    """The run's tags (module docstring)."""
    tags = {k: str(record[k]) for k in TAG_KEYS if record.get(k) is not None}
    tags.update(status=str(record.get("status", "finished")), run_dir=str(out.resolve()), **{"mlflow.runName": out.name})
    if record.get("commit"):
        tags["mlflow.source.git.commit"] = str(record["commit"])
    try:
        from hydra.core.hydra_config import HydraConfig
        from hydra.types import RunMode

        hydra = HydraConfig.get()
        if hydra.mode == RunMode.MULTIRUN:
            tags["sweep"] = str(Path(hydra.sweep.dir).resolve())
    except ValueError:  # not inside a Hydra job (run() called from Python)
        pass
    return tags


def _metrics(out: Path, record: dict, now: int):
    """MLflow ``Metric`` entities: the record's finite numbers (step 0; the seeds are tags) and the histories of
    :data:`HISTORIES`."""
    import pandas as pd
    from mlflow.entities import Metric

    metrics = [Metric(metric_name(k), float(v), now, 0) for k, v in record.items()
               if is_number(v) and math.isfinite(v) and k not in TAG_KEYS]  # fmt: skip
    for name, prefix in HISTORIES.items():
        if not (out / name).exists():
            continue
        table = pd.read_csv(out / name)
        steps = table["step"].astype(int).tolist() if "step" in table else list(range(len(table)))
        for column in table.columns.drop("step", errors="ignore"):
            values = pd.to_numeric(table[column], errors="coerce").tolist()
            metrics += [Metric(metric_name(f"{prefix}/{column}"), float(v), now, s) for s, v in zip(steps, values) if math.isfinite(v)]
    return metrics


def _experiment_id(client, name: str, location: str | None) -> str:
    """The id of the MLflow experiment ``name``, created if new with its artifacts at ``location`` (a URI; None: the
    store's default); two jobs creating it at once both get it."""
    from mlflow.exceptions import MlflowException

    found = client.get_experiment_by_name(name)
    if found is not None:
        return found.experiment_id
    try:
        return client.create_experiment(name, artifact_location=location)
    except MlflowException:  # created by a parallel job meanwhile
        found = client.get_experiment_by_name(name)
        if found is None:
            raise
        return found.experiment_id


def log_run(cfg: DictConfig, out: Path, record: dict, uri: str | None = None) -> str:
    """Log the finished run in folder ``out`` (its ``record``: metrics.json's or failed.json's) to MLflow; returns
    the MLflow run id. Raises what MLflow raises (:func:`track_run` turns that into a warning)."""
    from mlflow.tracking import MlflowClient

    for quiet in ("alembic", "mlflow.store.db.utils"):  # the first use of a store logs its table migrations
        logging.getLogger(quiet).setLevel(logging.WARNING)
    uri = tracking_uri(uri)
    for attempt in range(STORE_ATTEMPTS):  # the first jobs of a parallel sweep create a new store's tables at once
        try:
            client = MlflowClient(uri)
            experiment = _experiment_id(client, str(cfg.experiment_name), artifact_location(uri))
            break
        except Exception:  # noqa: BLE001  the other job's schema migration won: open the store again
            if attempt == STORE_ATTEMPTS - 1:
                raise
            time.sleep(0.5 * (attempt + 1))
    run = client.create_run(experiment, run_name=out.name, tags=_tags(cfg, out, record))
    run_id = run.info.run_id
    status = "FAILED"
    try:
        from mlflow.entities import Param

        params = [Param(k, v) for k, v in flat_params(cfg).items()]
        for i in range(0, len(params), 100):  # MLflow's batch limits: 100 parameters, 1000 metrics
            client.log_batch(run_id, params=params[i : i + 100])
        metrics = _metrics(out, record, int(time.time() * 1000))
        for i in range(0, len(metrics), 1000):
            client.log_batch(run_id, metrics=metrics[i : i + 1000])
        client.log_artifacts(run_id, str(out))
        status = "FAILED" if record.get("status") == "failed" else "FINISHED"
    finally:
        client.set_terminated(run_id, status)
    return run_id


def track_run(cfg: DictConfig, out: Path, record: dict) -> str | None:
    """:func:`log_run` when ``cfg.tracker.name`` is mlflow (None for none); a failure to log is a warning, never an
    error. Returns the MLflow run id, or None."""
    tracker = cfg.get("tracker")
    if tracker is None or choice(tracker.name) == "none":
        return None
    try:
        run_id = log_run(cfg, Path(out), record, tracker.uri)
    except Exception as err:  # noqa: BLE001  the run's files are complete: logging them is best effort
        log.warning("the run was not logged to MLflow (%s: %s); its files in %s are complete. tracker=none turns the "
                    "tracker off", type(err).__name__, err, out)  # fmt: skip
        return None
    log.info("logged to MLflow: experiment %s, run %s (%s; mlflow ui: README)", cfg.experiment_name, run_id, tracking_uri(tracker.uri))
    return run_id
