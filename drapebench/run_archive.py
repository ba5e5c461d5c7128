"""A regeneration's finished runs as small records, so that it can go on on another machine.

``python -m drapebench.reproduce --archive DIR`` keeps, for every finished run, the files its tables read (its
:data:`RECORD`: metrics, environment, config, the reproduce stamp, a recorded failure, per-epoch evaluations) and,
for a run that trained, ``converged.json`` (the training time to convergence, read off ``losses.csv``, which is
left out: about 0.6 MB a model). A few kB a run: committed, the archive outlives the machine, while the
checkpoint cache and the runs' folders do not. At the start of a regeneration the runs folder gets back every
archived run it lacks, and the archive every finished run it lacks; a run restored at its commit counts as finished
(:func:`drapebench.reproduce.finished`), so a sitting on a new machine, at the same commit, trains only what is left.
A sync never runs beside a regeneration in the same runs folder (``reproduce --archive`` syncs before it starts).
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

RECORD = ("metrics.json", "failed.json", "env.json", "config.yaml", "reproduce.json", "evaluations.csv")
STAMP = "reproduce.json"
CONVERGED = "converged.json"


def _finished(root: Path) -> dict:
    """{path relative to ``root``: run folder} of the finished runs below ``root`` (a stamp, and metrics or a
    failure; a half-written ``*.tmp`` copy is none)."""
    if not root.exists():
        return {}
    return {d.relative_to(root): d for d in (s.parent for s in root.rglob(STAMP))
            if not d.name.endswith(".tmp") and ((d / "metrics.json").exists() or (d / "failed.json").exists())}  # fmt: skip


def read_stamp(run: Path) -> dict:
    """The ``reproduce.json`` stamp of the run folder ``run`` (its overrides and commit); a stamp that is not JSON (a
    merge conflict in a committed archive, a disk that filled) raises a ValueError that names the file and the fix."""
    path = run / STAMP
    try:
        stamp = json.loads(path.read_text())
    except json.JSONDecodeError as err:
        raise ValueError(f"{path} is not valid JSON ({err}; a merge conflict?): resolve it, or delete {run} so that "
                         "the regeneration runs it again") from err
    if not isinstance(stamp, dict):
        raise ValueError(f"{path} holds {type(stamp).__name__}, not a stamp object: delete {run} so that the regeneration runs it again")
    return stamp


def _commit(run: Path) -> str | None:
    return read_stamp(run).get("commit")


def portable_checkpoint(path: str | None) -> str | None:
    """A run's checkpoint path without the machine's folders: from ``cache/checkpoints/`` on (relative to the data
    folder, :func:`drapebench.cache.data_dir`), as the archive records it; other paths as they are."""
    if not path:
        return path
    parts = Path(path).parts
    at = next((i for i in range(len(parts) - 1) if parts[i : i + 2] == ("cache", "checkpoints")), None)
    return path if at is None else "/".join(parts[at:])


def _copy(src: Path, dest: Path, names, converged: float | None = None, portable: bool = False) -> None:
    """Copy the files ``names`` that ``src`` holds (and ``converged.json`` with ``converged``, if given) into
    ``dest`` as a whole: into a temporary folder first, then renamed over ``dest`` (never left half-copied);
    ``portable``: the metrics' checkpoint path as :func:`portable_checkpoint` writes it."""
    from drapebench.cache import write_json

    tmp = dest.with_name(dest.name + ".tmp")
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    for name in names:
        if not (src / name).exists():
            continue
        shutil.copy2(src / name, tmp / name)
        if portable and name == "metrics.json":
            metrics = json.loads((src / name).read_text())
            if metrics.get("checkpoint") != portable_checkpoint(metrics.get("checkpoint")):
                write_json(tmp / name, {**metrics, "checkpoint": portable_checkpoint(metrics["checkpoint"])})
    if converged is not None:
        (tmp / CONVERGED).write_text(json.dumps({"converged_s": converged}))
    shutil.rmtree(dest, ignore_errors=True)
    tmp.rename(dest)


def record(run: Path, dest: Path) -> None:
    """The archive record of the finished run folder ``run`` into ``dest``: its :data:`RECORD` files (its checkpoint
    path relative to the data folder) and, when it trained, ``converged.json`` with its ``converged_s`` (from its
    ``losses.csv``, or the record it was restored from)."""
    from drapebench.train.convergence import converged_seconds

    metrics, losses = run / "metrics.json", run / "losses.csv"
    train_s = json.loads(metrics.read_text()).get("train_s") if metrics.exists() else None
    converged = converged_seconds(losses, train_s) if train_s and losses.exists() else converged_of(run) if train_s else None
    _copy(run, dest, RECORD, converged, portable=True)


def _result(run: Path) -> tuple:
    """What a table reads of the finished run ``run``: its metrics (checkpoint path as the archive writes it) or its
    recorded failure."""
    def read(name: str) -> dict | None:
        path = run / name
        return json.loads(path.read_text()) if path.exists() else None

    metrics = read("metrics.json")
    if metrics and metrics.get("checkpoint"):
        metrics["checkpoint"] = portable_checkpoint(metrics["checkpoint"])
    return metrics, read("failed.json")


def _vacant(folder: Path) -> bool:
    """Whether nothing is in ``folder`` (absent or empty): a run is restored only there, never over an unfinished run's
    files (a crashed one, or one running now)."""
    return not folder.exists() or not any(folder.iterdir())


def sync(root: Path, archive: Path, at: str | None = None, planned: set | None = None) -> tuple[int, int]:
    """Bring the runs folder ``root`` and the archive ``archive`` level: a finished run of ``root`` that the archive
    lacks is recorded (:func:`record`), an archived run is restored into ``root`` where its folder is vacant (its
    record's files; no ``losses.csv``). Where both hold a run at different commits, the one at ``at`` (the
    regeneration's commit) replaces the other; with neither at ``at`` (or ``at`` None) both stay. Where both hold one
    at the same commit and overrides with other results (a run made again), it raises a ValueError naming both and
    changes nothing. ``planned``: the run folders (relative to both) that tables plan; others are neither recorded nor
    restored (a sweep that changed leaves its old runs behind). Run it while no regeneration runs in ``root``.
    Returns (recorded, restored)."""
    root, archive = Path(root), Path(archive)
    runs, kept = _finished(root), _finished(archive)
    if planned is not None:
        runs, kept = ({rel: d for rel, d in found.items() if rel in planned} for found in (runs, kept))
    differ = sorted(rel for rel in runs.keys() & kept.keys()
                    if (runs[rel] / STAMP).read_bytes() == (kept[rel] / STAMP).read_bytes() and _result(runs[rel]) != _result(kept[rel]))  # fmt: skip
    if differ:
        raise ValueError(f"{len(differ)} runs have other results in the runs folder than in the archive at the same commit and "
                         f"overrides (made again, e.g. {root / differ[0]} against {archive / differ[0]}): a table would read the "
                         "runs folder's while a clone has the archive's; delete the stale copy (the run's folder in the runs "
                         "folder, or its record in the archive) and rerun")  # fmt: skip
    recorded = restored = 0
    for rel, run in runs.items():
        if rel not in kept or ((kept[rel] / STAMP).read_bytes() != (run / STAMP).read_bytes() and at is not None
                               and _commit(run) == at and _commit(kept[rel]) != at):  # fmt: skip
            record(run, archive / rel)
            recorded += 1
    for rel, saved in kept.items():
        dest = root / rel
        newer = rel in runs and at is not None and _commit(saved) == at and _commit(runs[rel]) != at
        if (rel not in runs and _vacant(dest)) or newer:
            dest.parent.mkdir(parents=True, exist_ok=True)
            _copy(saved, dest, (*RECORD, CONVERGED))
            restored += 1
    return recorded, restored


def converged_of(run: Path) -> float | None:
    """A restored run's training time to convergence (s) from its ``converged.json``, None without one."""
    path = Path(run) / CONVERGED
    return json.loads(path.read_text()).get("converged_s") if path.exists() else None


def clash(runs: Path, archive: Path) -> str:
    """Why ``archive`` cannot keep the records of the runs folder ``runs`` ("" when it can): it is that folder (recording a
    run into its own folder would strip it to its record), inside it or holding it (each sync would record the archive
    into itself)."""
    a, r = Path(archive).resolve(), Path(runs).resolve()
    if a == r or a.is_relative_to(r) or r.is_relative_to(a):
        return (f"the archive must be a folder apart from the runs folder {runs} (not it, not inside it, not holding it); "
                "name another, e.g. reports/runs")
    return ""


def main(argv=None) -> int:
    """``python -m drapebench.run_archive <runs> <archive> [--commit <sha>]``: :func:`sync` alone."""
    import argparse

    parser = argparse.ArgumentParser(description="Bring a regeneration's runs folder and its archive level (sync), as `python -m "
                                     "drapebench.reproduce --archive` does first; for a worktree whose reproduce predates --archive.")
    parser.add_argument("runs", type=Path, help="the runs folder (a worktree's outputs/reproduce)")
    parser.add_argument("archive", type=Path, help="the archive (e.g. the main checkout's reports/runs)")
    parser.add_argument("--commit", help="the regeneration's commit: where both hold a run, the one made at it wins (default: both stay)")
    args = parser.parse_args(argv)
    from drapebench.staleness import run_label

    if why := clash(args.runs, args.archive):
        parser.error(f"archive {args.archive}: {why}")
    at = None
    if args.commit:
        at = run_label(args.commit)
        if at is None:
            parser.error(f"--commit {args.commit}: not a commit of this repository (its runs would never match); "
                         "give the regeneration's commit, e.g. from `git log --oneline`")
    for name, path in (("runs", args.runs), ("archive", args.archive)):  # a missing one is made (a new machine's runs folder)
        if path.exists() and not path.is_dir():  # a file synced "0 runs" and said nothing was wrong
            parser.error(f"{name} {path}: a file; give the {name} folder (made if missing)")
    recorded, restored = sync(args.runs, args.archive, at)
    print(f"archive {args.archive}: {restored} runs restored into {args.runs}, {recorded} recorded from it")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
