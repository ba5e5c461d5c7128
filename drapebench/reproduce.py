"""Regenerate the committed tables with one command: ``python -m drapebench.reproduce [--tables a,b] [--quick]``
(``make reports``).

For each table (:func:`drapebench.table_specs.specs`, in their order) it expands the table's sweeps into runs (the
experiment's ``hydra.sweeper.params`` and the sweep's overrides, as Hydra's basic sweeper would), runs each one
that has not finished (a run folder ``<root>/<table>/<sweep>/<job>_<hash of its overrides>`` holding
``metrics.json`` or ``failed.json`` and a ``reproduce.json`` with the same overrides and commit is finished: a
stopped and restarted command goes on where it stopped; stopping it stops its runs, and a run that another process
is still running is not started twice), printing its progress and an estimate of what is left,
then writes the table from those runs and, at the end, ``claims.md`` over the tables written. The runs record
``viz=none`` (no recordings: a table needs none).

``--quick`` is the same pipeline on a tiny scene (the low-resolution body, 8 frames, 2 settling frames before the
reference, ``train=quick`` (``train=cpu`` shortened where a method builds its own training frames) with
``train.epochs=0`` (a method's own fixed schedule, such as an autoencoder's, still runs), seed 0; a method trained
on reference drapes reads four short ones, ``data=quick``; every method of a sweep but only the first value of its other swept keys, so
every row exists) into ``outputs/reproduce_quick/``, for a check that every table's pipeline runs, not for numbers,
so its runs are not tracked (``tracker=none``: they would enter the tables' MLflow experiments); the benchmark
tables (those with ``bench``), timed on their own scenes, are skipped.
The full command writes into ``reports/`` (``--out`` elsewhere).

``--jobs N`` runs N runs at once, each pinned to its share of the CPU cores (so that its automatic torch threads
are that share, :func:`drapebench.experiment.job_threads`): the runs that train one model go to one worker in
their order, so that no model is trained twice; a method trained on reference drapes has a group per reference set
and seed, and the set's later groups start once its first run has built the set; a run whose model is cached only
loads it and goes to any free worker (:func:`drapebench.reproduce_cost.groups`).
"""

from __future__ import annotations

import argparse
import contextlib
import fcntl
import hashlib
import json
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from collections import Counter
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

from drapebench.cache import PROJECT_ROOT, atomic_write
from drapebench.table_specs import Sweep, TableSpec, spec, specs, sweeps

QUICK = ("body=anny_lowres", "motion.n_frames=6", "motion.transition=2", "reference.settle_frames=2", "train=quick", "train.epochs=0",
         "seed=0", "data=quick", "tracker=none")
QUICK_KEEP = ("method",)  # the key whose every value --quick keeps: the table's rows
RUN = ("viz=none", "hydra.mode=RUN")


@dataclass(frozen=True)
class Job:
    """One run of a table's sweep: its overrides (one value per key) and its folder."""

    table: str
    sweep: Sweep
    overrides: tuple
    dir: Path


def expand(sweep: Sweep, quick: bool = False) -> list:
    """The runs of ``sweep``: one override list each (``key=value``), the experiment's sweeper params crossed with
    the sweep's overrides as Hydra's basic sweeper crosses them (a glob such as ``method=glob(*)`` expanded over
    the config group); with ``quick``, :data:`QUICK` and only the first value of keys not in :data:`QUICK_KEEP`, and
    each run's :func:`quick_extras`."""
    from hydra import compose, initialize_config_dir
    from hydra._internal.core_plugins.basic_sweeper import BasicSweeper
    from hydra.core.global_hydra import GlobalHydra
    from hydra.core.override_parser.overrides_parser import OverridesParser

    from drapebench.schema import register

    register()
    with initialize_config_dir(config_dir=str(PROJECT_ROOT / "conf"), version_base="1.3"):
        cfg = compose("config", overrides=[f"experiment={sweep.experiment}"], return_hydra_config=True)
        params = [f"{k}={v}" for k, v in (cfg.hydra.sweeper.get("params") or {}).items()]
        parser = OverridesParser.create(config_loader=GlobalHydra.instance().config_loader())
        overrides = parser.parse_overrides([*params, *sweep.overrides, *(QUICK if quick else ())])
        jobs = BasicSweeper.split_arguments(overrides, None)[0]
        if sweep.reference_garments:
            method = lambda j: tuple(o for o in j if o.split("=", 1)[0].lstrip("+") in ("method", "method.impl"))  # noqa: E731
            jobs = [j for j in jobs if _garment(j) in sweep.reference_garments or not _needs_reference(sweep.experiment, method(j))]
    if quick:
        seen, kept = set(), []
        for job in jobs:
            key = tuple(o for o in job if o.split("=", 1)[0].lstrip("+") not in QUICK_KEEP)
            first = all(o == _first(jobs, o) for o in key)
            if first and tuple(job) not in seen:
                seen.add(tuple(job))
                kept.append([*job, *quick_extras(job)])
        jobs = kept
    return [tuple(j) for j in jobs]


def quick_extras(job: list) -> tuple:
    """The overrides ``--quick`` adds to the run ``job`` (``key=value`` strings) beside :data:`QUICK`: the
    ``tables.QUICK`` of the package that implements its ``method=`` (settings that shorten only a pipeline check,
    such as a model's set-up solves, :mod:`drapebench.plugins`); none for a run that names no method config."""
    from drapebench.plugins import declared
    from drapebench.staleness import implementation

    name = next((o.split("=", 1)[1] for o in job if o.split("=", 1)[0].lstrip("+") == "method"), None)
    impl = implementation(name) if name else None
    return tuple(o for package, extras in declared("tables", "QUICK") if impl and package.rsplit(".", 1)[-1] == impl for o in extras)


def _garment(job: list) -> str | None:
    return next((o.split("=", 1)[1] for o in job if o.split("=", 1)[0].lstrip("+") == "garment"), None)


@lru_cache(maxsize=None)
def _needs_reference(experiment: str, method: tuple) -> bool:
    """Whether the method that the overrides ``method`` choose trains on reference drapes (composed once per
    method, inside Hydra's context)."""
    from hydra import compose

    from drapebench.experiment import method_class

    return method_class(compose("config", overrides=[f"experiment={experiment}", *method])).needs_reference


def _first(jobs: list, override: str) -> str:
    key = override.split("=", 1)[0]
    return next(o for o in jobs[0] if o.split("=", 1)[0] == key)


def plan(names: list, root: Path, quick: bool = False) -> list:
    """Every :class:`Job` of tables ``names`` (their own sweeps; a table reading another's runs adds none), in
    order, under ``root``."""
    jobs = []
    for name in names:
        s = spec(name)
        if s.sweeps_of:
            continue
        for i, sweep in enumerate(s.sweeps):
            for k, overrides in enumerate(expand(sweep, quick)):
                key = hashlib.sha256(" ".join([sweep.experiment, *overrides]).encode()).hexdigest()[:10]
                jobs.append(Job(name, sweep, overrides, root / name / str(i) / f"{k}_{key}"))
    return jobs


def commit() -> str:
    """The code the runs execute: :func:`drapebench.results.git_commit`, and with uncommitted changes
    ``<sha>-dirty+<hash of git diff HEAD>``, so that two sittings on different edits never share a label. The diff
    leaves out what a regeneration writes (:data:`drapebench.results.GENERATED`: the tables, the README's status, the
    archive under ``reports/``), as ``git_commit`` does: the tables written, or the archive synced, before the last
    table do not change the label of the runs it reads."""
    from drapebench.results import git_commit

    at = git_commit()
    if not at.endswith("-dirty"):
        return at
    return f"{at}+{hashlib.sha256(_diff_from('HEAD') or b'').hexdigest()[:12]}"


def _diff_from(base: str) -> bytes | None:
    """``git diff base`` of the tracked files, less what a regeneration writes (:data:`drapebench.results.GENERATED`),
    followed by the path and bytes of each :func:`drapebench.results.untracked_code` file; None when git cannot
    compare them (``base`` not a commit, no git)."""
    from drapebench.results import GENERATED, untracked_code

    excluded = [f":(exclude){g}" for g in GENERATED]
    try:
        done = subprocess.run(["git", "diff", base, "--", ".", *excluded], cwd=PROJECT_ROOT, capture_output=True, check=False)
    except OSError:
        return None
    if done.returncode != 0:
        return None
    untracked = b"".join(b"untracked " + p.encode() + b"\n" + _bytes(PROJECT_ROOT / p) for p in untracked_code(PROJECT_ROOT))
    return done.stdout + untracked


def _bytes(path: Path) -> bytes:
    """``path``'s bytes (a symlink to a folder, which git lists as one file: the path and bytes of each file under
    it, sorted); empty when it went away after git listed it."""
    try:
        if path.is_dir():
            files = sorted(f for f in path.rglob("*") if f.is_file() and "__pycache__" not in f.parts)
            return b"".join(f.relative_to(path).as_posix().encode() + b"\n" + f.read_bytes() for f in files)
        return path.read_bytes()
    except OSError:
        return b""


def _short(label: str) -> str:
    """A commit label as people read it: the sha's first 12 digits, and an edit's ``-dirty+<hash>``."""
    sha, dirty, edit = label.partition("-dirty+")
    return sha[:12] + (f"-dirty+{edit}" if dirty else "")


def code_against(at: str) -> str:
    """The label :func:`commit` gives the tracked files as they are now, measured from ``at``'s commit rather than
    HEAD: ``at``'s sha when they match it (what a regeneration writes aside), else ``<sha>-dirty+<hash>``; ``at``
    itself when git cannot compare. Equal to ``at`` while the code a regeneration started on is unchanged, even after
    a commit of its tables or notes."""
    sha = at.split("-dirty")[0]
    diff = _diff_from(sha)
    if diff is None:
        return at
    return f"{sha}-dirty+{hashlib.sha256(diff).hexdigest()[:12]}" if diff else sha


def finished(job: Job, at: str) -> bool:
    """Whether ``job`` has run to an end (results or a recorded failure) with the same overrides at commit ``at``
    (:func:`commit`); code git cannot name (``at`` "unknown") has finished nothing."""
    if at == "unknown":
        return False
    from drapebench.run_archive import STAMP, read_stamp

    if not (job.dir / STAMP).exists() or not ((job.dir / "metrics.json").exists() or (job.dir / "failed.json").exists()):
        return False
    done = read_stamp(job.dir)
    return done.get("overrides") == list(job.overrides) and done.get("commit") == at


BUSY = -1000  # run_job's status for a run it did not start (another process holds it, or the command is stopping): no exit status
_STOP_SIGNALS = (signal.SIGTERM, signal.SIGHUP, signal.SIGINT)
_LIVE: set = set()  # the run.py processes started here and not yet reaped: stopped with this command
_LIVE_LOCK = threading.RLock()  # re-entrant: run_job called in the main thread (not by run_all) must not deadlock its own stop
_STOPPING = threading.Event()  # set by a signal: no further run starts


def stop_runs_on_signals() -> None:
    """On SIGTERM, SIGHUP or SIGINT: start no further run, terminate the runs started (they would go on as orphans,
    beside a restarted command's copies of them, in the same folders) and exit with 128 + the signal's number. A run
    stopped so resumes its training from its last saved state when the command is run again."""

    def stop(signum, frame):
        _STOPPING.set()
        with _LIVE_LOCK:
            for proc in list(_LIVE):
                with contextlib.suppress(ProcessLookupError):
                    proc.terminate()
        raise SystemExit(128 + signum)

    for sig in _STOP_SIGNALS:
        signal.signal(sig, stop)


def run_job(job: Job, at: str, cpus: set | None = None) -> int:
    """Run ``job`` in a fresh folder (an unfinished one is removed first) and stamp it; returns run.py's status.
    ``cpus``: the CPU cores its process is pinned to (None: this process's). The run holds a lock
    (``<folder>.lock``, inherited by its process, so an orphaned run keeps it): a run that another process holds is
    not started again and its folder is left alone (status :data:`BUSY`), nor is one that finished meanwhile (status
    0); nothing starts once the command is stopping (:func:`stop_runs_on_signals`)."""
    if _STOPPING.is_set():
        return BUSY
    job.dir.parent.mkdir(parents=True, exist_ok=True)
    with open(job.dir.parent / f"{job.dir.name}.lock", "a") as lock:
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            return BUSY
        if finished(job, at):  # another command finished it after this one listed it
            return 0
        if job.dir.exists():
            shutil.rmtree(job.dir)
        argv = [sys.executable, str(PROJECT_ROOT / "run.py"), f"experiment={job.sweep.experiment}", *job.overrides, *RUN,
                f"hydra.run.dir={job.dir}"]  # fmt: skip
        log = job.dir.parent / f"{job.dir.name}.log"
        with open(log, "w") as f, _LIVE_LOCK:  # held from the start to the listing: a stop (main thread) waits for both
            if _STOPPING.is_set():
                return BUSY
            proc = subprocess.Popen(argv, cwd=PROJECT_ROOT, stdout=f, stderr=subprocess.STDOUT, pass_fds=(lock.fileno(),),
                                    env=dict(os.environ, DRAPEBENCH_PROGRESS="0"))  # fmt: skip
            _LIVE.add(proc)
        if cpus is not None:  # pinned right after exec, while the interpreter starts and before it makes a thread (not by
            with contextlib.suppress(ProcessLookupError):  # preexec_fn: unsafe beside the other workers' threads); gone: nothing to pin
                os.sched_setaffinity(proc.pid, cpus)
        try:
            code = proc.wait()
        finally:
            with _LIVE_LOCK:
                _LIVE.discard(proc)
        if (job.dir / "metrics.json").exists() or (job.dir / "failed.json").exists():
            with atomic_write(job.dir / "reproduce.json", "w") as f:
                json.dump({"overrides": list(job.overrides), "commit": at, "experiment": job.sweep.experiment}, f)
    return code


def _clock(seconds: float) -> str:
    return f"{int(seconds // 3600)}:{int(seconds % 3600 // 60):02d}:{int(seconds % 60):02d}"


def worker_cpus(workers: int) -> list:
    """The CPU cores of each of ``workers`` workers: this process's cores dealt out in turn (a worker gets at least
    one; with more workers than cores, cores are shared). None per worker where affinity cannot be set."""
    if not hasattr(os, "sched_getaffinity"):
        return [None] * workers
    cores = sorted(os.sched_getaffinity(0))
    return [set(cores[k % len(cores) :: workers]) or {cores[k % len(cores)]} for k in range(workers)]


def _override_values(job: Job) -> dict:
    return dict(o.split("=", 1) for o in job.overrides if "=" in o)


def run_kind(job: Job) -> str:
    """What ``job`` runs, for pricing it: its ``method.name=`` override, else its ``method=`` one, else its table (an
    optimisation to the loss's optimum takes minutes where a trained model's evaluation takes seconds), with its
    ``motion.n_frames=`` override where it has one ("<method>, 10000 frames": a long run is not priced as a short one)."""
    values = _override_values(job)
    kind = values.get("method.name") or values.get("method") or job.table
    return f"{kind}, {values['motion.n_frames']} frames" if "motion.n_frames" in values else kind


def time_left(took: dict, waiting: list, trains: set, workers: int) -> str:
    """", about H:MM:SS left (n trainings, m other runs)" for the jobs ``waiting``: each priced at the mean wall time
    of the finished runs (``took``: {folder: (seconds, trained, kind)}) of its own kind (:func:`run_kind`; a run
    that trains a model, its folder in ``trains``, apart from one that does not), else of its class (training or
    not), over ``workers``; a run left unpriced (its class has no finished run yet, or it sets its own length and
    no run of its kind has finished) is left out of the time and named as not timed yet (a training is not priced
    as an evaluation, nor the reverse, nor a 10,000-frame run as a 300-frame one); "" before any run has finished."""
    if not took:
        return ""

    def means(key) -> dict:
        groups = {}
        for seconds_taken, trained, kind in took.values():
            groups.setdefault(key(trained, kind), []).append(seconds_taken)
        return {k: sum(v) / len(v) for k, v in groups.items()}

    by_kind, by_class = means(lambda trained, kind: (trained, kind)), means(lambda trained, kind: trained)
    names = {True: "trainings", False: "other runs"}
    counts, untimed_counts, seconds = {True: 0, False: 0}, {True: 0, False: 0}, 0.0
    for job in waiting:
        trained = job.dir in trains
        counts[trained] += 1
        price = by_kind.get((trained, run_kind(job)))
        if price is None and "motion.n_frames" not in _override_values(job):
            price = by_class.get(trained)
        if price is None:
            untimed_counts[trained] += 1
        else:
            seconds += price
    seconds /= max(workers, 1)
    timed = [f"{counts[k] - untimed_counts[k]} {names[k]}" for k in (True, False) if counts[k] > untimed_counts[k]]
    untimed = [f"{untimed_counts[k]} {names[k]} not timed yet" for k in (True, False) if untimed_counts[k]]
    return f", about {_clock(seconds)} left ({', '.join(timed)}{'; ' + ', '.join(untimed) if untimed else ''})"


def run_all(jobs: list, at: str, say=print, workers: int = 1, runner=run_job, code_now=None) -> list:
    """Run the unfinished ``jobs`` in order, saying per run its place, what it is and an estimate of the time left
    (:func:`time_left`: each run left at the mean wall time of the finished runs of its kind so far); ``workers`` > 1
    runs that many at once, each worker pinned to its cores (:func:`worker_cpus`) and taking
    the next group of runs that share a model (:func:`drapebench.reproduce_cost.groups`) in order, once the run it
    waits for (its ``after``) has ended. Before each run starts, ``code_now()`` (default: :func:`code_against` of
    ``at``) must still give what it gave at the start: code changed during a regeneration stops it rather than stamp
    runs with code they did not run. Returns the jobs that did not finish."""
    from concurrent.futures import ThreadPoolExecutor

    from drapebench.reproduce_cost import grouped

    code_now = code_now or (lambda: code_against(at))
    start = code_now()
    todo = [j for j in jobs if not finished(j, at)]
    say(f"{len(jobs)} runs, {len(jobs) - len(todo)} already finished at {at[:12] + (' with uncommitted changes' if '-dirty' in at else '')}, {len(todo)} to run"
        + (f", {workers} at once" if workers > 1 else ""))
    say("grouping the runs by the model they share ...")
    group_list, trains, unplanned = grouped(todo) if todo else ([], set(), {})
    for job in todo:
        if job.dir in unplanned:
            say(f"could not plan {job.table}: {job.sweep.experiment} {' '.join(job.overrides)} ({unplanned[job.dir]}); "
                "it runs on its own and its log will say why")
    failed, lock, counter, took, waiting, ended = [], threading.Lock(), iter(range(1, len(todo) + 1)), {}, list(todo), set()
    turn = threading.Condition(lock)  # a run has ended: a group waiting for it may start
    changed = threading.Event()  # the code changed under the regeneration: no further run starts

    def one(job: Job, cpus) -> None:
        with lock:
            if _STOPPING.is_set() or changed.is_set():  # stopped by a signal or a code change: the runs left are not started
                failed.append(job)
                ended.add(job.dir)
                turn.notify_all()
                return
            i = next(counter)
            say(f"[{i}/{len(todo)}] {job.table}: {job.sweep.experiment} {' '.join(job.overrides)}{time_left(took, waiting, trains, workers)}")
            waiting.remove(job)  # counted above: the run starting now is left too
        t0 = time.monotonic()
        try:
            if (now := code_now()) != start:  # a table must not mix code: stop before a run would carry the wrong stamp
                changed.set()
                say(f"    the code changed since the regeneration started (it was {_short(start)}, it is {_short(now)}): this run "
                    "and those left are not started; commit or undo the change, then rerun the command")
                code = BUSY
            else:
                code = runner(job, at, cpus)
        except Exception as err:  # noqa: BLE001 - one run's error (a full disk, a failed start) must not hang the runs waiting for it
            code = 1
            say(f"    {job.table}: {job.sweep.experiment} {' '.join(job.overrides)} raised {type(err).__name__}: {err}")
        with lock:
            ended.add(job.dir)
            turn.notify_all()
            if code == BUSY:
                failed.append(job)
                if not (_STOPPING.is_set() or changed.is_set()):
                    say(f"    not started: another process is running it now (it holds {job.dir.parent / (job.dir.name + '.lock')})")
                return
            took[job.dir] = (time.monotonic() - t0, job.dir in trains, run_kind(job))
            if code != 0 and not finished(job, at):
                failed.append(job)
                say(f"    stopped without a result; its log: {job.dir.parent / (job.dir.name + '.log')}")

    def in_order() -> None:
        for job in todo:
            one(job, None)

    if workers <= 1:  # in a worker thread too: the main thread only waits, so a stop's handler never runs mid-start
        with ThreadPoolExecutor(1) as pool:
            pool.submit(in_order).result()
        return failed
    pending, cpus = list(group_list), worker_cpus(workers)

    def next_group():
        """The first pending group whose ``after`` run has ended (waiting while none is ready); None when none is left."""
        with turn:
            while pending:
                for group in pending:
                    after = getattr(group, "after", None)
                    if after is None or after.dir in ended:
                        pending.remove(group)
                        return group
                turn.wait()
        return None

    def worker(k: int) -> None:
        while (group := next_group()) is not None:
            for job in group:
                one(job, cpus[k])

    with ThreadPoolExecutor(workers) as pool:
        list(pool.map(worker, range(workers)))
    return [j for j in todo if j in failed]


def write_tables(names: list, root: Path, out: Path, quick: bool = False, say=print, at: str | None = None,
                 benches: bool = True, skipped: list | None = None) -> list:
    """Write each table of ``names`` into ``out`` from its runs under ``root`` (a benchmark's table: run its
    script, which ``quick`` and ``benches=False`` skip: it is timed on its own scene), only once every run it plans has
    a result or a recorded failure at commit ``at`` (default :func:`commit`); returns the paths written and appends
    to ``skipped`` the names of the tables left unwritten for want of runs."""
    from drapebench.report import evaluation_plot, write_table

    paths = []
    for name in names:
        s = spec(name)
        target = out / name
        if s.bench and (quick or not benches):
            say(f"{name}: skipped by {'--quick' if quick else '--write-only'} (a benchmark, timed on its own scene: {s.command()})")
            continue
        if s.bench:
            shown = target.relative_to(PROJECT_ROOT) if target.is_relative_to(PROJECT_ROOT) else target  # the footer's command: rerunnable anywhere
            # a script under benchmarks/ puts its own folder first on sys.path, so without PYTHONPATH it would import
            # the installed drapebench (in a worktree: the main checkout's code, whose commit its footer would name)
            path = os.pathsep.join(p for p in (str(PROJECT_ROOT), os.environ.get("PYTHONPATH", "")) if p)
            subprocess.run([sys.executable, *[a.format(out=shown) for a in s.bench]], cwd=PROJECT_ROOT, check=True,
                           env=dict(os.environ, PYTHONPATH=path))
            paths.append(target.with_suffix(".csv"))
            continue
        planned = plan([s.sweeps_of or name], root, quick)
        at = at or commit()
        dirs = [j.dir for j in planned if finished(j, at)]
        if len(dirs) < len(planned):  # a cell averaged over fewer scenes would change silently
            say(f"{name}: {len(planned) - len(dirs)} of its {len(planned)} runs have no result at {at[:12]}, not written "
                f"(what {target.name} held stays); {_how_to_finish(planned, at, benches)}")
            if skipped is not None:
                skipped.append(name)
            continue
        if s.evaluations:
            paths.append(evaluation_plot(dirs, target.with_suffix(".png"), title=s.what, command=s.command() + (" --quick" if quick else ""),
                                         methods=list(s.methods) or None))  # fmt: skip
            continue
        paths += write_table(dirs, name, target, command=s.command() + (" --quick" if quick else ""),
                             methods=list(s.methods) or None, garments=list(s.garments) or None)  # fmt: skip
    return paths


def _how_to_finish(planned: list, at: str, runs_them: bool) -> str:
    """What finishes a table whose ``planned`` runs lack results at ``at``: rerunning the command, or (with
    ``runs_them`` False, as ``--write-only``) the ``--at`` of the commits its finished runs were made at."""
    from drapebench.run_archive import STAMP, read_stamp

    if runs_them:
        return "rerun the command to finish them"
    made = Counter(read_stamp(j.dir).get("commit") or "unknown" for j in planned if (j.dir / STAMP).exists())
    made.pop(at, None)
    if not made:
        return "--write-only runs nothing and none of its runs is here: run the command without --write-only"
    most = next((c for c, _ in made.most_common() if c != "unknown"), None)
    hint = f"write them with --at {most if '-dirty+' in most else most[:12]}, or " if most else ""
    return (f"--write-only runs nothing; its runs here were made at {', '.join(f'{c[:12]} ({n})' for c, n in made.most_common())}: "
            f"{hint}run the command without --write-only")


def main(argv=None) -> int:
    tables = specs()
    parser = argparse.ArgumentParser(description="Run every committed table's experiments and write the tables and claims.md.")
    parser.add_argument("--tables", type=lambda t: [x.strip() for x in t.split(",") if x.strip()], default=list(tables),
                        help=f"comma-separated tables (default: all): {', '.join(tables)}")
    parser.add_argument("--quick", action="store_true", help="every table's pipeline on a tiny scene, untrained, into outputs/reproduce_quick")
    parser.add_argument("--out", type=Path, help="where the tables go (default: reports/, or outputs/reproduce_quick/reports with --quick)")
    parser.add_argument("--runs", type=Path, help="where the runs go (default: outputs/reproduce, or outputs/reproduce_quick/runs)")
    parser.add_argument("--jobs", type=int, default=1, help="runs at once, each pinned to its share of the CPU cores; the runs that share a "
                        "model run on one worker in turn, those sharing a reference set after its first run (default 1)")
    parser.add_argument("--archive", type=Path, help="keep every finished run's record (a few kB: its metrics, config and stamp) in this folder, "
                        "and restore from it the runs the runs folder lacks, first; committed, it carries a regeneration over to "
                        "another machine (drapebench/run_archive.py)")
    parser.add_argument("--dry-run", action="store_true", help="list the runs and whether each has finished, and per method the trainings the unfinished ones need and how many are cached; run nothing")
    parser.add_argument("--write-only", action="store_true", help="run nothing: write each table whose runs have all finished (at --at) "
                        "from the runs folder, and from what --archive restores into it, then claims.md")
    parser.add_argument("--at", help="with --write-only: the commit the runs were made at (default: this checkout's); a regeneration "
                        "that ran in another checkout is written here from its runs folder or the committed archive")
    args = parser.parse_args(argv)
    if not args.tables:
        parser.error(f"--tables: no table named; leave --tables out for all of them, or name some: {', '.join(tables)}")
    if args.jobs < 1:
        parser.error(f"--jobs: at least 1, got {args.jobs}")
    unknown = [t for t in args.tables if t not in tables]
    if unknown:
        parser.error(f"--tables: no table {', '.join(unknown)}; tables: {', '.join(tables)}")
    base = PROJECT_ROOT / "outputs" / ("reproduce_quick" if args.quick else "reproduce")
    root = args.runs or (base / "runs" if args.quick else base)
    out = args.out or (base / "reports" if args.quick else PROJECT_ROOT / "reports")
    files = [f"--{flag} {path}" for flag, path in (("out", out), ("runs", root), ("archive", args.archive)) if path and path.exists() and not path.is_dir()]
    if files:  # found now, not after hours of runs
        parser.error(f"{', '.join(files)}: a file, where a folder is needed; give a folder (it is made if missing)")
    if args.quick and out.resolve() == (PROJECT_ROOT / "reports").resolve():
        parser.error("--quick --out reports: quick tables are untrained 8-frame checks of the pipeline, not results, and would "
                     "replace the committed tables and claims.md; leave --out out or name another folder")
    if args.archive:
        from drapebench.run_archive import clash

        if args.quick and args.archive.resolve().is_relative_to((PROJECT_ROOT / "reports").resolve()):
            parser.error(f"--quick --archive {args.archive}: quick runs are untrained 8-frame checks of the pipeline, not results, "
                         "and would enter the committed archive; leave --archive out or name a folder outside reports/")
        if why := clash(root, args.archive):
            parser.error(f"--archive {args.archive}: {why}")
    if args.at and not args.write_only:
        parser.error(f"--at {args.at}: only with --write-only (runs are made at this checkout's commit); add --write-only or leave --at out")
    if args.write_only and args.dry_run:
        parser.error("--write-only --dry-run: both run nothing; --dry-run lists the runs, --write-only writes the finished tables; choose one")
    names = [n for n in tables if n in args.tables or _needed_by(n, args.tables)]
    at = commit()
    if at == "unknown" and not args.at and not args.dry_run:  # nothing would ever count as finished, nor be written
        try:
            why = subprocess.run(["git", "rev-parse", "HEAD"], cwd=PROJECT_ROOT, capture_output=True, text=True, check=False).stderr.strip()
        except OSError as err:
            why = str(err)
        parser.error(f"git cannot name this checkout's commit ({why or 'no git'}), so no run could count as finished: run "
                     f"inside a git clone of the project (if git calls it dubious: git config --global --add safe.directory {PROJECT_ROOT})")
    if args.at:
        from drapebench.staleness import run_label

        at = run_label(args.at)
        if at is None:
            parser.error(f"--at {args.at}: not a commit of this repository, nor <commit>-dirty+<12 hex digits> (no run would "
                         "match it); give the commit in the runs' reproduce.json, e.g. from `git log --oneline`")
    if args.archive and args.dry_run:
        print(f"archive {args.archive}: not synced by a dry run (the runs it would restore are listed as todo)")
    elif args.archive:
        from drapebench.run_archive import sync

        try:
            recorded, restored = sync(root, args.archive, at, {j.dir.relative_to(root) for j in plan(list(tables), root, args.quick)})
        except ValueError as err:
            print(f"archive {args.archive}: {err}", file=sys.stderr)
            return 1
        print(f"archive {args.archive}: {restored} runs restored from it, {recorded} recorded into it")
        from drapebench.results import CODE, uncommitted_code

        left = unplanned(args.archive)
        if left is None:
            print(f"archive {args.archive}: the runs no table plans are not named while uncommitted files under "
                  f"{', '.join(CODE)} may change what the sweeps plan (e.g. {uncommitted_code()[0]}): commit or remove them")
        elif left:
            print(f"archive {args.archive}: {len(left)} runs that no table plans any longer (e.g. {left[0]}): no table reads "
                  "them; delete them")
    jobs = plan(names, root, args.quick)
    if args.dry_run:
        from drapebench.reproduce_cost import summary

        for j in jobs:
            print(f"{'done' if finished(j, at) else 'todo'}  {j.table}: {j.sweep.experiment} {' '.join(j.overrides)}")
        todo = [j for j in jobs if not finished(j, at)]
        print(f"\nthe {len(todo)} runs to do, per method, the distinct trainings they need and how many of those are in the "
              "checkpoint cache already (the time of each training: the README's budget table), then the reference sets that "
              "the trainings of methods trained on reference drapes simulate first:")
        print("\n".join(summary(todo)))
        return 0
    failed = []
    if not args.write_only:
        stop_runs_on_signals()
        failed = run_all(jobs, at, workers=args.jobs, runner=_archiving(args.archive, root) if args.archive else run_job)
    unwritten: list = []
    paths = write_tables([n for n in names if n in args.tables], root, out, args.quick, at=at, benches=not args.write_only,
                         skipped=unwritten)
    from drapebench.claims import write_claims

    quick_note = "**--quick**: these verdicts read untrained 8-frame tables that check the pipeline; they are not results."
    paths.append(write_claims(out, note=quick_note if args.quick else ""))
    for p in paths:
        print(p)
    if failed:
        print(f"{len(failed)} runs stopped without a result (their logs are named above); rerun the command to retry them")
    if unwritten:
        print(f"not written: {', '.join(unwritten)} (why is said above)")
    return 1 if failed or unwritten else 0


def _archiving(archive: Path, root: Path):
    """:func:`run_job` that then records the run into ``archive`` when it finished (:func:`drapebench.run_archive.record`)."""
    from drapebench.run_archive import record

    def runner(job: Job, at: str, cpus: set | None = None) -> int:
        code = run_job(job, at, cpus)
        if finished(job, at):
            record(job.dir, archive / job.dir.relative_to(root))
        return code

    return runner


def unplanned(archive: Path) -> list[Path] | None:
    """The run folders in ``archive`` (a run archive, laid out as the runs folder) that no table's sweeps plan any
    longer, in full or ``--quick`` (a sweep changed since they ran), sorted: no table reads them; delete them. None
    while :func:`drapebench.results.uncommitted_code` lists files: a scratch ``conf/method/x.yaml`` moves every later
    run of a ``method=glob(*)`` sweep to another folder, and an edited experiment reorders its runs, so the plan is not
    the commit's and no run can be called unplanned."""
    from drapebench.results import uncommitted_code
    from drapebench.run_archive import STAMP

    if uncommitted_code():
        return None
    planned = {j.dir for quick in (False, True) for j in plan(list(specs()), archive, quick)}
    return sorted(d for d in (s.parent for s in archive.rglob(STAMP)) if d not in planned)


def _needed_by(name: str, tables: list) -> bool:
    """Whether a table of ``tables`` reads ``name``'s runs."""
    found = specs()
    return any(found[t].sweeps_of == name for t in tables if t in found)


if __name__ == "__main__":
    sys.exit(main())
