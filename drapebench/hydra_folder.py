"""The ``.hydra/`` folder (config, overrides) an earlier run left in a single run's folder: Hydra writes the new run's
over it before the run starts, so :func:`keep_earlier_hydra` copies it aside first and, when the run does not take
the folder (it holds another run's results, or the run failed before claiming it), :func:`put_back_earlier_hydra`
restores it. Multirun jobs are not covered: each gets a folder of its own.

It imports only the standard library: the sweep callback, which calls it, is loaded before any job runs.
"""

from __future__ import annotations

import atexit
import shutil
import tempfile
from pathlib import Path

_KEPT: dict[Path, tuple[Path, Path | None]] = {}  # run folder -> (its .hydra/, the copy kept of it; None: there was none)


def keep_earlier_hydra(run_dir: Path, subdir: str) -> None:
    """Before Hydra writes ``run_dir/subdir`` (its ``.hydra/``): copy the one there aside, or record that there is none."""
    hydra_dir = (Path(run_dir) / subdir).resolve()
    kept = None
    if hydra_dir.is_dir():
        holder = Path(tempfile.mkdtemp(prefix="drapebench_hydra_"))
        atexit.register(shutil.rmtree, holder, ignore_errors=True)  # a job that never reaches the run still cleans up
        kept = Path(shutil.copytree(hydra_dir, holder / "kept"))
    _KEPT[Path(run_dir).resolve()] = (hydra_dir, kept)


def put_back_earlier_hydra(run_dir: Path, refused: bool) -> None:
    """The run did not take ``run_dir``: put back the ``.hydra/`` kept by :func:`keep_earlier_hydra`. Where there was
    none, the new one is removed only when the run was ``refused`` (the folder is another run's); otherwise it is the
    failed run's own record and stays. The kept copy is dropped either way."""
    hydra_dir, kept = _KEPT.pop(Path(run_dir).resolve(), (None, None))
    if hydra_dir is None:
        return
    if kept is None:
        if refused and hydra_dir.is_dir():
            shutil.rmtree(hydra_dir)
        return
    aside = Path(tempfile.mkdtemp(prefix=".hydra.", dir=hydra_dir.parent))
    try:
        shutil.copytree(kept, aside / "earlier")
        if hydra_dir.exists():
            hydra_dir.rename(aside / "new")
        (aside / "earlier").rename(hydra_dir)
    finally:
        shutil.rmtree(aside, ignore_errors=True)
        shutil.rmtree(kept.parent, ignore_errors=True)


def forget_earlier_hydra(run_dir: Path) -> None:
    """The run took ``run_dir``: its own ``.hydra/`` stays, and the copy of the earlier one is dropped."""
    _, kept = _KEPT.pop(Path(run_dir).resolve(), (None, None))
    if kept is not None:
        shutil.rmtree(kept.parent, ignore_errors=True)
