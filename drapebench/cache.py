"""Content hashing, cache folders and atomic file writes shared by every cached artefact.

Everything the suite builds (body bakes, datasets, topologies, reference simulations,
checkpoints) is stored under :func:`cache_dir` with a name derived from :func:`content_hash`
of what produced it, and written through :func:`atomic_write` so an interrupted write never
leaves a file that looks complete.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import tempfile
from pathlib import Path
from typing import Any, Iterator

import numpy as np

PROJECT_ROOT = Path(__file__).resolve().parent.parent


def data_dir() -> Path:
    """Root of generated data: ``$DRAPEBENCH_DATA`` or ``<project>/data``."""
    return Path(os.environ.get("DRAPEBENCH_DATA", PROJECT_ROOT / "data"))


def cache_dir(kind: str) -> Path:
    """A (created) sub-folder of ``data/cache`` for one kind of cached artefact."""
    path = data_dir() / "cache" / kind
    path.mkdir(parents=True, exist_ok=True)
    return path


def _update(h: "hashlib._Hash", obj: Any) -> None:
    if obj is None:
        h.update(b"N")
    elif isinstance(obj, (bool, int, float, str)):
        h.update(f"{type(obj).__name__}:{obj!r};".encode())
    elif isinstance(obj, bytes):
        h.update(b"B" + obj)
    elif isinstance(obj, dict):
        h.update(b"{")
        for key in sorted(obj, key=str):
            _update(h, str(key))
            _update(h, obj[key])
        h.update(b"}")
    elif isinstance(obj, (list, tuple)):
        h.update(b"[")
        for item in obj:
            _update(h, item)
        h.update(b"]")
    elif hasattr(obj, "detach") and hasattr(obj, "cpu"):  # torch tensor
        _update(h, obj.detach().cpu().numpy())
    elif isinstance(obj, np.ndarray):
        arr = np.ascontiguousarray(obj)
        h.update(f"A{arr.dtype.str}{arr.shape};".encode())
        h.update(arr.tobytes())
    elif isinstance(obj, np.generic):
        _update(h, obj.item())
    elif hasattr(obj, "__dataclass_fields__"):
        _update(h, type(obj).__name__)
        _update(h, {k: getattr(obj, k) for k in obj.__dataclass_fields__})
    else:
        raise TypeError(f"content_hash cannot hash an object of type {type(obj).__name__}")


def content_hash(*parts: Any, length: int = 16) -> str:
    """Stable hex digest of nested dicts/lists/scalars/arrays/tensors/dataclasses.

    Arrays hash by dtype, shape and bytes; dict keys are sorted, so the digest does not depend
    on insertion order. Returns the first ``length`` hex characters of a SHA-256.
    """
    h = hashlib.sha256()
    for part in parts:
        _update(h, part)
    return h.hexdigest()[:length]


def file_checksum(path: str | os.PathLike) -> str:
    """SHA-256 hex digest of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


@contextlib.contextmanager
def atomic_write(path: str | os.PathLike, mode: str = "wb") -> Iterator[Any]:
    """Open a temporary file next to ``path``; rename it onto ``path`` only on success.

    Use either as ``with atomic_write(p) as f: f.write(...)`` (file object, ``mode`` "wb"/"w")
    or with ``mode=None`` to get the temporary *path* for libraries that open files themselves
    (h5py, torch.save, rerun). On an exception the temporary file is removed and ``path`` is left
    as it was.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)  # mkstemp creates 0600; give the final file normal permissions
    try:
        if mode is None:
            yield Path(tmp)
        else:
            with open(tmp, mode) as f:
                yield f
                f.flush()
                os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def write_json(path: str | os.PathLike, obj: Any) -> None:
    """Atomically write ``obj`` as indented JSON."""
    with atomic_write(path, "w") as f:
        json.dump(obj, f, indent=2, sort_keys=False, default=_json_default)
        f.write("\n")


def _json_default(obj: Any) -> Any:
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")
