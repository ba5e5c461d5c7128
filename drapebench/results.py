"""The run record: the summary columns of a run, its provenance (commit, environment) and the
``prediction.h5`` file of draped vertices."""

from __future__ import annotations

import platform
import subprocess
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path

import h5py
import numpy as np
import torch

from drapebench.cache import PROJECT_ROOT, atomic_write
from drapebench.progress import progress

SUMMARY_COLUMNS = ["method", "garment", "motion", "body", "reference", "shape", "seed", "n_vertices", "n_frames", "eps_e", "eps_a", "eps_c", "eps_c_std",
                   "edge_mm", "smoothness", "penetration_mm", "jitter", "vertex_error_mm", "ms_per_frame", "train_s"]  # fmt: skip


@dataclass(frozen=True)
class MetricInfo:
    """What a metric column means: table label, unit, which direction is better, one-line meaning, and the
    decimals a table prints it with."""

    label: str
    unit: str
    better: str
    meaning: str
    decimals: int = 3


# The one catalogue of metric names, units and directions (full definitions: docs/metrics.md).
METRICS = {
    "eps_e": MetricInfo("ε_e (%)", "%", "lower, down to the reference's", "mean edge-length change"),
    "eps_a": MetricInfo("ε_a (%)", "%", "lower, down to the reference's", "mean face-area change"),
    "eps_c": MetricInfo("ε_c (%)", "%", "lower, 0 ideal", "garment vertices inside the body"),
    "eps_c_nn": MetricInfo("ε_c nn (%)", "%", "lower", "vertices behind their nearest body vertex (GAPS code's count)"),
    "edge_mm": MetricInfo("edge (mm)", "mm", "lower", "mean edge-length change"),
    "smoothness": MetricInfo("smooth. (m)", "m", "lower", "mean |cotangent Laplacian| of the positions", decimals=5),
    "penetration_mm": MetricInfo("pen. (mm)", "mm", "lower", "mean depth of the vertices inside the body"),
    "jitter": MetricInfo("jitter (mm)", "mm", "lower, down to the reference's", "mean |second difference| of positions over frames"),
    "eps_c_canonical": MetricInfo("ε_c canon. (%)", "%", "lower, 0 ideal",
                                  "decoded canonical garment vertices inside the canonical body (VAE, before posing)"),
    "sampled_prior_pct": MetricInfo("samples N(0,I) (%)", "%", "lower, 0 ideal",
                                    "vertices of decoded latent samples z ~ N(0, I) inside the canonical body (VAE)"),
    "sampled_prior3_pct": MetricInfo("samples N(0,9I) (%)", "%", "lower, 0 ideal",
                                     "vertices of decoded latent samples z ~ N(0, 9 I) inside the canonical body (VAE)"),
    "sampled_codes_pct": MetricInfo("samples codes (%)", "%", "lower, 0 ideal",
                                    "vertices of decoded latent samples at the training codes' spread inside the canonical body (VAE)"),
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
    "pen_mm": MetricInfo("PEN (mm)", "mm", "neither: how much GenSim's PEN moves its ARAP stage", "mean |PEN displacement| over vertices and frames"),
    "pen_p99_mm": MetricInfo("PEN p99 (mm)", "mm", "neither", "99th percentile of |PEN displacement| over vertices and frames"),
    "hem_drop_mm": MetricInfo("hem drop (mm)", "mm", "neither: 0 holds, > 0 the skirt falls or stretches", "mean lowering of the hem (lowest boundary loop) by GenSim's PEN"),
    "pin_drop_mm": MetricInfo("pin drop (mm)", "mm", "neither: 0 holds, > 0 the garment falls", "mean lowering of the pinned vertices (waistband) by GenSim's PEN"),
    "gaps_loss": MetricInfo("GAPS loss (J)", "J", "lower, down to its optimum's",
                            "GAPS's own training loss per frame (its weighted terms, k_ext at its cap)"),
    "loss_gap_closed": MetricInfo("gap closed (%)", "%", "higher, 100 at the loss's optimum",
                                  "share of the loss gap from the untrained skinning to the loss's optimum that training closes", decimals=1),
    "setup_s": MetricInfo("setup (s)", "s", "lower", "one-off per-garment set-up inside the drape (not in ms/frame)"),
}


def metric_decimals(name: str) -> int:
    """Decimals a table prints the metric column ``name`` (or its ``<metric>@<variant>``) with: 3 unless
    :data:`METRICS` says otherwise."""
    base = name.partition("@")[0]
    return METRICS[base].decimals if base in METRICS else 3


def metric_label(name: str) -> str:
    """Table label of a metric column (the name itself when it is not in :data:`METRICS`); a variant's
    ``<metric>@<variant>`` (a drape the method scores beside its own, :meth:`methods.base.DrapingMethod.scored_variants`)
    is the metric's label with the variant in brackets."""
    base, _, variant = name.partition("@")
    label = METRICS[base].label if base in METRICS else base
    return f"{label} [{variant}]" if variant else label


def legend(names) -> str:
    """One line explaining the metrics among ``names`` (meaning, unit, better) and where they are defined
    ("" when none of them is a metric)."""
    bases = dict.fromkeys(n.partition("@")[0] for n in names)
    parts = [f"{n}: {METRICS[n].meaning} ({METRICS[n].unit}, {METRICS[n].better})" for n in bases if n in METRICS]
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
