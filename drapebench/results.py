"""The run record: the summary columns of a run, its provenance (commit, environment) and the
``prediction.h5`` file of draped vertices."""

from __future__ import annotations

import contextlib
import hashlib
import platform
import subprocess
from functools import lru_cache
from importlib import metadata
from pathlib import Path
from typing import Iterator

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


GENERATED = ("reports", "README.md")  # what `python -m drapebench.reproduce` writes into the tree: no run reads them
CODE = ("conf", "methods", "drapebench", "run.py")  # what a run reads: an untracked file there is code it may run
READ_IF_IGNORED = (".py", ".yaml", ".yml")  # an ignored file under CODE with these endings is still code a run may read


def uncommitted_code(root: Path | None = None) -> list[str]:
    """The files under :data:`CODE` that differ from the commit (paths relative to ``root``, default the project's;
    sorted): tracked files with changes, and :func:`untracked_code`. Empty when git cannot list them."""
    try:
        done = subprocess.run(["git", "diff", "HEAD", "--name-only", "-z", "--", *CODE], cwd=root or PROJECT_ROOT,
                              capture_output=True, text=True, check=True)  # fmt: skip
    except (OSError, subprocess.CalledProcessError):
        return untracked_code(root)
    return sorted({p for p in done.stdout.split("\0") if p} | set(untracked_code(root)))


def untracked_code(root: Path | None = None) -> list[str]:
    """The untracked files under :data:`CODE` (paths relative to ``root``, default the project's; sorted): those git
    does not ignore, and ignored ones a run reads all the same (:data:`READ_IF_IGNORED`: Hydra's ``glob(*)`` sweeps an
    ignored ``conf/method/x.local.yaml`` too): a run may read them (a new ``conf/method/x.yaml`` that a sweep's
    ``method=glob(*)`` picks up), so they make its commit label dirty. Empty when git cannot list them."""
    def others(*flags) -> set:
        done = subprocess.run(["git", "ls-files", "--others", *flags, "-z", "--", *CODE], cwd=root or PROJECT_ROOT,
                              capture_output=True, text=True, check=True)  # fmt: skip
        return {p for p in done.stdout.split("\0") if p}

    try:
        every, not_ignored = others(), others("--exclude-standard")
    except (OSError, subprocess.CalledProcessError):
        return []
    return sorted(not_ignored | {p for p in every - not_ignored if p.endswith(READ_IF_IGNORED)})


def _head_commit() -> str:
    """HEAD commit of the project now (with ``-dirty`` if tracked files have changes, but for the tables and the
    README's status that :data:`GENERATED` names: a regeneration that has written some tables still runs the commit's
    code; or if there are :func:`untracked_code` files), or ``unknown``."""
    try:
        sha = subprocess.run(["git", "rev-parse", "HEAD"], cwd=PROJECT_ROOT, capture_output=True, text=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no", "--", ".", *(f":(exclude){g}" for g in GENERATED)],
                               cwd=PROJECT_ROOT, capture_output=True, text=True, check=True).stdout.strip()  # fmt: skip
        return sha + ("-dirty" if dirty or untracked_code() else "")
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


PREDICTION_CHUNK = 1024  # frames converted and written at once by PredictionWriter.append
H5_CHUNK_FRAMES = 8  # frames per compressed h5 chunk of prediction.h5 (8 x 2,796 vertices: 0.27 MB in float32)


class PredictionWriter:
    """The ``vertices`` (T, V, 3) m of an open prediction file (:func:`prediction_writer`), written as a drape is made:
    :meth:`append` adds the next frames; ``digest`` is the content hash of the frames written so far (what a
    :class:`StoredFrames` of the file carries, so nothing re-reads the file to hash it)."""

    def __init__(self, file: h5py.File, n_frames: int, n_vertices: int) -> None:
        self.file, self.shape, self.n_written = file, (n_frames, n_vertices, 3), 0
        self.data, self._hash = None, None

    def append(self, vertices: torch.Tensor) -> None:
        """Write the next frames ``vertices`` (B, V, 3) m (float64 kept float64: a float64 run's file is exact far from
        the origin; anything else as float32), :data:`PREDICTION_CHUNK` frames converted at a time (no second copy of
        a long drape). ValueError for a shape other than the file's, or frames beyond its length."""
        x = torch.as_tensor(vertices)
        if x.shape[1:] != self.shape[1:] or self.n_written + len(x) > self.shape[0]:
            raise ValueError(f"frames of shape {tuple(x.shape)} do not fit frames {self.n_written}.. of a prediction of shape {self.shape}")
        if self.data is None:  # the first frames fix the file's dtype
            dtype = np.float64 if x.dtype == torch.float64 else np.float32
            chunks = (max(1, min(H5_CHUNK_FRAMES, self.shape[0])), *self.shape[1:])
            self.data = self.file.create_dataset("vertices", shape=self.shape, dtype=dtype, chunks=chunks, compression="gzip", compression_opts=1)
            self._hash = hashlib.sha256(f"{np.dtype(dtype).str}{self.shape};".encode())
        for a in range(0, len(x), PREDICTION_CHUNK):
            part = np.ascontiguousarray(x[a : a + PREDICTION_CHUNK].detach().cpu().numpy().astype(self.data.dtype, copy=False))
            self.data[self.n_written : self.n_written + len(part)] = part
            self._hash.update(part.reshape(-1).view(np.uint8))
            self.n_written += len(part)

    @property
    def digest(self) -> str:
        """Hex SHA-256 of the file's dtype, shape and the bytes of the frames written so far."""
        return self._hash.hexdigest()


@contextlib.contextmanager
def prediction_writer(path: str | Path, n_frames: int, faces: torch.Tensor, n_vertices: int, **attrs) -> Iterator[PredictionWriter]:
    """A prediction file (``vertices`` (n_frames, V, 3), ``faces`` (F, 3) int32, scalar/string ``attrs``) written
    atomically: a temporary file that is renamed onto ``path`` once all ``n_frames`` frames were appended
    (:meth:`PredictionWriter.append`) and the block ends without an exception; removed otherwise (ValueError when
    frames are missing)."""
    with atomic_write(path, mode=None) as tmp, h5py.File(tmp, "w") as f:
        f.create_dataset("faces", data=np.asarray(faces, dtype=np.int32))
        for k, v in attrs.items():
            f.attrs[k] = v
        writer = PredictionWriter(f, n_frames, n_vertices)
        yield writer
        if writer.n_written != n_frames:
            raise ValueError(f"{Path(path).name}: {writer.n_written} of {n_frames} frames were written; the file was not kept")


def write_prediction(path: str | Path, vertices: torch.Tensor, faces: torch.Tensor, **attrs) -> None:
    """Write draped vertices (T, V, 3) m (float64 kept float64, anything else as float32) and faces (F, 3) with
    scalar/string attributes to h5, atomically (:func:`prediction_writer`; converted a chunk at a time)."""
    x = torch.as_tensor(vertices)
    with prediction_writer(path, len(x), faces, x.shape[1], **attrs) as writer:
        for a in progress(range(0, len(x), PREDICTION_CHUNK), desc=f"writing {Path(path).name}", unit="chunk"):
            writer.append(x[a : a + PREDICTION_CHUNK])


class StoredFrames:
    """The ``vertices`` (T, V, 3) of a prediction file, read on demand: ``frames[a:b]`` is a tensor of the frames
    [a, b) in the file's dtype; ``shape``, ``dtype`` and ``len`` as a tensor's; ``digest`` the content hash its
    :class:`PredictionWriter` computed. A long drape is evaluated or exported from it without being held."""

    def __init__(self, path: str | Path, digest: str) -> None:
        self.path, self.digest = Path(path), digest
        with h5py.File(self.path, "r") as f:
            self.shape = torch.Size(f["vertices"].shape)
            self.dtype = torch.float64 if f["vertices"].dtype == np.float64 else torch.float32

    def __len__(self) -> int:
        return self.shape[0]

    def __getitem__(self, frames: slice) -> torch.Tensor:
        if not isinstance(frames, slice):
            raise TypeError(f"StoredFrames are read by a slice of frames, e.g. frames[a:b], not {frames!r}")
        with h5py.File(self.path, "r") as f:
            return torch.from_numpy(f["vertices"][frames])


def read_prediction(path: str | Path) -> tuple[np.ndarray, np.ndarray, dict]:
    """Vertices (T, V, 3), faces (F, 3) and attributes of a prediction file."""
    with h5py.File(path, "r") as f:
        return f["vertices"][()], f["faces"][()], dict(f.attrs)
