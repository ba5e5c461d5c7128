"""Content hashing, cache folders, atomic file writes and the one cache API every cached artefact uses.

Everything the suite builds (garments, SDF grids, topologies, reference simulations, datasets,
checkpoints, evaluations) goes through a :class:`Cache`: the file name is a :func:`content_hash`
of a format version and everything that produced it (a body by its arrays, :func:`body_key`),
the file is written through :func:`atomic_write` and sealed with a SHA-256 sidecar
(``<file>.sha256``), and a file whose sidecar is missing or does not match (truncated, corrupt,
foreign, interrupted) is never read: it is rebuilt with a warning naming it. A sidecar rather
than an embedded header keeps every format (npz, npy, pickle, torch, h5) readable by its own
library and checks the whole file, whatever the reader would have noticed. Inside
:func:`forcing` every entry is rebuilt the first time a run asks for it. Two processes that ask for one missing
entry at once build it once: the second waits (:meth:`Cache.building`) and reads what the first stored.
"""

from __future__ import annotations

import contextlib
import contextvars
import fcntl
import hashlib
import json
import logging
import os
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterator

import numpy as np

PROJECT_ROOT = Path(__file__).resolve().parent.parent

log = logging.getLogger(__name__)


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
        h.update(arr.tobytes() if arr.dtype.hasobject else arr.reshape(-1).view(np.uint8))  # the bytes, not a copy of them
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
def atomic_write(path: str | os.PathLike, mode: str = "wb", keep_suffix: bool = False) -> Iterator[Any]:
    """Open a temporary file next to ``path``; rename it onto ``path`` only on success.

    Use either as ``with atomic_write(p) as f: f.write(...)`` (file object, ``mode`` "wb"/"w")
    or with ``mode=None`` to get the temporary *path* for libraries that open files themselves
    (h5py, torch.save, rerun). ``keep_suffix`` ends the temporary name in ``path``'s suffix too
    (``.x.usd.1234.tmp.usd``), for libraries that choose the format by it (USD). On an exception the
    temporary file is removed and ``path`` is left as it was.
    """
    path = Path(path)
    tmp = _temporary_beside(path, ".tmp" + (path.suffix if keep_suffix else ""))
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


def _temporary_beside(path: Path, suffix: str) -> Path:
    """A new empty file beside ``path`` (its folder made), named ``.<name>.<random><suffix>``, with the permissions
    a new file gets (mkstemp's are 0600)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=suffix, dir=path.parent)
    os.close(fd)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)
    return Path(tmp)


@contextlib.contextmanager
def atomic_write_set(paths) -> Iterator[list[Path]]:
    """Temporary paths, one beside each of ``paths``, for files that replace ``paths`` as a set: none is renamed into
    place until the block has written them all, so an exception while writing any (a failed plot) leaves every one of
    ``paths`` as it was and removes the temporaries; a rename that fails partway (a full disk) puts back the files
    already replaced (each old file is linked aside first) and removes those that were new."""
    paths = [Path(p) for p in paths]
    temporaries: list[Path] = []
    try:
        for p in paths:  # one at a time: those made before a failing one are removed too
            temporaries.append(_temporary_beside(p, ".tmp"))
        yield list(temporaries)
        _replace_together(temporaries, paths)
    finally:
        for tmp in temporaries:
            tmp.unlink(missing_ok=True)


def _replace_together(temporaries: list[Path], paths: list[Path]) -> None:
    """Rename each of ``temporaries`` onto its path of ``paths``; if one fails, undo those already done and raise."""
    old = {}
    try:
        for p in paths:
            if p.exists():
                old[p] = _temporary_beside(p, ".old")
                old[p].unlink()
                try:
                    os.link(p, old[p])  # the old file stays in place; the link keeps it if a later rename fails
                except OSError:
                    shutil.copy2(p, old[p])
        done = []
        try:
            for tmp, p in zip(temporaries, paths):
                os.replace(tmp, p)
                done.append(p)
        except BaseException:
            for p in done:
                if p in old:
                    os.replace(old[p], p)
                else:
                    p.unlink(missing_ok=True)
            raise
    finally:
        for saved in old.values():
            saved.unlink(missing_ok=True)


def write_json(path: str | os.PathLike, obj: Any) -> None:
    """Atomically write ``obj`` as indented JSON."""
    with atomic_write(path, "w") as f:
        json.dump(obj, f, indent=2, sort_keys=False, default=_json_default)
        f.write("\n")


def check_json(obj: Any, what: str) -> None:
    """Raise ValueError, naming ``what`` and the key path, when :func:`write_json` cannot write ``obj`` (a tensor, a
    dataclass, a set): for what a run writes only after its work."""

    def walk(value, path: str) -> None:
        if isinstance(value, dict):
            for key, item in value.items():
                walk(item, f"{path}.{key}" if path else str(key))
        elif isinstance(value, (list, tuple)):
            for i, item in enumerate(value):
                walk(item, f"{path}[{i}]")
        else:
            try:
                json.dumps(value, default=_json_default)
            except (TypeError, ValueError) as err:
                raise ValueError(f"{what} holds {path or 'a value'} = {value!r}, which JSON cannot hold ({err}): use plain "
                                 "numbers, strings, lists and dicts") from None

    walk(obj, "")


def _json_default(obj: Any) -> Any:
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")


_BODY_KEYS: dict[int, tuple] = {}


def body_key(body) -> str:
    """Content hash of a body model's arrays (template, shape and pose blend shapes, joint regressor,
    skinning weights, faces, kinematic tree), memoised per object: the body in a cache key, never its name. Float
    arrays are hashed as float32, so a body loaded in float64 has the key of the same body in float32."""
    hit = _BODY_KEYS.get(id(body))
    if hit is None or hit[0] is not body:
        parts = [body.v_template, body.shapedirs, body.J_regressor, body.weights, body.faces, list(body.parents)]
        if getattr(body, "posedirs", None) is not None:
            parts.append(body.posedirs)
        parts = [p.float() if hasattr(p, "is_floating_point") and p.is_floating_point() else p for p in parts]
        hit = (body, content_hash(*parts))
        _BODY_KEYS[id(body)] = hit
    return hit[1]


_FORCED: contextvars.ContextVar[set | None] = contextvars.ContextVar("drapebench_cache_forced", default=None)


@contextlib.contextmanager
def forcing(enabled: bool = True) -> Iterator[None]:
    """Inside the block every cache entry is rebuilt the first time it is asked for, then reused
    (``force=true`` of a run). ``enabled=False`` leaves the caches as they are."""
    token = _FORCED.set(set()) if enabled else None
    try:
        yield
    finally:
        if token is not None:
            _FORCED.reset(token)


def _seal_path(path: Path) -> Path:
    return path.with_name(path.name + ".sha256")


@dataclass(frozen=True)
class Cache:
    """One kind of cached file (a sub-folder of ``data/cache``) at format ``version``.

    ``path(*key)`` names an entry by content hash; ``load(path, reader)`` returns ``reader(path)`` or
    None when the entry is missing, unsealed, fails its checksum, cannot be read or is rejected by
    the reader (returns None); ``store(path, writer)`` writes it atomically and seals it;
    ``get_or_build`` does all three. Bump ``version`` when the stored format or the producing code
    changes: the key changes and old files are never read.
    """

    kind: str
    version: int | str

    def path(self, *key_parts: Any, prefix: str = "", suffix: str = ".npz") -> Path:
        """``data/cache/<kind>/<prefix>_<content_hash(version, *key_parts)><suffix>``."""
        name = content_hash(self.version, *key_parts)
        return cache_dir(self.kind) / (f"{prefix}_{name}{suffix}" if prefix else f"{name}{suffix}")

    def sealed(self, path: str | os.PathLike) -> bool:
        """Whether the entry ``path`` is written and sealed (its checksum is checked by :meth:`load`, not here)."""
        path = Path(path)
        return path.exists() and _seal_path(path).exists()

    def load(self, path: str | os.PathLike, reader: Callable[[Path], Any], force: bool = False) -> Any:
        """``reader(path)`` for a sealed, intact entry; None (with a warning naming the file if one
        exists but is unusable) to rebuild it. ``force`` (or an enclosing :func:`forcing` that has not
        rebuilt this entry yet) returns None without reading."""
        path = Path(path)
        forced = _FORCED.get()
        if force or (forced is not None and path not in forced) or not path.exists():
            return None
        seal = _seal_path(path)
        if not seal.exists():
            problem = "has no checksum sidecar (foreign file or interrupted write)"
        elif file_checksum(path) not in seal.read_text().split():
            problem = "fails its checksum (truncated or corrupt)"
        else:
            try:
                value = reader(path)
            except Exception as err:  # a sealed file the reader rejects (written by other code)
                problem = f"cannot be read ({type(err).__name__}: {err})"
            else:
                if value is not None:
                    return value
                problem = "does not hold what was asked for"
        log.warning("%s cache file %s %s; rebuilding it", self.kind, path, problem)
        return None

    def store(self, path: str | os.PathLike, writer: Callable[[Path], None]) -> Path:
        """Write an entry with ``writer(tmp_path)`` atomically, then seal it; returns ``path``. An entry
        being replaced stays readable until its successor is in place: while the new file is renamed onto
        it, the seal accepts both checksums, so a process killed at any point leaves a sealed entry."""
        path = Path(path)
        seal = _seal_path(path)
        with atomic_write(path, mode=None) as tmp:
            writer(tmp)
            checksum = file_checksum(tmp)
            previous = seal.read_text().split() if seal.exists() and path.exists() else []
            with atomic_write(seal, "w") as f:
                f.write("\n".join([*previous, checksum]))
        with atomic_write(seal, "w") as f:
            f.write(checksum)
        forced = _FORCED.get()
        if forced is not None:
            forced.add(path)
        return path

    def remove(self, path: str | os.PathLike) -> None:
        """Delete an entry and its seal (nothing when there is none)."""
        path = Path(path)
        path.unlink(missing_ok=True)
        _seal_path(path).unlink(missing_ok=True)

    @contextlib.contextmanager
    def building(self, path: str | os.PathLike) -> Iterator[bool]:
        """Hold the entry ``path``'s build lock (an exclusive lock on a file of ``data/cache/.locks/`` named by the
        entry's path) while the body looks the entry up and builds it; yields whether another process held it first
        (it may have stored the entry meanwhile: look again). Where the lock cannot be created, no lock is taken."""
        path = Path(path)
        try:
            handle = open(cache_dir(".locks") / f"{content_hash(str(path.resolve()))}.lock", "a")
        except OSError:
            yield False
            return
        with handle:
            try:
                fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
                waited = False
            except BlockingIOError:
                log.info("%s cache: another process is building %s; waiting for it", self.kind, path.name)
                fcntl.flock(handle, fcntl.LOCK_EX)
                waited = True
            try:
                yield waited
            finally:
                fcntl.flock(handle, fcntl.LOCK_UN)

    def get_or_build(
        self,
        path: str | os.PathLike,
        build: Callable[[], Any],
        write: Callable[[Any, Path], None],
        read: Callable[[Path], Any],
        *,
        force: bool = False,
        enabled: bool = True,
    ) -> Any:
        """The entry at ``path`` if it loads (see :meth:`load`), else ``build()`` stored with
        ``write(value, tmp_path)``, built once when processes ask at once (:meth:`building`); ``enabled=False``
        builds without reading or writing."""
        if not enabled:
            return build()
        value = self.load(path, read, force)
        if value is None:
            with self.building(path) as waited:
                value = self.load(path, read) if waited else None  # stored by the process that held the lock
                if value is None:
                    value = build()
                    self.store(path, lambda tmp: write(value, tmp))
        return value
