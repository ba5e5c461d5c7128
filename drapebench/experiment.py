"""The pipeline behind ``run.py``: build (or load) the scene, train or load the method, drape, evaluate, write.

Outputs in the Hydra run directory: ``metrics.json`` (one flat record), ``frames.csv`` (one row per
frame), ``prediction.h5``, ``drape.rrd`` (unless ``viz=none``), ``config.yaml`` (resolved) and
``env.json`` (commit, package versions, device, threads). Every file is written atomically.
"""

from __future__ import annotations

import json
import logging
import os
import platform
import subprocess
import time
from importlib import metadata
from pathlib import Path

import numpy as np
import pandas as pd
import torch
from omegaconf import DictConfig, OmegaConf

from drapebench.body.dataset import dataset_hash
from drapebench.cache import PROJECT_ROOT, atomic_write, cache_dir, content_hash, file_checksum, write_json
from drapebench.errors import DrapeFailed

log = logging.getLogger("drapebench")
SUMMARY_COLUMNS = ["method", "garment", "motion", "body", "shape", "n_vertices", "n_frames", "eps_e", "eps_a", "eps_c", "eps_c_std",
                   "edge_mm", "smoothness", "penetration_mm", "jitter", "vertex_error_mm", "ms_per_frame", "train_s"]  # fmt: skip


def git_commit() -> str:
    """HEAD commit of the project (with ``-dirty`` if the tree has changes), or ``unknown``."""
    try:
        sha = subprocess.run(["git", "rev-parse", "HEAD"], cwd=PROJECT_ROOT, capture_output=True, text=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=PROJECT_ROOT,
                               capture_output=True, text=True, check=True).stdout.strip()  # fmt: skip
        return sha + ("-dirty" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def environment(device: str) -> dict:
    """What produced a result: commit, package versions, device, threads, machine."""
    versions = {}
    for pkg in ("torch", "numpy", "scipy", "hydra-core", "rerun-sdk", "pandas", "trimesh", "h5py", "drapebench"):
        try:
            versions[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            versions[pkg] = None
    return {
        "commit": git_commit(), "versions": versions, "device": device, "torch_threads": torch.get_num_threads(),
        "python": platform.python_version(), "machine": platform.machine(), "processor": platform.processor(),
        "node": platform.node(), "cuda": torch.cuda.get_device_name(0) if torch.cuda.is_available() else None,
    }  # fmt: skip


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


def _method_class(cfg: DictConfig):
    import methods

    impl = cfg.method.impl or cfg.method.name
    return methods.get(impl)


def _valid(path: Path) -> bool:
    """True if cache file ``path`` exists and matches the SHA-256 in its ``.sha256`` sidecar."""
    sums = path.with_name(path.name + ".sha256")
    if not path.exists():
        return False
    if sums.exists() and sums.read_text().strip() == file_checksum(path):
        return True
    log.warning("cache file %s fails its checksum; rebuilding it", path)
    return False


def _seal(path: Path) -> None:
    """Write the checksum sidecar that :func:`_valid` checks (after ``path`` is complete)."""
    with atomic_write(path.with_name(path.name + ".sha256"), "w") as f:
        f.write(file_checksum(path))


def drape_ms_per_frame(timings_ms: dict, drape_s: float, n_frames: int) -> float:
    """Cost of one drape frame in ms. A drape loaded from a cache (``timings_ms["cache_load"]`` present)
    reports the original computation (the sum of its other stages), not the load; otherwise the wall
    time ``drape_s`` (s) of ``drape``. Raises ValueError for n_frames < 1."""
    if n_frames < 1:
        raise ValueError(f"n_frames must be >= 1, got {n_frames}")
    if "cache_load" in timings_ms:
        return sum(v for k, v in timings_ms.items() if k != "cache_load") / n_frames
    return drape_s * 1e3 / n_frames


def _checkpoint(method, cfg: DictConfig, garment, data, train_cfg: dict):
    """Train, or load a checkpoint whose hash (method + training config + training data content + garment +
    body + material) matches."""
    data_key = dataset_hash(train_cfg["dataset"]) if train_cfg.get("dataset") else None
    key = content_hash(OmegaConf.to_container(cfg.method, resolve=True), train_cfg, data_key, garment.vertices,
                       garment.faces, cfg.body.name, OmegaConf.to_container(cfg.material, resolve=True))  # fmt: skip
    path = cache_dir("checkpoints") / f"{cfg.method.name}_{key}.pt"
    if not cfg.force and _valid(path):
        state = torch.load(path, map_location="cpu", weights_only=False)
        method.bind(data.body, data.material)
        method.load_state_dict(state["method"])
        log.info("loaded checkpoint %s (trained in %.1f s)", path.name, state["train_s"])
        return state["train_s"], str(path)
    report = method.fit(data, train_cfg)
    state = method.state_dict()
    if not state:
        return report.train_s, None
    with atomic_write(path, mode=None) as tmp:
        torch.save({"method": state, "train_s": report.train_s, "history": report.history}, tmp)
    _seal(path)
    return report.train_s, str(path)


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
    key = content_hash(_metrics_code_hash(), prediction, reference, garment.vertices, garment.faces, seq.betas,
                       seq.poses, seq.trans, seq.n_transition, cfg.body.name, body.v_template, material, opts)  # fmt: skip
    path = cache_dir("evaluations") / f"{garment.kind}_{seq.name}_{key}.npz"
    if not cfg.force and _valid(path):
        with np.load(path) as z:
            summary = json.loads(str(z["summary"]))
            columns = json.loads(str(z["columns"]))
            return summary, pd.DataFrame({c: z[f"col_{i}"] for i, c in enumerate(columns)})
    summary, frames = evaluate(garment, seq, body, prediction, reference=reference, material=material, **opts)
    with atomic_write(path) as f:
        np.savez(f, summary=np.array(json.dumps(summary, default=float)), columns=np.array(json.dumps(list(frames.columns))),
                 **{f"col_{i}": frames[c].to_numpy() for i, c in enumerate(frames.columns)})  # fmt: skip
    _seal(path)
    return summary, frames


def _reference(cfg: DictConfig, garment, seq, body, material):
    """Physics-based drape (T, V, 3) of the test sequence (cached by drapebench.reference), or None."""
    ref = OmegaConf.to_container(cfg.reference, resolve=True)
    solver = ref.pop("solver")
    if solver is None:
        return None
    from drapebench.reference import simulate_record

    rec = simulate_record(garment, seq, body, material, solver, force=bool(cfg.force), **ref)
    log.info("reference %s: %s", solver, f"loaded from {rec.path}" if rec.from_cache else f"simulated in {rec.sim_s:.1f} s")
    return rec.vertices.to(garment.vertices.dtype)


def run(cfg: DictConfig, out_dir: str | Path | None = None) -> dict:
    """Run one experiment described by ``cfg``; writes the run's files into ``out_dir`` (default: the
    Hydra run directory) and returns the flat metrics record. When the method fails on the scene
    (:class:`drapebench.errors.DrapeFailed`) and ``cfg.on_failure`` is "record", writes ``failed.json``
    instead of ``metrics.json`` and returns that record (``status`` "failed")."""
    if out_dir is None:
        from hydra.core.hydra_config import HydraConfig

        out_dir = HydraConfig.get().runtime.output_dir
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    (out / "failed.json").unlink(missing_ok=True)
    try:
        return _run(cfg, out)
    except DrapeFailed as err:
        if getattr(cfg.on_failure, "name", cfg.on_failure) != "record":
            raise
        record = {"status": "failed", "method": cfg.method.name, "garment": cfg.garment.kind, "motion": cfg.motion.name,
                  "body": cfg.body.name, "shape": shape_label(cfg.motion.betas), "error": type(err).__name__,
                  "message": str(err), "experiment": cfg.experiment_name, "commit": git_commit()}  # fmt: skip
        write_json(out / "failed.json", record)
        log.error("run failed (recorded in %s, on_failure=record): %s", out / "failed.json", err)
        return record


def _run(cfg: DictConfig, out: Path) -> dict:
    from drapebench.body import load_body, make_sequence
    from drapebench.body.dataset import build_dataset, load_dataset
    from drapebench.garments import make_garment
    from drapebench.physics import Material
    from drapebench.store import TrainData, write_prediction

    t_start = time.perf_counter()
    viz = getattr(cfg.viz, "name", cfg.viz)  # a VizMode member once validated by the schema
    if viz not in ("rerun", "none"):
        raise ValueError(f"viz must be 'rerun' or 'none', not {viz!r}")
    (out / "metrics.json").unlink(missing_ok=True)  # a rerun into the same folder is incomplete until it ends
    torch.set_num_threads(job_threads(cfg))
    torch.manual_seed(int(cfg.seed))
    method_cls = _method_class(cfg)  # fail fast on an unknown method
    stages = {}
    t = time.perf_counter()
    body = load_body(cfg.body.name, device=cfg.device)
    material = Material.from_config(OmegaConf.to_container(cfg.material, resolve=True))
    garment = make_garment(cfg.garment.kind, body, seed=int(cfg.garment.seed), cache=not cfg.force, **cfg.garment.params)
    m = cfg.motion
    seq = make_sequence(m.name, int(m.n_frames), float(m.fps), int(m.seed), betas=None if m.betas is None else list(m.betas),
                        transition=int(m.transition), split="test", **m.params)  # fmt: skip
    stages["scene_s"] = time.perf_counter() - t
    log.info("scene: %s (%d vertices) on %s, %s (%d frames) in %.1f s", garment.kind, garment.n_vertices, body.name, seq.name,
             seq.n_frames, stages["scene_s"])  # fmt: skip

    t = time.perf_counter()
    reference = _reference(cfg, garment, seq, body, material)
    if reference is not None:
        stages["reference_s"] = time.perf_counter() - t

    method = method_cls(OmegaConf.to_container(cfg.method.params, resolve=True))
    train_cfg = OmegaConf.to_container(cfg.train, resolve=True)

    def load_train():
        return load_dataset(build_dataset(cfg.train.dataset, force=cfg.force))

    data = TrainData(body=body, material=material, garment=garment, load_train=load_train, test_sequences=[seq])
    t = time.perf_counter()
    train_s, ckpt = _checkpoint(method, cfg, garment, data, train_cfg)
    stages["fit_s"] = time.perf_counter() - t

    t = time.perf_counter()
    result = method.drape(garment, seq)
    drape_s = time.perf_counter() - t
    t = time.perf_counter()
    summary, frames = _evaluate(cfg, garment, seq, body, result.vertices, reference, material)
    stages["eval_s"] = time.perf_counter() - t
    record = {
        "method": cfg.method.name, "garment": cfg.garment.kind, "motion": m.name, "body": cfg.body.name,
        "shape": shape_label(m.betas), "n_vertices": garment.n_vertices, "n_frames": seq.n_frames, **summary,
        "ms_per_frame": drape_ms_per_frame(result.timings_ms, drape_s, seq.n_frames), "train_s": train_s,
        **{f"ms_{k}": v / seq.n_frames for k, v in result.timings_ms.items()},
        "seed": int(cfg.seed), "experiment": cfg.experiment_name, "checkpoint": ckpt, "commit": git_commit(),
    }  # fmt: skip
    write_prediction(out / "prediction.h5", result.vertices, garment.faces, method=cfg.method.name, garment=garment.kind,
                     motion=seq.name, body=cfg.body.name, fps=seq.fps, n_transition=seq.n_transition)  # fmt: skip
    with atomic_write(out / "frames.csv", "w") as f:
        frames.to_csv(f, index=False)
    with atomic_write(out / "config.yaml", "w") as f:
        f.write(OmegaConf.to_yaml(cfg, resolve=True))
    write_json(out / "env.json", environment(cfg.device))
    if viz == "rerun":
        from drapebench.geometry.sdf import inside_body
        from drapebench.viz import record_drape

        t = time.perf_counter()
        inside = inside_body(result.vertices, seq.vertices(body), body.faces)  # the rule behind eps_c
        record_drape(out / "drape.rrd", seq.vertices(body), body.faces, result.vertices, garment.topology, seq.fps,
                     penetrating=inside, reference=reference, name=f"{cfg.method.name}_{garment.kind}_{seq.name}")  # fmt: skip
        stages["viz_s"] = time.perf_counter() - t
    stages["total_s"] = time.perf_counter() - t_start
    record.update(stages)
    write_json(out / "metrics.json", record)  # last: its presence marks a complete run
    log.info("%s", " ".join(f"{k}={record[k]:.3g}" for k in ("eps_e", "eps_a", "eps_c", "ms_per_frame", "total_s")))
    log.info("results in %s", out)
    return record


try:
    from hydra.experimental.callback import Callback
except ImportError:  # pragma: no cover - hydra < 1.1
    Callback = object


class SweepSummary(Callback):
    """Hydra callback: at the end of a sweep, gather every job's metrics.json into summary.md / summary.csv."""

    def on_multirun_end(self, config: DictConfig, **kwargs) -> None:
        from drapebench.report import write_summary

        sweep_dir = Path(config.hydra.sweep.dir)
        if sweep_dir.exists():
            path = write_summary(sweep_dir)
            log.info("sweep summary: %s", path)
