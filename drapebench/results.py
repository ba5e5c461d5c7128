"""The run record: the summary columns of a run, its provenance (commit, environment) and the
``prediction.h5`` file of draped vertices."""

from __future__ import annotations

import platform
import subprocess
from functools import lru_cache
from importlib import metadata
from pathlib import Path

import h5py
import numpy as np
import torch

from drapebench.cache import PROJECT_ROOT, atomic_write
from drapebench.metric_info import MetricInfo
from drapebench.progress import progress

SUMMARY_COLUMNS = ["method", "garment", "motion", "body", "reference", "shape", "seed", "n_vertices", "n_frames", "eps_e", "eps_a", "eps_c", "eps_c_std",
                   "edge_mm", "smoothness", "penetration_mm", "jitter", "vertex_error_mm", "ms_per_frame", "train_s"]  # fmt: skip


# The library's metrics: names, units and directions (full definitions: docs/metrics.md); each method declares its own
# diagnostics beside its code (methods/<name>/metrics.py), and metric_catalogue() joins the two.
METRICS = {
    "eps_e": MetricInfo("ε_e (%)", "%", "lower, down to the reference's", "mean edge-length change"),
    "eps_a": MetricInfo("ε_a (%)", "%", "lower, down to the reference's", "mean face-area change"),
    "eps_c": MetricInfo("ε_c (%)", "%", "lower, 0 ideal", "garment vertices inside the body"),
    "eps_c_nn": MetricInfo("ε_c nn (%)", "%", "lower", "vertices behind their nearest body vertex (the count of the code of Chen et al., 3DV 2024)"),
    "edge_mm": MetricInfo("edge (mm)", "mm", "lower", "mean edge-length change"),
    "smoothness": MetricInfo("smooth. (m)", "m", "lower", "mean |cotangent Laplacian| of the positions", decimals=5),
    "penetration_mm": MetricInfo("pen. (mm)", "mm", "lower", "mean depth of the vertices inside the body"),
    "jitter": MetricInfo("jitter (mm)", "mm", "lower, down to the reference's", "mean |second difference| of positions over frames"),
    "vertex_error_mm": MetricInfo("err. (mm)", "mm", "lower", "mean distance to the reference drape"),
    "max_strain": MetricInfo("max strain (%)", "%", "lower", "largest edge-length change of any edge in any frame"),
    "max_penetration_mm": MetricInfo("max pen. (mm)", "mm", "lower, 0 ideal", "deepest garment vertex inside the body in any frame"),
    "drift_mm": MetricInfo("drift (mm)", "mm", "lower, 0 ideal",
                           "change of the mean garment-to-body distance between the first and last 10 % of frames"),
    "ms_per_frame": MetricInfo("ms/frame", "ms", "lower", "drape time per frame"),
    "train_s": MetricInfo("train (s)", "s", "lower", "training time"),
    "converged_s": MetricInfo("to converge (s)", "s", "lower",
                              "training time until the loss's running mean stays within 5 % of its total drop above its final value"),
    "energy_j": MetricInfo("energy (J)", "J", "lower, toward the reference's", "StVK + bending + gravity energy per frame"),
    "loss_gap_closed": MetricInfo("gap closed (%)", "%", "higher, 100 at the loss's optimum",
                                  "share of the loss gap from the untrained skinning to the loss's optimum that training closes", decimals=1),
    "setup_s": MetricInfo("setup (s)", "s", "lower", "one-off per-garment set-up inside the drape (not in ms/frame)"),
}


def metric_catalogue() -> dict[str, MetricInfo]:
    """Every metric a run can record: :data:`METRICS` and the diagnostics each method declares
    (:mod:`drapebench.plugins`); ValueError naming the package when a method redeclares a metric's name."""
    from drapebench.plugins import method_packages

    return _catalogue(tuple(method_packages()))


@lru_cache(maxsize=None)
def _catalogue(packages: tuple) -> dict[str, MetricInfo]:
    from drapebench.plugins import declared

    out = dict(METRICS)
    for package, metrics in declared("metrics", "METRICS"):
        for name, info in metrics.items():
            if name in out:
                raise ValueError(f"{package}.metrics declares {name!r}, which is already a metric: name it otherwise")
            out[name] = info
    return out


def metric_info(name: str) -> MetricInfo | None:
    """The :class:`MetricInfo` of metric column ``name`` (or of its ``<metric>@<variant>``); None when no one
    declares it."""
    return metric_catalogue().get(name.partition("@")[0])


def metric_decimals(name: str) -> int:
    """Decimals a table prints the metric column ``name`` (or its ``<metric>@<variant>``) with: 3 unless its
    :func:`metric_info` says otherwise."""
    info = metric_info(name)
    return info.decimals if info else 3


def metric_label(name: str) -> str:
    """Table label of a metric column (the name itself when no one declares it); a variant's
    ``<metric>@<variant>`` (a drape the method scores beside its own, :meth:`methods.base.DrapingMethod.scored_variants`)
    is the metric's label with the variant in brackets."""
    base, _, variant = name.partition("@")
    info = metric_info(base)
    label = info.label if info else base
    return f"{label} [{variant}]" if variant else label


def legend(names) -> str:
    """One line explaining the metrics among ``names`` (meaning, unit, better) and where they are defined
    ("" when none of them is a metric)."""
    catalogue = metric_catalogue()
    bases = dict.fromkeys(n.partition("@")[0] for n in names)
    parts = [f"{n}: {catalogue[n].meaning} ({catalogue[n].unit}, {catalogue[n].better})" for n in bases if n in catalogue]
    if parts and any("@" in n for n in names):
        parts.append("[v]: the same metric of the method's variant v of its drape (e.g. after a post-processing; the method's README)")
    return "Legend: " + "; ".join(parts) + ". Definitions: docs/metrics.md." if parts else ""


def headline(record: dict, names=("eps_e", "eps_a", "eps_c", "vertex_error_mm", "ms_per_frame")) -> str:
    """The run's headline metrics with units, e.g. ``eps_e 5.08 %, ..., ms_per_frame 7.03 ms`` (those present)."""
    return ", ".join(f"{n} {record[n]:.3g} {METRICS[n].unit}" for n in names if n in record)


def _head_commit() -> str:
    """HEAD commit of the project now (with ``-dirty`` if the tree has changes), or ``unknown``."""
    try:
        sha = subprocess.run(["git", "rev-parse", "HEAD"], cwd=PROJECT_ROOT, capture_output=True, text=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=PROJECT_ROOT,
                               capture_output=True, text=True, check=True).stdout.strip()  # fmt: skip
        return sha + ("-dirty" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


_COMMIT_AT_IMPORT = _head_commit()  # the code this process runs: a sweep's later jobs do not re-import it


def git_commit() -> str:
    """The project's commit when this process imported drapebench (``-dirty`` if the tree had changes then), or
    ``unknown``: the code a run executes, even when the repository moves on while a long sweep runs."""
    return _COMMIT_AT_IMPORT


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


PREDICTION_CHUNK = 1024  # frames converted and written at once by write_prediction


def write_prediction(path: str | Path, vertices: torch.Tensor, faces: torch.Tensor, **attrs) -> None:
    """Write draped vertices (T, V, 3) m (float64 kept float64: a float64 run's file is exact far from the origin;
    anything else as float32) and faces (F, 3) with scalar/string attributes to h5, atomically; the vertices are
    converted and written :data:`PREDICTION_CHUNK` frames at a time (no second copy of a long drape)."""
    x = torch.as_tensor(vertices)
    dtype = np.float64 if x.dtype == torch.float64 else np.float32
    with atomic_write(path, mode=None) as tmp, h5py.File(tmp, "w") as f:
        out = f.create_dataset("vertices", shape=tuple(x.shape), dtype=dtype, compression="gzip", compression_opts=1)
        for a in progress(range(0, len(x), PREDICTION_CHUNK), desc=f"writing {Path(path).name}", unit="chunk"):
            out[a : a + PREDICTION_CHUNK] = x[a : a + PREDICTION_CHUNK].detach().cpu().numpy().astype(dtype, copy=False)
        f.create_dataset("faces", data=np.asarray(faces, dtype=np.int32))
        for k, v in attrs.items():
            f.attrs[k] = v


def read_prediction(path: str | Path) -> tuple[np.ndarray, np.ndarray, dict]:
    """Vertices (T, V, 3), faces (F, 3) and attributes of a prediction file."""
    with h5py.File(path, "r") as f:
        return f["vertices"][()], f["faces"][()], dict(f.attrs)
