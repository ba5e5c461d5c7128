"""The run record: the summary columns of a run, its provenance (commit, environment) and the
``prediction.h5`` file of draped vertices."""

from __future__ import annotations

import platform
import subprocess
from importlib import metadata
from pathlib import Path

import h5py
import numpy as np
import torch

from drapebench.cache import PROJECT_ROOT, atomic_write

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


def write_prediction(path: str | Path, vertices: torch.Tensor, faces: torch.Tensor, **attrs) -> None:
    """Write draped vertices (T, V, 3) and faces (F, 3) with scalar/string attributes to h5, atomically."""
    with atomic_write(path, mode=None) as tmp, h5py.File(tmp, "w") as f:
        f.create_dataset("vertices", data=np.asarray(vertices, dtype=np.float32), compression="gzip", compression_opts=1)
        f.create_dataset("faces", data=np.asarray(faces, dtype=np.int32))
        for k, v in attrs.items():
            f.attrs[k] = v


def read_prediction(path: str | Path) -> tuple[np.ndarray, np.ndarray, dict]:
    """Vertices (T, V, 3), faces (F, 3) and attributes of a prediction file."""
    with h5py.File(path, "r") as f:
        return f["vertices"][()], f["faces"][()], dict(f.attrs)
