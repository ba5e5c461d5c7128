"""The pipeline behind ``run.py``: build (or load) the scene, train or load the method, drape, evaluate, write.

Outputs in the Hydra run directory: ``metrics.json`` (one flat record), ``frames.csv`` (one row per
frame), ``prediction.h5`` (written as the drape is made, ``chunk_frames`` frames at a time for a method that streams:
drapebench.drape_stream), ``drape.rrd`` (unless ``viz=none``), ``export/`` (with ``export=usd|obj|pc2``:
drapebench.export), ``config.yaml`` (resolved, written first: it says whose folder it is) and ``env.json``
(commit, package versions, device, threads), and for a learned method ``losses.csv`` (drapebench.train) and
``settings.json`` (its parameters resolved, the code's defaults included: what ``config.yaml`` leaves to them). Every
file is written atomically. The finished run is then logged to MLflow (drapebench.tracker; ``tracker=none``: not). A folder that holds another run's results is refused; an earlier run of the same
config is cleared (logged).
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import time
from functools import partial
from pathlib import Path
from typing import NamedTuple

import numpy as np
import pandas as pd
import torch
from omegaconf import DictConfig, OmegaConf

from drapebench.body.dataset import dataset_hash
from drapebench.cache import PROJECT_ROOT, Cache, atomic_write, body_key, check_json, content_hash, forcing, write_json
from drapebench.errors import DrapeFailed
from drapebench.garments.factory import garment_label
from drapebench.results import METRICS, environment, git_commit, headline
from drapebench.scene import Scene
from drapebench.schema import check_keys, choice
from drapebench.staleness import code_of, trained_by_changed_code
from drapebench.hydra_folder import forget_earlier_hydra, put_back_earlier_hydra
from drapebench.tracker import track_run
from drapebench.train.trainer import write_logs

log = logging.getLogger("drapebench")


def shape_label(betas) -> str:
    """Readable body-shape label of a test sequence's betas: "mean", or "b1=-2" for the non-zero components."""
    if betas is None or not any(float(b) for b in betas):
        return "mean"
    return ",".join(f"b{i}={float(b):g}" for i, b in enumerate(betas) if float(b))


def job_threads(cfg: DictConfig) -> int:
    """Torch threads for this job: ``cfg.threads``, else the cores this process may use divided by the
    jobs the launcher runs at once (joblib ``n_jobs``; submitit ``cpus_per_task`` is taken as is)."""
    if cfg.threads is not None:
        if int(cfg.threads) < 1:
            raise ValueError(f"threads must be >= 1 (or null for automatic), got {cfg.threads}")
        return int(cfg.threads)
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    try:
        from hydra.core.hydra_config import HydraConfig

        launcher = HydraConfig.get().launcher
    except ValueError:  # not inside a Hydra job (e.g. run() called from Python)
        return cores
    if launcher.get("cpus_per_task"):
        return int(launcher.cpus_per_task)
    n_jobs = launcher.get("n_jobs")
    if not n_jobs:
        return cores
    parallel = min(cores, int(n_jobs) if n_jobs > 0 else max(1, cores + 1 + int(n_jobs)))
    return max(1, cores // parallel)


def method_impl(cfg: DictConfig) -> str:
    """The implementation a config names: ``method.impl``, else ``method.name`` (the schema's default)."""
    return cfg.method.impl or cfg.method.name


def method_class(cfg: DictConfig):
    """The method class a config names (:func:`method_impl`); ValueError naming the choices."""
    import methods

    return methods.get(method_impl(cfg))


CHECKPOINTS = Cache("checkpoints", 1)
EVALUATIONS = Cache("evaluations", 1)


def command_line_train_keys() -> set[str]:
    """The ``train.<key>`` names set on the command line (Hydra's task overrides, ``+``/``++`` included); empty
    outside a Hydra job. A method's own budget (``method.params.train.schedule``) never overrides them."""
    try:
        from hydra.core.hydra_config import HydraConfig

        overrides = HydraConfig.get().overrides.task
    except ValueError:  # not inside a Hydra job
        return set()
    keys = (o.split("=", 1)[0].lstrip("+~") for o in overrides)
    return {k.split(".")[1] for k in keys if k.startswith("train.")}


def method_params(cfg: DictConfig, typed: set[str]) -> dict:
    """``cfg.method.params`` as a dict, less the keys of the method's own budget (``method.params.train.schedule``)
    that the user typed as ``train.<key>`` (``typed``, :func:`command_line_train_keys`): what the user typed wins. The
    budget's length is one setting, so a typed ``train.epochs`` or ``train.steps`` drops both of the schedule's
    (``train.epochs=0``, an untrained row, is not overridden by a method's ``steps``)."""
    params = OmegaConf.to_container(cfg.method.params, resolve=True)
    schedule = params.get("train", {}).get("schedule") if isinstance(params.get("train"), dict) else None
    length = typed & {"epochs", "steps"}
    for key in sorted((typed | ({"epochs", "steps"} if length else set())) & set(schedule or {})):
        by = key if key in typed else " / train.".join(sorted(length))
        log.info("train.%s from the command line replaces method.params.train.schedule.%s", by, key)
        schedule.pop(key)
    return params


def warn_untrained_shape(betas, train_cfg: dict, own, method: str) -> list[int]:
    """Warn (and return the indices) when test ``betas`` (S,) leave the range ``method`` was trained on: ``own``
    (per component, the bound of the shapes it draws itself: its ``trained_beta_bound()``) if not None, else the
    training dataset's (:func:`drapebench.body.dataset.beta_bound`)."""
    from drapebench.body.dataset import beta_bound

    betas = np.asarray(betas, dtype=np.float64).reshape(-1)
    bound = np.zeros(len(betas))
    if own is not None:
        bound[: len(own)] = np.asarray(own, dtype=np.float64)[: len(betas)]
    elif train_cfg.get("dataset"):
        b = beta_bound(train_cfg["dataset"])
        bound[: len(b)] = b[: len(betas)]
    else:
        return []
    out = np.flatnonzero(np.abs(betas) > bound + 1e-6)
    if len(out):
        log.warning("test betas %s are outside the range %s was trained on (|beta_k| <= %s): its drape is an extrapolation there",
                    ", ".join(f"b{k}={betas[k]:g}" for k in out), method, np.round(bound, 3).tolist())  # fmt: skip
    return out.tolist()


def drape_ms_per_frame(timings_ms: dict, drape_s: float, n_frames: int) -> float:
    """Cost of one drape frame in ms. A drape loaded from a cache (``timings_ms["cache_load"]`` present)
    reports the original computation (the sum of its other stages), not the load; otherwise the wall
    time ``drape_s`` (s) of ``drape``. A method's one-off per-garment set-up (``timings_ms["setup"]``,
    reported as ``setup_s``) is not a frame's cost and is left out. Raises ValueError for n_frames < 1."""
    if n_frames < 1:
        raise ValueError(f"n_frames must be >= 1, got {n_frames}")
    if "cache_load" in timings_ms:
        return sum(v for k, v in timings_ms.items() if k not in ("cache_load", "setup")) / n_frames
    return (drape_s * 1e3 - timings_ms.get("setup", 0.0)) / n_frames


def checkpoint_path(method, cfg: DictConfig, garment, body, train_cfg: dict | None = None) -> Path:
    """Where the model ``method`` (built from ``cfg.method.params``) trained under ``cfg`` is cached: the hash of the
    method config, the method's settings_key, the training config (``train_cfg``, default ``cfg.train``), the training
    data's content, the garment (not for a generic method), the body it trains on (``method.trained_body`` of the
    run's ``body``) and the material. Where the settings_key is a dict of parameters, a ``method.params`` key it leaves
    out (how a drape is computed, e.g. its arithmetic or threads, not what is trained) is left out of the method
    config too: setting it loads the model trained without it."""
    train_cfg = OmegaConf.to_container(cfg.train, resolve=True) if train_cfg is None else train_cfg
    data_key = dataset_hash(train_cfg["dataset"]) if train_cfg.get("dataset") else None
    if method.needs_reference:  # trained on the reference set of the `data` preset
        data_key = OmegaConf.to_container(cfg.data, resolve=True)
    scene_garment = None if method.generic else (garment.vertices, garment.faces)  # one model for any garment: not keyed by it
    settings = method.settings_key()
    return CHECKPOINTS.path(keyed_method_config(method, cfg), *([settings] if settings is not None else []), train_cfg, data_key, scene_garment,
                            body_key(method.trained_body(body)), OmegaConf.to_container(cfg.material, resolve=True), prefix=cfg.method.name, suffix=".pt")  # fmt: skip


def keyed_method_config(method, cfg: DictConfig) -> dict:
    """``cfg.method`` as a checkpoint's key holds it: where ``method.settings_key()`` is a dict of parameters, without
    the ``method.params`` keys it leaves out (how a drape is computed, not what is trained)."""
    settings = method.settings_key()
    method_cfg = OmegaConf.to_container(cfg.method, resolve=True)
    if isinstance(settings, dict) and isinstance(method_cfg.get("params"), dict):
        method_cfg["params"] = {k: v for k, v in method_cfg["params"].items() if k in settings}
    return method_cfg


def loadable_checkpoint(path: Path, impl: str) -> bool:
    """Whether a run would load the checkpoint at ``path`` rather than train: it is sealed in the cache and was not
    trained by other ``methods/<impl>`` code than today's (:func:`drapebench.staleness.trained_by_changed_code`)."""
    if not CHECKPOINTS.sealed(path):
        return False
    try:
        state = torch.load(path, map_location="cpu", weights_only=False, mmap=True)
    except (RuntimeError, OSError, EOFError, ValueError):  # unreadable: the run would train it again
        return False
    return trained_by_changed_code(impl, state) is None


class Trained(NamedTuple):
    """Where a run's model came from (:func:`_checkpoint`). ``train_s``: its training time (s); ``checkpoint``: its
    path; ``stopped``: how its training ended ("done"; "clock": its lr decayed by ``train.max_minutes``' clock;
    "time": cut by it); ``trained_at``: the commit whose code trained it ("unrecorded" for a checkpoint stored before
    it was recorded); ``steps``: its optimisation steps (None: unrecorded); ``body``: the name of the body model it
    trained on (``method.trained_body``); ``model``: the content hash of its trained state (12 hex digits: two runs of
    one checkpoint path with different hashes read different trainings of it). A method with nothing learned: its
    fit's time, the rest None."""

    train_s: float
    checkpoint: str | None = None
    stopped: str | None = None
    trained_at: str | None = None
    steps: int | None = None
    body: str | None = None
    model: str | None = None


def _checkpoint(method, cfg: DictConfig, garment, data, train_cfg: dict, log_dir: Path | None = None) -> Trained:
    """Train, or load a checkpoint whose hash (method config + the method's settings_key + training config + training data content + garment
    (not for a generic method) + the body it trains on (``method.trained_body``) + material) matches. ``log_dir`` (passed to ``fit`` as the train config's ``log_dir``
    entry, for live logs) gets the fit's ``losses.csv`` (per step) and, when the method evaluates per epoch,
    ``evaluations.csv``, the same from a fresh fit or a loaded checkpoint. A "clock" or "time" training is warned
    again on every load (the key holds the configuration, not the code or the machine's speed); a checkpoint
    trained by other ``methods/<impl>`` code than this checkout's (its stored fingerprint, uncommitted edits
    included: :func:`drapebench.staleness.trained_by_changed_code`) is trained again, as a table would call its rows
    stale."""
    code = code_of(method_impl(cfg))  # the code on disk before anything is read or trained (kept for the process: fingerprint's cache)
    path = checkpoint_path(method, cfg, garment, data.body, train_cfg)
    state = CHECKPOINTS.load(path, partial(torch.load, map_location="cpu", weights_only=False), force=bool(cfg.force))
    if state is not None and (why := trained_by_changed_code(method_impl(cfg), state)):
        log.warning("checkpoint %s: %s (drapebench.staleness); training it again", path.name, why)
        state = None
    if state is not None:
        method.bind(data.body, data.material)
        method.load_state_dict(state["method"])
        log.info("loaded checkpoint %s (trained in %.1f s)", path.name, state["train_s"])
        _write_fit_logs(log_dir, state.get("history", []), state.get("evaluations", []))
        stopped = state.get("stopped", "done")
        if stopped == "time":
            log.warning("checkpoint %s was cut by train.max_minutes before its budget's last step (%d steps done): its model "
                        "depends on the speed of the machine that trained it; force=true retrains it", path.name, state.get("n_steps", 0))  # fmt: skip
        elif stopped == "clock":
            log.warning("checkpoint %s ran every step, but its learning rate decayed by train.max_minutes' clock ahead of the "
                        "steps: its model depends on the speed of the machine that trained it; force=true retrains it", path.name)  # fmt: skip
        return Trained(state["train_s"], str(path), stopped, state.get("commit", "unrecorded"), state.get("n_steps"), method.trained_body(data.body).name,
                       content_hash(state["method"], length=12))
    if method.needs_reference:  # its reference drapes are simulated (or read) before the fit's clock starts: data, not training
        data.read_train()
    report = method.fit(data, train_cfg if log_dir is None else {**train_cfg, "log_dir": str(log_dir)})
    _write_fit_logs(log_dir, report.history, report.evaluations)
    state = method.state_dict()
    if not state:
        return Trained(report.train_s)
    CHECKPOINTS.store(path, lambda tmp: torch.save({"method": state, "train_s": report.train_s, "history": report.history,
                                                    "evaluations": report.evaluations, "stopped": report.stopped,
                                                    "n_steps": report.n_steps, "commit": git_commit(), "code": code}, tmp))  # fmt: skip
    return Trained(report.train_s, str(path), report.stopped, git_commit(), report.n_steps, method.trained_body(data.body).name,
                   content_hash(state, length=12))


def _write_fit_logs(log_dir: Path | None, history: list[dict], evaluations: list[dict]) -> None:
    """``losses.csv`` and ``evaluations.csv`` of a fit into ``log_dir`` (those with rows; nothing without a log_dir)."""
    if log_dir is not None:
        write_logs(log_dir, history, evaluations)


def _metrics_code_hash() -> str:
    """Hash of the sources the metrics depend on, so cached evaluations expire when they change."""
    pkg = PROJECT_ROOT / "drapebench"
    files = [pkg / "metrics.py", *sorted((pkg / "geometry").glob("*.py")), *sorted((pkg / "physics").glob("*.py"))]
    return content_hash([f.read_bytes() for f in files])


def _evaluate(cfg: DictConfig, garment, seq, body, prediction, reference, material):
    """:func:`drapebench.metrics.evaluate`, cached by content hash of everything it reads (a
    deterministic method's second identical run reuses it)."""
    from drapebench.metrics import evaluate

    opts = {"skip_transition": bool(cfg.eval.skip_transition), "energies": bool(cfg.eval.energies)}
    content = getattr(prediction, "digest", prediction)  # a drape streamed to its file: the hash of its frames as written
    path = EVALUATIONS.path(_metrics_code_hash(), content, reference, garment.vertices, garment.faces, seq.betas, seq.poses,
                            seq.trans, seq.n_transition, body_key(body), material, opts, prefix=f"{garment.kind}_{seq.name}")  # fmt: skip

    def read(p):
        with np.load(p) as z:
            columns = json.loads(str(z["columns"]))
            return json.loads(str(z["summary"])), pd.DataFrame({c: z[f"col_{i}"] for i, c in enumerate(columns)})

    def write(value, p):
        summary, frames = value
        with open(p, "wb") as f:
            np.savez(f, summary=np.array(json.dumps(summary, default=float)), columns=np.array(json.dumps(list(frames.columns))),
                     **{f"col_{i}": frames[c].to_numpy() for i, c in enumerate(frames.columns)})  # fmt: skip

    def build():
        return evaluate(garment, seq, body, prediction, reference=reference, material=material, chunk_frames=int(cfg.chunk_frames), **opts)

    return EVALUATIONS.get_or_build(path, build, write, read, force=bool(cfg.force))


RUN_FILES = ("metrics.json", "failed.json", "frames.csv", "prediction.h5", "drape.rrd", "losses.csv", "evaluations.csv",
             "losses.png", "export", "env.json", "settings.json", "config.yaml", "converged.json")  # what a run writes into its folder (losses.png: the report's; export/: a folder; converged.json: a restored run's, drapebench.run_archive)


class RunFolderInUse(ValueError):
    """The run folder holds another run's results; nothing was changed in it."""


def claim_run_dir(out: Path, config: str) -> None:
    """Make ``out`` the folder of the run whose resolved config (YAML) is ``config``, and write it there as
    ``config.yaml``. Files of :data:`RUN_FILES` that an earlier run of the same config left (or an earlier
    run that wrote no result) are removed, and the log says which; a folder whose files belong to another
    run, or to no run that says so, raises :class:`RunFolderInUse` naming them and the fix."""
    present = [n for n in RUN_FILES if (out / n).exists()]
    earlier = (out / "config.yaml").read_text() if "config.yaml" in present else None
    results = [n for n in present if n not in ("config.yaml", "env.json")]
    if results and earlier != config:
        whose = "another run (its config.yaml differs)" if earlier is not None else "no run of this config (there is no config.yaml)"
        raise RunFolderInUse(f"run folder {out} holds results of {whose}: {', '.join(results)}; nothing was changed. Run "
                             "into a new folder (hydra.run.dir=..., or leave it to Hydra's dated folders), or move those files away")  # fmt: skip
    if present:
        for name in present:
            shutil.rmtree(out / name) if (out / name).is_dir() else (out / name).unlink()
        whose = "an earlier run of this config" if earlier == config else "a run that wrote no result"
        log.warning("run folder %s held files of %s (%s); removed them", out, whose, ", ".join(present))
    with atomic_write(out / "config.yaml", "w") as f:
        f.write(config)


def run(cfg: DictConfig, out_dir: str | Path | None = None) -> dict:
    """Run one experiment described by ``cfg``; writes the run's files into ``out_dir`` (default: the
    Hydra run directory) and returns the flat metrics record. When the method fails on the scene
    (:class:`drapebench.errors.DrapeFailed`) and ``cfg.on_failure`` is "record", writes ``failed.json``
    instead of ``metrics.json`` and returns that record (``status`` "failed"). Raises ValueError for a
    config key nothing reads (:func:`drapebench.schema.check_keys`), and :class:`RunFolderInUse` when
    ``out_dir`` holds another run's results (:func:`claim_run_dir`)."""
    if out_dir is None:
        from hydra.core.hydra_config import HydraConfig

        out_dir = HydraConfig.get().runtime.output_dir if HydraConfig.initialized() else None
    out = Path(out_dir) if out_dir is not None else None
    try:  # until the run takes the folder, the .hydra/ Hydra wrote over an earlier run's is put back on any error
        check_keys(cfg)
        if out is None:
            raise ValueError("experiment.run needs out_dir outside a Hydra run (python run.py sets it)")
        out.mkdir(parents=True, exist_ok=True)
        claim_run_dir(out, OmegaConf.to_yaml(cfg, resolve=True))
    except BaseException as err:
        if out is not None:
            put_back_earlier_hydra(out, refused=isinstance(err, RunFolderInUse))
        raise
    forget_earlier_hydra(out)
    try:
        with forcing(bool(cfg.force)):
            record = _run(cfg, out)
    except DrapeFailed as err:
        if choice(cfg.on_failure) != "record":
            raise
        record = failure_record(cfg, err)
        write_json(out / "failed.json", record)
        log.error("run failed (recorded in %s, on_failure=record): %s", out / "failed.json", err)
    track_run(cfg, out, record)
    return record


def failure_record(cfg: DictConfig, err: BaseException) -> dict:
    """The ``failed.json`` record of a run of ``cfg`` that raised ``err``: the scene, the error and its message."""
    return {"status": "failed", "method": cfg.method.name, "garment": garment_label(cfg.garment), "motion": cfg.motion.name,
            "body": cfg.body.name, "shape": shape_label(cfg.motion.betas), "dtype": choice(cfg.dtype),
            "seed": int(cfg.seed), "train_seed": int(cfg.train.seed), "device": str(cfg.device), "error": type(err).__name__,
            "message": str(err), "experiment": cfg.experiment_name, "commit": git_commit()}  # fmt: skip


def _recorded_body(cfg: DictConfig, body, viz: str):
    """The body drape.rrd draws: ``viz_body`` (e.g. anny_lowres, a lighter body playing the same motion) or the run's
    ``body``; None without a recording, where a given ``viz_body`` is ignored with a warning. Raises ValueError when
    ``viz_body`` cannot play the run's motion (another skeleton)."""
    from drapebench.body import load_body

    if viz != "rerun":
        if cfg.viz_body is not None:
            log.warning("viz_body=%s is read only by viz=rerun (this run records nothing, viz=%s): ignored", cfg.viz_body, viz)
        return None
    if cfg.viz_body is None:
        return body
    try:
        shown = load_body(cfg.viz_body)
    except (FileNotFoundError, ValueError) as err:
        raise ValueError(f"viz_body={cfg.viz_body} cannot be loaded ({err}); give viz_body a shipped body (anny, anny_lowres) or "
                         "a body file's path, or leave it unset to draw the run's body") from err  # fmt: skip
    if shown.n_joints != body.n_joints:
        raise ValueError(f"viz_body={cfg.viz_body} has {shown.n_joints} joints, the run's body {body.name} {body.n_joints}: "
                         "it cannot play the same motion; choose a body of the same skeleton (anny, anny_lowres)")  # fmt: skip
    return shown


def _run(cfg: DictConfig, out: Path) -> dict:
    from drapebench.body import load_body
    from drapebench.body.model import torch_device

    t_start = time.perf_counter()
    viz = choice(cfg.viz)
    if viz not in ("rerun", "none"):
        raise ValueError(f"viz must be 'rerun' or 'none', not {viz!r}")
    export = choice(cfg.export)
    if export == "usd":
        from drapebench.export import require_usd

        require_usd()  # before the drape, not after it
    if viz == "rerun":
        from drapebench.viz import require_rerun

        require_rerun()  # likewise
    if int(cfg.seed) < 0:  # train.seed, motion.seed and garment.seed are checked where they are read
        raise ValueError(f"seed must be >= 0 (it seeds torch and, through train.seed, numpy's generator), got {cfg.seed}; e.g. seed=0")
    torch.set_num_threads(job_threads(cfg))
    torch.manual_seed(int(cfg.seed))
    method_cls = method_class(cfg)  # fail fast on an unknown method
    params = method_params(cfg, command_line_train_keys())
    method = method_cls(params)  # and on a bad method.params key or value, before the scene and its reference are built
    settings = method.settings_key()  # what the model is built and trained with, its code's defaults included
    if settings is not None:
        check_json(settings, f"{cfg.method.name}'s settings_key()")  # settings.json is written with the results, after the work
    stages = {}
    t = time.perf_counter()
    device = torch_device(cfg.device)  # a CUDA run on a machine without CUDA is refused here, naming the fix
    # The scene (body sequence, garment, reference, metrics, recording) is built and scored on the CPU; the method
    # trains and drapes on the run's device with its own copy of the body, and its drape comes back once.
    scene = Scene.from_config(cfg, device="cpu")
    body, material, seq, garment, dtype = scene.body, scene.material, scene.seq, scene.garment, scene.dtype
    run_body = body if device.type == "cpu" else load_body(cfg.body.name, dtype=dtype, device=device)
    shown = _recorded_body(cfg, body, viz)  # before the drape: a bad viz_body is refused, not found after the work
    stages["scene_s"] = time.perf_counter() - t
    garment_name = garment_label(cfg.garment)  # the name its record, recording and export go by
    log.info("scene: %s (%d vertices) on %s, %s (%d frames) in %.1f s", garment_name, garment.n_vertices, body.name, seq.name,
             seq.n_frames, stages["scene_s"])  # fmt: skip

    t = time.perf_counter()
    reference, reference_error = None, None
    try:
        reference = scene.reference()
    except DrapeFailed as err:  # the reference simulation diverged: the method's drape and its own metrics stand
        reference_error = str(err)
        log.warning("the %s reference failed, so this run has no vertex error: %s", cfg.reference.solver, err)
    if reference is not None:
        stages["reference_s"] = time.perf_counter() - t

    train_cfg = OmegaConf.to_container(cfg.train, resolve=True)

    data = scene.train_data(method, run_body)
    t = time.perf_counter()
    trained = _checkpoint(method, cfg, garment, data, train_cfg, log_dir=out)
    stages["fit_s"] = time.perf_counter() - t
    if trained.checkpoint is not None:
        warn_untrained_shape(seq.betas, train_cfg, method.trained_beta_bound(), cfg.method.name)

    from drapebench.drape_stream import stream_drape
    from drapebench.export import input_hashes

    attrs = {"method": cfg.method.name, "garment": garment_name, "motion": seq.name, "body": cfg.body.name, "fps": seq.fps,
             "n_transition": seq.n_transition, "inputs": json.dumps(input_hashes(garment, seq, body))}  # inputs: what an export checks  # fmt: skip
    streamed = stream_drape(method, garment, seq, out / "prediction.h5", int(cfg.chunk_frames), cfg.method.name, attrs)
    on_device, result, drape_s = streamed.on_device, streamed.result, streamed.drape_s
    t = time.perf_counter()
    summary, frames = _evaluate(cfg, garment, seq, body, result.vertices, reference, material)
    for variant, drape in method.scored_variants(seq, on_device).items():  # the same metrics, suffixed @variant
        scored = _evaluate(cfg, garment, seq, body, drape.cpu(), reference, material)[0]
        summary.update({f"{k}@{variant}": v for k, v in scored.items() if k in METRICS})
    summary.update(method.diagnostics(garment, seq, on_device))  # method-specific measurements (declared in methods/<name>/metrics.py)
    stages["eval_s"] = time.perf_counter() - t
    record = {
        "method": cfg.method.name, "garment": garment_name, "motion": cfg.motion.name, "body": cfg.body.name,
        "shape": shape_label(seq.betas), "dtype": str(dtype).removeprefix("torch."), "reference": cfg.reference.solver or "none", "n_vertices": garment.n_vertices, "n_frames": seq.n_frames, **summary,
        "ms_per_frame": drape_ms_per_frame(result.timings_ms, drape_s, seq.n_frames), "train_s": trained.train_s,
        "setup_s": result.timings_ms.get("setup", 0.0) / 1e3,
        **{f"ms_{k}": v / seq.n_frames for k, v in result.timings_ms.items() if k != "setup"},
        "seed": int(cfg.seed), "train_seed": int(cfg.train.seed), "device": str(cfg.device), "experiment": cfg.experiment_name, "checkpoint": trained.checkpoint, "commit": git_commit(),
        **{key: value for key, value in (("train_stopped", trained.stopped), ("trained_at", trained.trained_at), ("train_steps", trained.steps),
                                          ("train_body", trained.body), ("model_hash", trained.model)) if value is not None}, **({"reference_error": reference_error} if reference_error else {}),
    }  # fmt: skip
    if export != "none":
        from drapebench.export import Drape, export_drape

        t = time.perf_counter()
        label = f"{cfg.method.name} {garment_name} on {seq.name} ({cfg.body.name})"
        paths = export_drape(out, Drape.from_scene(result.vertices[:], garment, seq, body, label), export)
        stages["export_s"] = time.perf_counter() - t
        log.info("exported the drape (%s): %d file(s) in %s", export, len(paths), paths[0].parent)
    with atomic_write(out / "frames.csv", "w") as f:
        frames.to_csv(f, index=False)
    write_json(out / "env.json", environment(cfg.device))
    if settings is not None:
        write_json(out / "settings.json", settings)
    if viz == "rerun":
        from drapebench.geometry.sdf import inside_body
        from drapebench.viz import record_drape

        t = time.perf_counter()
        vertices = result.vertices[:]  # the whole drape, as the recording holds it
        inside = inside_body(vertices, seq.vertices(body), body.faces)  # the rule behind eps_c
        record_drape(out / "drape.rrd", seq.vertices(shown), shown.faces, vertices, garment.topology, seq.fps,
                     penetrating=inside, reference=reference, stages=result.extras, metrics=frames,
                     name=f"{cfg.method.name}_{garment_name}_{seq.name}", in_place=seq.trans, displaced_from=method.displaced_from)  # fmt: skip
        stages["viz_s"] = time.perf_counter() - t
    stages["total_s"] = time.perf_counter() - t_start
    record.update(stages)
    write_json(out / "metrics.json", record)  # last: its presence marks a complete run
    log.info("%s (total %.1f s; what they mean: docs/metrics.md, or the legend under any table)", headline(record), record["total_s"])
    log.info("results in %s", out)
    return record

