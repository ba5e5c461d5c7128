"""The pipeline behind ``run.py``: build (or load) the scene, train or load the method, drape, evaluate, write.

Outputs in the Hydra run directory: ``metrics.json`` (one flat record), ``frames.csv`` (one row per
frame), ``prediction.h5``, ``drape.rrd`` (unless ``viz=none``), ``config.yaml`` (resolved) and
``env.json`` (commit, package versions, device, threads). Every file is written atomically.
"""

from __future__ import annotations

import logging
import platform
import subprocess
import time
from importlib import metadata
from pathlib import Path

import torch
from omegaconf import DictConfig, OmegaConf

from drapebench.cache import PROJECT_ROOT, atomic_write, cache_dir, content_hash, file_checksum, write_json

log = logging.getLogger("drapebench")
SUMMARY_COLUMNS = ["method", "garment", "motion", "body", "n_vertices", "n_frames", "eps_e", "eps_a", "eps_c", "eps_c_std",
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


def _method_class(cfg: DictConfig):
    import methods

    impl = cfg.method.impl or cfg.method.name
    return methods.get(impl)


def _checkpoint(method, cfg: DictConfig, garment, data, train_cfg: dict):
    """Train, or load a checkpoint whose hash (method + training config + garment + body) matches."""
    key = content_hash(OmegaConf.to_container(cfg.method, resolve=True), train_cfg, garment.vertices, garment.faces,
                       cfg.body.name, OmegaConf.to_container(cfg.material, resolve=True))  # fmt: skip
    path = cache_dir("checkpoints") / f"{cfg.method.name}_{key}.pt"
    sums = path.with_suffix(".sha256")
    if path.exists() and not cfg.force:
        if sums.exists() and sums.read_text().strip() == file_checksum(path):
            state = torch.load(path, map_location="cpu", weights_only=False)
            method.bind(data.body, data.material)
            method.load_state_dict(state["method"])
            log.info("loaded checkpoint %s (trained in %.1f s)", path.name, state["train_s"])
            return state["train_s"], str(path)
        log.warning("checkpoint %s fails its checksum; retraining", path.name)
    report = method.fit(data, train_cfg)
    state = method.state_dict()
    if state:
        with atomic_write(path, mode=None) as tmp:
            torch.save({"method": state, "train_s": report.train_s, "history": report.history}, tmp)
        with atomic_write(sums, "w") as f:
            f.write(file_checksum(path))
    return report.train_s, str(path) if state else None


def run(cfg: DictConfig, out_dir: str | Path | None = None) -> dict:
    """Run one experiment described by ``cfg``; returns the flat metrics record."""
    from drapebench.body import load_body, make_sequence
    from drapebench.body.dataset import build_dataset, load_dataset
    from drapebench.garments import make_garment
    from drapebench.metrics import evaluate
    from drapebench.physics import Material
    from drapebench.store import TrainData, write_prediction

    if out_dir is None:
        from hydra.core.hydra_config import HydraConfig

        out_dir = HydraConfig.get().runtime.output_dir
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    torch.set_num_threads(int(cfg.threads))
    torch.manual_seed(int(cfg.seed))
    method_cls = _method_class(cfg)  # fail fast on an unknown method
    if cfg.reference.solver is not None:
        raise ValueError(f"reference solver {cfg.reference.solver!r} is not available in this version; use reference=none")
    timings = {}
    t = time.perf_counter()
    body = load_body(cfg.body.name, device=cfg.device)
    material = Material.from_config(OmegaConf.to_container(cfg.material, resolve=True))
    garment = make_garment(cfg.garment.kind, body, seed=int(cfg.garment.seed), cache=not cfg.force, **cfg.garment.params)
    m = cfg.motion
    seq = make_sequence(m.name, int(m.n_frames), float(m.fps), int(m.seed), betas=None if m.betas is None else list(m.betas),
                        transition=int(m.transition), split="test", **m.params)  # fmt: skip
    timings["scene_s"] = time.perf_counter() - t
    log.info("scene: %s (%d vertices) on %s, %s (%d frames) in %.1f s", garment.kind, garment.n_vertices, body.name, seq.name,
             seq.n_frames, timings["scene_s"])  # fmt: skip

    method = method_cls(OmegaConf.to_container(cfg.method.params, resolve=True))
    train_cfg = OmegaConf.to_container(cfg.train, resolve=True)
    def load_train():
        return load_dataset(build_dataset(cfg.train.dataset, force=cfg.force))

    data = TrainData(body=body, material=material, garment=garment, load_train=load_train, test_sequences=[seq])
    train_s, ckpt = _checkpoint(method, cfg, garment, data, train_cfg)

    t = time.perf_counter()
    result = method.drape(garment, seq)
    drape_s = time.perf_counter() - t
    summary, frames = evaluate(garment, seq, body, result.vertices, material=material,
                               skip_transition=cfg.eval.skip_transition, energies=cfg.eval.energies)  # fmt: skip
    record = {
        "method": cfg.method.name, "garment": cfg.garment.kind, "motion": m.name, "body": cfg.body.name,
        "n_vertices": garment.n_vertices, "n_frames": seq.n_frames, **summary,
        "ms_per_frame": drape_s * 1e3 / seq.n_frames, "train_s": train_s,
        **{f"ms_{k}": v / seq.n_frames for k, v in result.timings_ms.items()},
        "seed": int(cfg.seed), "experiment": cfg.experiment_name, "checkpoint": ckpt, "commit": git_commit(),
    }  # fmt: skip
    write_prediction(out / "prediction.h5", result.vertices, garment.faces, method=cfg.method.name, garment=garment.kind,
                     motion=seq.name, fps=seq.fps)  # fmt: skip
    with atomic_write(out / "frames.csv", "w") as f:
        frames.to_csv(f, index=False)
    with atomic_write(out / "config.yaml", "w") as f:
        f.write(OmegaConf.to_yaml(cfg, resolve=True))
    write_json(out / "env.json", environment(cfg.device))
    if cfg.viz == "rerun":
        from drapebench.geometry.proximity import nearest_body_vertex
        from drapebench.viz import record_drape

        nn = nearest_body_vertex(result.vertices, seq.vertices(body), seq.vertex_normals(body))
        record_drape(out / "drape.rrd", seq.vertices(body), body.faces, result.vertices, garment.topology, seq.fps,
                     penetrating=nn.distance < 0, name=f"{cfg.method.name}_{garment.kind}_{seq.name}")  # fmt: skip
    elif cfg.viz != "none":
        raise ValueError(f"viz must be 'rerun' or 'none', not {cfg.viz!r}")
    write_json(out / "metrics.json", record)  # last: its presence marks a complete run
    log.info("%s", " ".join(f"{k}={record[k]:.3g}" for k in ("eps_e", "eps_a", "eps_c", "ms_per_frame")))
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
