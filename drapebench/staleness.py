"""Which rows of a committed table are stale: run at another commit than the table's newest, or by method code
that has changed since, or reading a cached model that such code trained (a model is cached by its configuration,
not its code: the table names the commit that trained it, ``report.trained_note``).

A method's code is its implementation folder ``methods/<impl>/`` (its ``.py`` files but the declarations of what
it reports, :func:`makes_numbers`) and its configs (``conf/method/<name>.yaml`` of every config whose implementation
it is), and, for a table, the presets its runs were made with (the table's "Presets" note; a table written before
it: its name's track, :func:`track_of`: ``cpu`` for the CPU tables, ``paper`` for a ``_gpu`` one): the budget files
named like them in ``conf/method/<impl>_*/`` and, for a method that trains, ``conf/train/<train>.yaml`` and
``conf/data/<data>.yaml``.
So a change to the GPU presets leaves the CPU tables' rows current, and the other way round. A cached model's own
stored code (:func:`code_of`) leaves the presets out: its cache key holds the resolved presets it trained with.
Compared by :func:`fingerprint`: Python without comments and docstrings (its syntax tree), YAML as the data it loads,
so a reflowed docstring changes nothing and a changed default does. Reads git history; a commit the repository does
not know (or a run on uncommitted changes, ``-dirty``) cannot be checked and counts as stale.
"""

from __future__ import annotations

import ast
import hashlib
import importlib
import json
import re
import subprocess
from functools import lru_cache
from pathlib import Path

import yaml

from drapebench.cache import PROJECT_ROOT
from drapebench.plugins import DECLARATIONS

METHOD_CONF = "conf/method"
TRAINING_CONF = ("conf/train", "conf/data")  # the training and reference-set presets: configuration of a method that trains
TRACKS = ("cpu", "paper")  # the preset names the committed tables are made with: CPU tables and _gpu tables


def track_of(table: str) -> str:
    """The presets a committed table's runs use when the table does not name them (a table written before its
    "Presets" note, ``drapebench.report.presets_note``): "paper" for a ``_gpu`` table (``train=paper``,
    ``data=paper``), "cpu" for the others (their experiments' ``train=cpu``, ``data=cpu``). A track is one preset
    name for both, or "<train>+<data>"."""
    return "paper" if table.endswith("_gpu") else "cpu"


def _presets(track: str) -> tuple[str, str]:
    """(the training preset, the reference-set preset) of ``track`` ("cpu", or "paper+cpu")."""
    train, _, data = track.partition("+")
    return train, data or train


def code_key(impl: str, track: str) -> str:
    """The key of ``impl``'s fingerprint on ``track`` in a {key: fingerprint} code dict (:func:`current_code`): the
    implementation's name for the CPU track, ``<impl>@<track>`` for another."""
    return impl if track == "cpu" else f"{impl}@{track}"


def _git(*args: str) -> subprocess.CompletedProcess:
    """``git -C <project> *args``; without a git binary, a failed process (every commit then reads as unknown)."""
    try:
        return subprocess.run(["git", "-C", str(PROJECT_ROOT), *args], capture_output=True, text=True)
    except FileNotFoundError:
        return subprocess.CompletedProcess(["git", *args], 127, "", "git: not found")


@lru_cache(maxsize=None)
def known(commit: str) -> str | None:
    """The full hash of ``commit`` (a hash or its prefix) when this repository has it, else None."""
    if not commit or commit.endswith("-dirty") or commit == "unknown":
        return None
    out = _git("rev-parse", "--verify", "--quiet", f"{commit}^{{commit}}")
    return out.stdout.strip() or None


def run_label(given: str) -> str | None:
    """The commit label that runs made at ``given`` record (:func:`drapebench.reproduce.commit`): the full hash of a
    commit or its prefix; an uncommitted edit's ``<sha>-dirty+<12 hex digits>`` with its sha expanded the same way;
    None when it is neither (or names no commit of this repository)."""
    sha, dirty, edit = given.partition("-dirty+")
    full = known(sha)
    if not dirty:
        return full
    return f"{full}-dirty+{edit}" if full and re.fullmatch(r"[0-9a-f]{12}", edit) else None


def is_ancestor(a: str, b: str) -> bool:
    """Whether commit ``a`` is ``b`` or an ancestor of it (both known)."""
    return _git("merge-base", "--is-ancestor", a, b).returncode == 0


def newest(commits) -> str | None:
    """The commit of ``commits`` that descends from all the others (the table's commit), None when one is unknown
    or they are not on one line of history."""
    full = [known(c) for c in commits]
    if not full or None in full:
        return None
    return next((c for c in full if all(is_ancestor(o, c) for o in full)), None)


def _conf_impl(stem: str, seen=()) -> str | None:
    path = PROJECT_ROOT / METHOD_CONF / f"{stem}.yaml"
    if not path.exists() or stem in seen:
        return None
    data = yaml.safe_load(path.read_text()) or {}
    if data.get("impl"):
        return _folder(str(data["impl"]))
    parents = [d for d in data.get("defaults", []) if isinstance(d, str) and d != "_self_"]
    return next((i for i in (_conf_impl(p, (*seen, stem)) for p in parents) if i), None)


def _folder(impl: str) -> str:
    """The folder under ``methods/`` holding implementation ``impl`` (``<m>_optimum`` lives in ``methods/<m>``)."""
    return max((f for f in impls() if impl == f or impl.startswith(f + "_")), key=len, default=impl)


@lru_cache(maxsize=None)
def implementation(row: str) -> str | None:
    """The implementation folder (``methods/<folder>``) behind a table row: the row's method config, or the config
    whose name is the longest prefix of it (``<m>_untrained`` is ``<m>`` run with ``method.name`` changed); None
    when no method config matches."""
    stems = sorted((p.stem for p in (PROJECT_ROOT / METHOD_CONF).glob("*.yaml")), key=len, reverse=True)
    stem = next((s for s in stems if row == s or row.startswith(s + "_")), None)
    return _conf_impl(stem) if stem else None


@lru_cache(maxsize=None)
def code_files(impl: str, track: str | None = None) -> tuple:
    """The config files (repository paths) that belong to ``impl``: every method config of today's tree whose
    implementation it is, and with a ``track``, for a method that trains (:func:`learns`), the training and
    reference-set presets it names (``conf/train/<train>.yaml``, ``conf/data/<data>.yaml``), listed whether or not
    the file exists (a preset added or removed changes the fingerprint); its ``.py`` files and its budget folders'
    presets (:func:`budget_files`) are listed per commit by :func:`fingerprint`."""
    conf = PROJECT_ROOT / METHOD_CONF
    files = [f"{METHOD_CONF}/{p.name}" for p in sorted(conf.glob("*.yaml")) if _conf_impl(p.stem) == impl]
    if track is not None and learns(impl):
        files += [f"{d}/{name}.yaml" for d, name in zip(TRAINING_CONF, _presets(track))]
    return tuple(files)


def budget_files(impl: str, track: str, commit: str | None = None) -> list:
    """The ``<preset>.yaml`` of ``track``'s presets (its training one and its reference-set one: a budget folder is
    keyed by either) in each of ``impl``'s budget folders (``conf/method/<impl>_*/``) in the
    tree of ``commit`` (None: the working tree), whether or not the file exists there: a folder that exists on one
    side only then changes the fingerprint."""
    if commit is None:
        folders = [d.name for d in sorted((PROJECT_ROOT / METHOD_CONF).glob(f"{impl}_*")) if d.is_dir()]
    else:
        listed = _git("ls-tree", "-d", "--name-only", commit, f"{METHOD_CONF}/").stdout.split()
        folders = sorted(Path(d).name for d in listed if Path(d).name.startswith(f"{impl}_"))
    return [f"{METHOD_CONF}/{d}/{name}.yaml" for d in folders for name in dict.fromkeys(_presets(track))]


@lru_cache(maxsize=None)
def learns(impl: str) -> bool:
    """Whether a registered method of the folder ``methods/<impl>`` trains a model (its class's ``learns``)."""
    import methods

    for name in methods.available():
        module, _, cls = methods.target(name).partition(":")
        parts = module.split(".")
        if len(parts) > 1 and parts[0] == "methods" and parts[1] == impl and getattr(getattr(importlib.import_module(module), cls), "learns", False):
            return True
    return False


def _normalised(path: str, text: str) -> str:
    """``text`` without what does not change behaviour: a Python file's comments and docstrings, a YAML file's
    comments and layout."""
    if path.endswith(".py"):
        try:
            tree = ast.parse(text)
        except SyntaxError:
            return text
        for node in ast.walk(tree):
            body = getattr(node, "body", None)
            if isinstance(body, list) and body and isinstance(body[0], ast.Expr) and isinstance(getattr(body[0], "value", None), ast.Constant) \
                    and isinstance(body[0].value.value, str):  # fmt: skip
                node.body = body[1:] or [ast.Pass()]
        return ast.dump(tree)
    return json.dumps(yaml.safe_load(text), sort_keys=True, default=str)


def makes_numbers(path: str) -> bool:
    """Whether the file ``path`` of a method's folder is code that makes its numbers: not a declaration of what it
    reports (its top-level ``metrics.py``, ``claims.py``, ``tables.py``: labels, claims and table specs,
    :mod:`drapebench.plugins`)."""
    parts = Path(path).parts
    return not (len(parts) == 3 and parts[0] == "methods" and Path(parts[2]).stem in DECLARATIONS)


@lru_cache(maxsize=None)
def fingerprint(impl: str, commit: str | None = None, track: str | None = None) -> str:
    """A short hash of ``impl``'s code (see the module docstring) at ``commit`` (full hash), or in the working tree
    for None, with the presets of ``track`` (None: none, a cached model's code, :func:`code_of`)."""
    if commit is None:  # the files git tracks, as commit() labels runs: an untracked scratch file changes neither
        tracked = _git("ls-files", "--", f"methods/{impl}/")
        listed = (tracked.stdout.split() if tracked.returncode == 0 else
                  [str(p.relative_to(PROJECT_ROOT)) for p in (PROJECT_ROOT / "methods" / impl).rglob("*.py")])  # fmt: skip
        paths = sorted(p for p in listed if p.endswith(".py") and makes_numbers(p))
        read = lambda p: (PROJECT_ROOT / p).read_text() if (PROJECT_ROOT / p).exists() else None  # noqa: E731
    else:
        listed = _git("ls-tree", "-r", "--name-only", commit, "--", f"methods/{impl}/").stdout.split()
        paths = sorted(p for p in listed if p.endswith(".py") and makes_numbers(p))
        read = lambda p: (lambda r: r.stdout if r.returncode == 0 else None)(_git("show", f"{commit}:{p}"))  # noqa: E731
    h = hashlib.sha256()
    for p in [*paths, *code_files(impl, track), *(budget_files(impl, track, commit) if track is not None else [])]:
        text = read(p)
        h.update(f"{p}\0{'absent' if text is None else _normalised(p, text)}\0".encode())
    return h.hexdigest()[:12]


def stale_rows(rows, row_commits: dict, table_commits, code: dict | None = None, owner: str | None = None,
               trained_at: dict | None = None, track: str = "cpu") -> dict:  # fmt: skip
    """{row: why} for the rows of ``rows`` that are stale: from another commit than the newest of
    ``table_commits``, from a commit git does not know, or run (or their models trained) by code whose
    :func:`fingerprint` with ``track``'s presets (the table's runs', :func:`track_of`) differs from ``code``
    ({:func:`code_key`: fingerprint}, the code the verdicts are judged against; default: the working tree's).
    ``row_commits``: {row: [commits]}; a row missing from it ran at the table's commits. ``owner``: the
    implementation of the rows that name no method config (a benchmark's garment rows; :func:`table_specs.owner`).
    ``trained_at``: {method: [commits]}, those whose code trained the method's cached
    models where they are not its runs' commit (a garment row reads every method of ``owner``; "unrecorded", a
    model cached before that was recorded, is not judged)."""
    table_commit = newest(table_commits)
    out = {}
    for row in rows:
        commits = row_commits.get(row, list(table_commits))
        full = [known(c) for c in commits]
        impl = implementation(row) or owner
        if not commits:
            out[row] = "its table names no commit its runs were made at"
        elif None in full:
            out[row] = f"its commit {commits[full.index(None)]} is not in this repository's history (or ran on uncommitted changes)"
        elif table_commit is None:
            odd = [c for c in table_commits if known(c) is None]
            out[row] = (f"the table's commit {odd[0]} is not in this repository's history (or ran on uncommitted changes)" if odd
                        else "the table's commits are not on one line of history")  # fmt: skip
        elif any(c != table_commit for c in full):
            out[row] = f"from {', '.join(c[:7] for c in full if c != table_commit)}, not the table's {table_commit[:7]}"
        elif impl is not None and fingerprint(impl, full[0], track) != _judged(code, impl, track):
            out[row] = f"methods/{impl} or its configs changed since {full[0][:7]}"
        elif impl is not None and (why := _trained_by_other_code(impl, _trained(row, impl, trained_at or {}), code, track)):
            out[row] = why
    return out


def _judged(code: dict | None, impl: str, track: str) -> str:
    """The fingerprint ``impl``'s rows on ``track`` are judged against: ``code``'s entry, else the working tree's."""
    return (code or {}).get(code_key(impl, track)) or fingerprint(impl, None, track)


def _trained(row: str, impl: str, trained_at: dict) -> list:
    """The commits that trained ``row``'s models: its own entry of ``trained_at`` ({method: [commits]}), or for a row
    that names no method (a benchmark's garment row, judged as ``impl``'s) those of every method of ``impl``."""
    if implementation(row) is not None:
        return trained_at.get(row, [])
    return [c for method, commits in trained_at.items() if implementation(method) == impl for c in commits]


def _trained_by_other_code(impl: str, trained_at: list, code: dict | None, track: str = "cpu") -> str | None:
    """Why models trained at the commits ``trained_at`` are not those of ``code``'s methods/<impl> with ``track``'s
    presets (None if they are)."""
    for t in trained_at:
        if t == "unrecorded":
            continue
        full = known(t)
        if full is None:
            return f"its model was trained at {t}, a commit not in this repository's history (or uncommitted changes)"
        if fingerprint(impl, full, track) != _judged(code, impl, track):
            return f"its model was trained by methods/{impl} as of {full[:7]}, which has changed since"
    return None


def changed_since(impl: str, commit: str) -> str | None:
    """The full hash of ``commit`` when git knows it and ``impl``'s code (:func:`fingerprint`) there differs from the
    checked-out commit's (HEAD's: untracked files and uncommitted edits do not count, as a run's commit label
    ignores the first and marks the second "-dirty"); None when it is the same, or when ``commit`` cannot be
    checked ("unrecorded", uncommitted changes, a commit this repository does not have)."""
    full, head = known(commit), known("HEAD")
    if full is None or head is None:
        return None
    return full if fingerprint(impl, full) != fingerprint(impl, head) else None


def code_of(impl: str) -> str | None:
    """The working tree's :func:`fingerprint` of the folder behind a method config's ``impl`` (``<m>_optimum``:
    ``methods/<m>``), stored with a model it trains, without presets (the model's cache key holds those it trained
    with); None when ``impl`` names no folder under ``methods/``."""
    folder = _folder(str(impl or ""))
    return fingerprint(folder) if folder in impls() else None


def trained_by_changed_code(impl: str, state) -> str | None:
    """Why the cached model ``state`` (a checkpoint's dict) was trained by other code than this checkout's, or None.
    Its ``code`` (:func:`code_of` when it was trained, uncommitted edits included) is compared with today's; where
    they differ but it was trained at a clean commit git knows, the code at that commit is fingerprinted again the
    way it is today (a stored code of an older definition, presets included, is no reason to retrain); a checkpoint
    stored before the code was recorded is judged by its ``commit`` (:func:`changed_since`). None too when it cannot
    be checked: ``impl`` names no folder, or an old checkpoint's commit is unknown."""
    now = code_of(impl)
    if now is None:
        return None
    if state.get("code"):
        full = known(state.get("commit", ""))
        if state["code"] == now or (full is not None and fingerprint(_folder(impl), full) == now):
            return None
        return f"it was trained by methods/{_folder(impl)} code {state['code']}, which is {now} now"
    older = changed_since(_folder(impl), state.get("commit", "unrecorded"))
    return None if older is None else f"it was trained by methods/{_folder(impl)} as of {older[:7]}, which has changed since"


def impls() -> list:
    """Every implementation folder under ``methods/`` (those with an ``__init__.py``)."""
    return sorted(p.parent.name for p in (PROJECT_ROOT / "methods").glob("*/__init__.py"))


def current_code() -> dict:
    """{:func:`code_key`: fingerprint} of the working tree's code of every implementation on every track."""
    return {code_key(impl, track): fingerprint(impl, None, track) for impl in impls() for track in TRACKS}

