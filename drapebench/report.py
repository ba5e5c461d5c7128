"""Tables (Markdown, LaTeX, CSV) and runtime-vs-error plots from run directories.

``python -m drapebench.report <run or sweep dirs> --table baseline --out reports/baseline``
gathers every ``metrics.json`` below the given folders and writes ``<out>.md``, ``<out>.tex``,
``<out>.csv`` and ``<out>_runtime.png``, each with its provenance (command, commit, machine).
Layout as in the papers: methods as rows, garments as column groups, metrics as sub-columns;
where a metric has a ``<metric>_std`` column it is shown as mean +- std.
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import re
import shlex
import sys
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from drapebench.cache import PROJECT_ROOT, atomic_write, atomic_write_set
from drapebench.plugins import declared, known_impl
from drapebench.results import SUMMARY_COLUMNS, legend, metric_catalogue, metric_decimals, metric_info, metric_label
from drapebench.run_archive import converged_of, portable_checkpoint
from drapebench.table_file import write_csv
from drapebench.table_specs import spec, specs
from drapebench.train.convergence import converged_seconds

CASE_COLUMNS = ["method", "garment", "motion", "shape", "dtype", "n_frames"]  # a row of a per-run table
ENERGY_PARTS = ("energy_stvk", "energy_bending", "energy_gravity")  # summed into energy_j (J per frame)


def speedup_reference() -> str | None:
    """The row runtime tables give every method's speed-up over: the physics reference run as a method, as its
    package declares it (``tables.SPEEDUP_REFERENCE``, :mod:`drapebench.plugins`); None when none does."""
    found = [row for _, row in declared("tables", "SPEEDUP_REFERENCE")]
    if len(found) > 1:
        raise ValueError(f"several methods declare themselves the speed-up reference: {', '.join(found)}")
    return found[0] if found else None


def floor_methods() -> dict[str, str]:
    """{row: what it is}: the rows that run the reference's drape by other means against the reference (their
    vertex error is the reference's distance from itself), as the method packages declare them
    (``tables.REFERENCE_FLOOR``)."""
    return {row: what for _, rows in declared("tables", "REFERENCE_FLOOR") for row, what in rows.items()}


def reference_floor(df: pd.DataFrame, group: str = "garment") -> str:
    """The note under a vertex-error table on how far the reference is from itself: the :func:`floor_methods`
    rows' vertex error per ``group`` value, or the command that measures it when the runs have none ("" when the
    runs have no vertex error, or no method declares such rows)."""
    floors = floor_methods()
    if "vertex_error_mm" not in df or not df["vertex_error_mm"].notna().any() or not floors:
        return ""
    floor = df[df["method"].isin(list(floors)) & df["vertex_error_mm"].notna()]
    head = ("Reference floor: a method's vertex error means little below the reference's distance from itself, "
            "its own rows")  # fmt: skip
    if floor.empty:
        return (f"Reference floor: not measured for these scenes; run the table's sweep with "
                f"`method={','.join(floors)}` (the reference drape computed by {' and by '.join(floors.values())}).")
    parts = []
    for method, rows in floor.groupby("method", sort=False):
        cells = ", ".join(f"{k} {v:.1f}" for k, v in rows.groupby(group, sort=False)["vertex_error_mm"].mean().items())
        parts.append(f"`{method}`, {floors[method]}: {cells} mm")
    return f"{head}: " + "; ".join(parts) + "."


def _job_order(path: Path) -> list:
    """Sort key putting sweep job folders in job order (2_x before 10_x)."""
    return [int(p) if p.isdigit() else p for p in re.split(r"(\d+)", str(path))]


def _run_files(d: Path, name: str) -> list[Path]:
    """``d/name`` when ``d`` is a run dir, else every ``name`` below ``d`` (a sweep), in job order."""
    return [d / name] if (d / name).exists() else sorted(d.rglob(name), key=_job_order)


def join_registry(run_dir: Path) -> dict:
    """A method that ``run_dir``'s ``config.yaml`` names by import path joins the registry, so that its package's
    declarations (its diagnostics' labels, its tables) are read (:func:`drapebench.plugins.known_impl`); returns that
    config ({} without one)."""
    conf = Path(run_dir) / "config.yaml"
    cfg = (yaml.safe_load(conf.read_text()) or {}) if conf.exists() else {}
    if cfg:
        method = cfg.get("method") or {}
        known_impl(str(method.get("name")), method.get("impl"))
    return cfg


def _run_presets(cfg: dict) -> dict:
    """The training and reference-set presets a run's config names (``train_preset``, ``data_preset``: the names of
    its ``train`` and ``data``), {} where it names none."""
    return {f"{k}_preset": str(cfg[k]["name"]) for k in ("train", "data") if isinstance(cfg.get(k), dict) and cfg[k].get("name")}


def collect(dirs) -> pd.DataFrame:
    """One row per ``metrics.json`` found below ``dirs`` (a run dir or a sweep dir, jobs in job order; a method its
    ``config.yaml`` names by import path joins the registry, :func:`drapebench.plugins.known_impl`), with its
    ``run_dir`` and, for a run that trained (a ``losses.csv`` beside it), ``converged_s``
    (:func:`drapebench.train.convergence.converged_seconds`; a run restored from an archive without its
    ``losses.csv``: the value recorded, :func:`drapebench.run_archive.converged_of`)."""
    rows = []
    for d in dirs:
        d = Path(d)
        for f in _run_files(d, "metrics.json"):
            rec = json.loads(f.read_text())
            rec["run_dir"] = str(f.parent)
            env = f.parent / "env.json"
            if env.exists():  # the torch threads the run drew with: a drape time depends on them
                rec["torch_threads"] = json.loads(env.read_text()).get("torch_threads")
            rec.update(_run_presets(join_registry(f.parent)))
            losses = f.parent / "losses.csv"  # without it (a run restored from an archive): its record of the time
            converged = (converged_seconds(losses, rec["train_s"]) if losses.exists() else converged_of(f.parent)) if rec.get("train_s") else None
            if converged is not None:
                rec["converged_s"] = converged
            rows.append(rec)
    if not rows:
        raise FileNotFoundError(f"no metrics.json below {', '.join(map(str, dirs))}; did the runs finish?")
    return with_scene(with_loss_gap(with_energy(pd.DataFrame(rows))))


def with_energy(df: pd.DataFrame) -> pd.DataFrame:
    """``df`` with ``energy_j`` (J per frame) = StVK + bending + gravity energy where the runs have the three
    (the collision penalty has no physical stiffness, so collisions are counted by eps_c instead)."""
    if all(c in df for c in ENERGY_PARTS) and "energy_j" not in df:
        df = df.assign(energy_j=df[list(ENERGY_PARTS)].sum(axis=1, min_count=len(ENERGY_PARTS)))
    return df


OPTIMUM_SUFFIX = "_optimum"  # method <m>'s loss optimum runs as method <m>_optimum


def with_loss_gap(df: pd.DataFrame) -> pd.DataFrame:
    """``df`` with ``loss_gap_closed`` (%) where a run scores its own loss on its drape and its untrained start
    (a metric its method declares ``own_loss``, :class:`drapebench.metric_info.MetricInfo`: ``<loss>`` and
    ``<loss>@untrained``) and runs of ``<method>_optimum`` score the same scene (garment, motion, shape, body):
    100 (L_untrained - L) / (L_untrained - L_optimum), the share of the gap from the untrained start to the loss's
    optimum (mean over the optimum's runs of the scene) that training closes; undefined (NaN, "–" in a table) where
    the optimum is not below the untrained start (no gap to close)."""
    keys = [c for c in ("garment", "motion", "shape", "body") if c in df]
    gap = None
    for loss in (n for n, info in metric_catalogue().items() if info.own_loss):
        if not {loss, f"{loss}@untrained", "method"} <= set(df):
            continue
        optima = df[df["method"].astype(str).str.endswith(OPTIMUM_SUFFIX)].groupby(["method", *keys], dropna=False)[loss].mean()
        opt = [optima.get((f"{r['method']}{OPTIMUM_SUFFIX}", *(r[k] for k in keys)), np.nan) for _, r in df.iterrows()]
        start = df[f"{loss}@untrained"]
        gap_size = start - np.asarray(opt, dtype=float)
        closed = 100.0 * (start - df[loss]) / gap_size.where(gap_size > 0)
        gap = closed if gap is None else gap.fillna(closed)
    return df if gap is None else df.assign(loss_gap_closed=gap)


def with_scene(df: pd.DataFrame) -> pd.DataFrame:
    """``df`` with a ``scene`` column, "<garment> <motion>", and a ``case`` column, "<motion> <body shape>": the
    column groups of tables over several motions (and shapes)."""
    if {"garment", "motion"} <= set(df):
        df = df.assign(scene=df["garment"].astype(str) + " " + df["motion"].astype(str))
    if {"motion", "shape"} <= set(df):
        df = df.assign(case=df["motion"].astype(str) + " " + df["shape"].astype(str))
    return df


def collect_failures(dirs) -> pd.DataFrame:
    """One row per ``failed.json`` below ``dirs`` (runs recorded with ``on_failure=record``), with its ``run_dir``;
    an empty frame when none failed."""
    rows = []
    for d in map(Path, dirs):
        rows += [{**json.loads(f.read_text()), "run_dir": str(f.parent)} for f in _run_files(d, "failed.json")]
    return with_scene(pd.DataFrame(rows))


def collect_unfinished(dirs) -> pd.DataFrame:
    """One row per Hydra job folder below ``dirs`` (its ``.hydra/overrides.yaml``) without ``metrics.json`` or
    ``failed.json``: a job interrupted (killed, out of memory, Ctrl-C) or still running. ``status`` "unfinished", its
    method, garment and motion (from its ``config.yaml``, else Hydra's), a ``message`` with the command that finishes it
    (its overrides, shell-quoted, into its own folder as a single run: ``hydra.mode=RUN``, as an experiment's sweep sets
    MULTIRUN), and its ``run_dir``; an empty frame when there is none."""
    from drapebench.garments import garment_label

    rows = []
    for overrides in (f for d in map(Path, dirs) for f in _run_files(d, "overrides.yaml") if f.parent.name == ".hydra"):
        job = overrides.parent.parent
        if (job / "metrics.json").exists() or (job / "failed.json").exists():
            continue
        conf = job / "config.yaml" if (job / "config.yaml").exists() else overrides.parent / "config.yaml"
        cfg = (yaml.safe_load(conf.read_text()) or {}) if conf.exists() else {}
        given = " ".join(shlex.quote(str(o)) for o in yaml.safe_load(overrides.read_text()) or [])
        rows.append({"status": "unfinished", "method": (cfg.get("method") or {}).get("name"), "garment": garment_label(cfg.get("garment") or {"kind": None}),
                     "motion": (cfg.get("motion") or {}).get("name"), "run_dir": str(job),
                     "message": f"no metrics.json or failed.json: the job was interrupted or is still running (its log: {job / 'run.log'}); "
                                f"finish it with python run.py {given} {shlex.quote(f'hydra.run.dir={job}')} hydra.mode=RUN (a training resumes from its checkpoint)"})  # fmt: skip
    return pd.DataFrame(rows)


def failure_notes(failed: pd.DataFrame, where, what: str = "failed") -> str:
    """One line per distinct failure message (the runs it stopped, "method on <where(row)>", named once each, with
    a count where runs repeat, then ``what`` and the message), in the order the failures were found; "" when none
    failed."""
    if failed.empty:
        return ""
    lines = []
    for message, rows in failed.groupby("message", sort=False):
        runs = pd.Series([f"{r.method} on {where(r)}" for _, r in rows.iterrows()]).value_counts(sort=False)
        names = ", ".join(f"{name}{f' (x{n})' if n > 1 else ''}" for name, n in runs.items())
        lines.append(f"\n- {names} {what}: {message}")
    return "".join(lines)


def reference_failure_notes(df: pd.DataFrame, where) -> str:
    """:func:`failure_notes` of the runs whose reference drape failed (``reference_error`` in metrics.json): they
    have every metric but the vertex error; "" when none."""
    if "reference_error" not in df:
        return ""
    lost = df[df["reference_error"].notna()].rename(columns={"reference_error": "message"})
    return failure_notes(lost, where, "have no vertex error, their reference failed")


def mark_failures(t: pd.DataFrame, failed: pd.DataFrame, group: str = "garment") -> pd.DataFrame:
    """``t`` (from :func:`table`) with every cell of a failed (method, group value) set to "failed"
    (rows and column groups added where no run of them finished)."""
    if failed.empty:
        return t
    metrics = list(dict.fromkeys(m for _, m in t.columns)) if len(t.columns) else []
    groups = list(dict.fromkeys([g for g, _ in t.columns] + list(failed[group])))
    cols = pd.MultiIndex.from_tuples([(g, m) for g in groups for m in metrics], names=t.columns.names)
    rows = list(dict.fromkeys(list(t.index) + list(failed["method"])))
    out = t.astype(object).reindex(index=pd.Index(rows, name=t.index.name), columns=cols).astype(object).fillna("–")
    for _, f in failed.iterrows():
        out.loc[f["method"], [(f[group], m) for m in metrics]] = "failed"
    return out


SEED_COLUMNS = ("seed", "train_seed")  # what tells runs that differ only in their seed apart


def seed_ids(df: pd.DataFrame) -> pd.Series:
    """One label per run naming its seeds ("0", or "0/3" where the training seed differs from the run's seed);
    "" for runs that record none."""
    cols = [c for c in SEED_COLUMNS if c in df]
    if not cols:
        return pd.Series("", index=df.index)
    parts = df[cols].astype(object).where(df[cols].notna(), "")
    return parts.apply(lambda r: "/".join(dict.fromkeys(str(int(v)) if v != "" else "" for v in r)).strip("/"), axis=1)


def seed_stats(g: pd.DataFrame, metric: str) -> tuple[float, float, int]:
    """Mean, sample std and count of ``metric`` over the seeds of the runs ``g`` (one table cell): each seed's
    runs (its scenes: shapes, motions) are averaged first, then the seeds; std is nan for one seed."""
    per_seed = g.groupby(seed_ids(g), sort=False)[metric].mean().dropna()
    n = len(per_seed)
    return (float(per_seed.mean()) if n else float("nan"), float(per_seed.std(ddof=1)) if n > 1 else float("nan"), n)


def unbalanced_seeds(df: pd.DataFrame, group: str) -> list[str]:
    """The (method, ``group`` value) cells whose seeds cover different scenes (not comparable as seeds)."""
    scene_cols = [c for c in ("garment", "motion", "shape", "body", "dtype") if c in df and c != group]
    out = []
    for (method, value), g in df.groupby(["method", group], sort=False):
        scenes = g.assign(_seed=seed_ids(g)).groupby("_seed")[scene_cols].apply(
            lambda s: tuple(sorted(map(tuple, s.astype(str).values))))  # fmt: skip
        if scenes.nunique() > 1:
            out.append(f"{method} on {value}")
    return out


def table(df: pd.DataFrame, metrics: list[str], decimals: int | None = None, group: str = "garment") -> pd.DataFrame:
    """Methods x (``group`` value, metric) table of formatted cells (groups: garments, or body shapes with
    ``group="shape"``). Runs of a cell that differ only in their seed give "mean ± std (n=k)" over the k seeds
    (each seed's runs averaged first); a cell of one seed gives its mean, "± std" where the runs carry a
    ``<metric>_std`` column (the spread over frames). ``decimals``: for every metric, or None for each
    metric's own (:func:`drapebench.results.metric_decimals`)."""
    if group not in df:
        raise KeyError(f"the runs have no {group!r} column (written by drapebench.experiment since the table needs it); rerun them")
    cells = {}
    for (method, garment), g in df.groupby(["method", group], sort=False):
        for m in metrics:
            if m not in g or g[m].isna().all():  # a metric this method does not report: the cell stays "–"
                continue
            mean, std, n = seed_stats(g, m)
            std_col = f"{m}_std"
            d = metric_decimals(m) if decimals is None else decimals
            if n > 1:
                cells[(method, garment, m)] = f"{mean:.{d}f} ± {std:.{d}f} (n={n})"
            elif std_col in g and pd.notna(g[std_col].mean()):
                cells[(method, garment, m)] = f"{g[m].mean():.{d}f} ± {g[std_col].mean():.{d}f}"
            else:
                cells[(method, garment, m)] = f"{g[m].mean():.{d}f}"
    methods = list(dict.fromkeys(df["method"]))
    garments = list(dict.fromkeys(df[group]))
    cols = pd.MultiIndex.from_tuples([(g, metric_label(m)) for g in garments for m in metrics], names=[group, "metric"])
    out = pd.DataFrame(index=pd.Index(methods, name="method"), columns=cols, dtype=object)
    for (method, garment, m), v in cells.items():
        out.loc[method, (garment, metric_label(m))] = v
    return out.fillna("–")


def seeds_note(df: pd.DataFrame, group: str | None) -> str:
    """The line under a table on what its ± means: the seeds behind its cells, and the cells whose seeds
    cover different scenes."""
    ids = seed_ids(df)
    seeds = ", ".join(sorted(set(ids) - {""}, key=lambda s: [int(p) for p in s.split("/")])) or "not recorded"
    if group is None:  # a per-run table: each run its own row, named by its seed where they differ
        return f"Seeds: {seeds} (one row per run{', its seed in the seed column' if ids.nunique() > 1 else ''})."
    counts = df.assign(_seed=ids).groupby(["method"] + ([group] if group else []), sort=False)["_seed"].nunique()
    several = bool((counts > 1).any())
    line = (f"Seeds: {seeds}. A cell \"mean ± std (n=k)\" is the mean and sample std over k training seeds (each "
            "seed's runs averaged first); a \"mean ± std\" without n is one seed's mean and its spread over frames."
            if several else f"Seeds: {seeds} (one per cell: a \"± std\" is the spread over frames, not over seeds).")  # fmt: skip
    bad = unbalanced_seeds(df, group) if group and several else []
    if bad:
        line += f" Not comparable as seeds (their seeds ran different scenes): {', '.join(bad)}."
    return line


def time_cut_note(df: pd.DataFrame) -> str:
    """A warning naming the runs whose model depends on the speed of the machine that trained it (``train_stopped``
    in metrics.json): "time", cut by ``train.max_minutes`` before its budget's last step, and "clock", every step run
    but the learning rate decayed by that clock ahead of the steps ("" when there is none)."""
    if "train_stopped" not in df:
        return ""
    notes = []
    for stop, label, why in (("time", "Time-cut training", "train.max_minutes stopped the training before its budget's last step"),
                             ("clock", "Clock-scheduled training", "every step ran, but the learning rate decayed by train.max_minutes' "
                                                                   "clock ahead of the steps")):  # fmt: skip
        hit = df[df["train_stopped"] == stop]
        if not hit.empty:
            runs = ", ".join(dict.fromkeys(f"{r['method']} {r['garment']} seed {r.get('seed', '?')}" for _, r in hit.iterrows()))
            notes.append(f"**{label}**: {runs}: {why}, so the model depends on the machine's speed (rerun on an idle machine, "
                         "or with a larger max_minutes and force=true).")
    return "\n\n".join(notes)


def short_commit(commit: str) -> str:
    """A full commit hash as its first 7 digits, ``-dirty`` kept (uncommitted code is not the commit's); other labels
    ("unrecorded", "unknown") as they are."""
    return commit[:7] + ("-dirty" if "-dirty" in commit else "") if re.match(r"[0-9a-f]{40}", commit) else commit


def commits_note(df: pd.DataFrame) -> str:
    """A warning naming each method's commits when the runs behind a table come from more than one commit
    ("" when they all come from one)."""
    if "commit" not in df or df["commit"].nunique() <= 1:
        return ""
    per = df.groupby("method", sort=False)["commit"].agg(lambda c: ", ".join(short_commit(str(x)) for x in dict.fromkeys(c)))
    return (f"**Mixed commits**: the rows come from {df['commit'].nunique()} commits, so code changed between them: "
            + "; ".join(f"{m} {c}" for m, c in per.items()) + ".")


def trained_note(df: pd.DataFrame) -> str:
    """A note naming, per method, the commits whose code trained its models where they are not the commit of the
    runs that used them (``trained_at`` in metrics.json: a cached model is keyed by its configuration, not its code;
    "unrecorded" for a model cached before that was recorded); "" when every model was trained at its run's commit."""
    if "trained_at" not in df or "commit" not in df:
        return ""
    other = df[df["trained_at"].notna() & (df["trained_at"] != df["commit"])]
    if other.empty:
        return ""
    per = other.groupby("method", sort=False)["trained_at"].agg(lambda c: ", ".join(short_commit(str(x)) for x in dict.fromkeys(c)))
    return ("**Models trained at**: some models were trained (and cached) by the code of another commit than their runs': "
            + "; ".join(f"{m} {c}" for m, c in per.items()) + ".")


def mixed_models_note(df: pd.DataFrame) -> str:
    """A warning naming each model (method, checkpoint) whose runs in the table read different trainings of it
    (``model_hash`` in metrics.json, the content hash of the trained state: a training resumed after an interruption,
    or made again on another machine, can differ from the first): its cells mix models, and the scoreboard's "cases with
    the same numbers count once" no longer sees their copies. "" when every model is one training, or unrecorded."""
    if "model_hash" not in df or "checkpoint" not in df:
        return ""
    known = df[df["model_hash"].notna() & df["checkpoint"].notna()]
    known = known.assign(checkpoint=known["checkpoint"].map(portable_checkpoint))  # a run restored from the archive names it from cache/ on
    trainings = known.groupby(["method", "checkpoint"], sort=False)["model_hash"].agg(lambda h: list(dict.fromkeys(h)))
    mixed = trainings[trainings.map(len) > 1]
    if mixed.empty:
        return ""
    said = "; ".join(f"{method} ({Path(str(checkpoint)).name}): {', '.join(hashes)}" for (method, checkpoint), hashes in mixed.items())
    return (f"**Mixed trainings**: the runs of one model read different trainings of it ({said}): its cells mix models; delete "
            "the runs of one training (and its cached checkpoint) and run them again.")


def presets_note(df: pd.DataFrame) -> str:
    """The training and reference-set presets of the runs behind a table, "**Presets**: train=cpu, data=cpu." (read by
    the scoreboard: a table's rows are judged by those presets' files, :mod:`drapebench.staleness`), or a note that
    the runs mix them; "" where a run did not record them (made before, or restored without its config)."""
    columns = [f"{k}_preset" for k in ("train", "data")]
    if not all(c in df for c in columns) or df[columns].isna().any(axis=None):
        return ""
    names = {k: sorted(set(map(str, df[f"{k}_preset"]))) for k in ("train", "data")}
    if len(names["train"]) == 1 and len(names["data"]) == 1:
        return f"**Presets**: train={names['train'][0]}, data={names['data'][0]}."
    return (f"**Mixed presets**: the runs mix train={' and '.join(names['train'])} with data={' and '.join(names['data'])}: "
            "make one table per preset (the scoreboard judges this one by its name's track).")


def training_note(df: pd.DataFrame) -> str:
    """A note naming, per trained method, what its models trained on and for how long: the body model (its
    ``trained_body``, which may differ from the scene's), the optimisation steps and the training minutes, each
    model (checkpoint) counted once, a range where its models differ (what runs made before a key was recorded
    lack is left out); "" when no run loaded a trained model."""
    if "checkpoint" not in df:
        return ""
    models = df[df["checkpoint"].notna()].drop_duplicates([c for c in ("checkpoint", "trained_at") if c in df])  # a retrained model keeps its path
    if models.empty:
        return ""

    def spread(values: pd.Series, fmt) -> str | None:  # "a" or "a-b" over the known values, as printed
        known = sorted({fmt(float(v)) for v in values if pd.notna(v)}, key=lambda text: float(text.replace(",", "")))
        return None if not known else known[0] if len(known) == 1 else f"{known[0]}-{known[-1]}"

    parts, unrecorded = [], False
    for method, runs in models.groupby("method", sort=False):
        bodies = ", ".join(dict.fromkeys(map(str, runs["train_body"].dropna()))) if "train_body" in runs else ""
        steps = spread(runs.get("train_steps", pd.Series(dtype=float)), lambda v: f"{v:,.0f}")
        minutes = spread(runs.get("train_s", pd.Series(dtype=float)), lambda v: f"{v / 60:.1f}")
        unrecorded |= not bodies or steps is None
        said = ", ".join(x for x in (f"{steps} steps" if steps else "", f"{minutes} min" if minutes else "") if x)
        parts.append(f"{method}{' on ' + bodies if bodies else ''}: {said or 'unrecorded'} ({len(runs)} model{'s' if len(runs) > 1 else ''})")
    return ("**Training**: per method, the body model its models trained on, their optimisation steps and training "
            "minutes (from each run's metrics.json; a cached model counts once): " + "; ".join(parts) + "."
            + (" Where a body or the steps are missing, the runs predate their recording." if unrecorded else ""))


def run_table(df: pd.DataFrame, failed: pd.DataFrame, metrics: list[str], decimals: int | None = None) -> pd.DataFrame:
    """One row per run (its scene in ``CASE_COLUMNS``, then ``metrics``), the failed runs' metric cells
    "failed"; rows in the order of the runs; ``decimals`` as :func:`table`'s."""
    cases = [c for c in CASE_COLUMNS if c in df or c in failed]
    if seed_ids(df).nunique() > 1:  # runs that differ only in their seed stay apart, named by it
        df = df.assign(seed=seed_ids(df))
        cases.append("seed")
    done = df.reindex(columns=cases + metrics).astype(object)
    for m in metrics:
        d = metric_decimals(m) if decimals is None else decimals
        done[m] = [f"{v:.{d}f}" if pd.notna(v) else "–" for v in df.get(m, pd.Series([float("nan")] * len(df)))]
    bad = failed.reindex(columns=cases).assign(**{m: "failed" for m in metrics}) if len(failed) else None
    out = pd.concat([done, bad]) if bad is not None else done
    return out.fillna("–").set_index("method")


def provenance(df: pd.DataFrame, command: str) -> str:
    """One line naming the command, commits, machine, the runs' torch threads (their ``env.json``; a drape time
    depends on them) and date that produced the table."""
    commits = ", ".join(sorted(set(map(str, df.get("commit", pd.Series(["unknown"]))))))
    when = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    counts = sorted({int(t) for t in df.get("torch_threads", pd.Series(dtype=float)).dropna()})
    threads = f", {' or '.join(map(str, counts))} torch thread{'s' if counts != [1] else ''} per run" if counts else ""
    return f"Produced by `{command}` from runs at commit(s) {commits} on {platform.machine()} / {platform.system()}{threads} ({when})."


def scene(df: pd.DataFrame) -> str:
    """One line naming the garments, bodies and their shapes ("mean", "b0=-1,b1=1.5": the nonzero betas), motions and
    reference drapes of the runs behind a table."""

    def names(col: str, missing: str = "not recorded") -> str:
        return ", ".join(dict.fromkeys(map(str, df[col].dropna()))) if col in df and df[col].notna().any() else missing

    ref = names("reference", "vbd or style3d (not recorded)" if df.get("vertex_error_mm", pd.Series(dtype=float)).notna().any() else "none")
    shapes = list(dict.fromkeys(map(str, df["shape"].dropna()))) if "shape" in df else []
    shape = f" ({'shapes' if len(shapes) > 1 else 'shape'} {' / '.join(shapes)})" if shapes else ""
    return f"Scene: garments {names('garment')}; body {names('body')}{shape}; motions {names('motion')}; reference drape {ref}."


MAX_MARKDOWN_COLUMNS = 12  # a wider grouped table is written as one table per group


def _markdown(t: pd.DataFrame) -> str:
    """``t`` as markdown: its (group, metric) columns flattened to "group metric", or, past
    ``MAX_MARKDOWN_COLUMNS``, one table per group under a "**group**" line, without the rows that
    were not run in that group (every cell "–")."""
    if not isinstance(t.columns, pd.MultiIndex):
        return t.rename(columns=metric_label).to_markdown()
    groups = list(dict.fromkeys(t.columns.get_level_values(0)))
    if len(t.columns) > MAX_MARKDOWN_COLUMNS and len(groups) > 1:
        return "\n\n".join(f"**{g}**\n\n{t[g][(t[g] != '–').any(axis=1)].to_markdown()}" for g in groups)
    flat = t.copy()
    flat.columns = [f"{g} {m}" for g, m in t.columns]
    return flat.to_markdown()


def runtime_error(df: pd.DataFrame) -> str:
    """The accuracy axis of a runtime plot: ``vertex_error_mm`` when the runs have a reference, else ``eps_e``."""
    return "vertex_error_mm" if "vertex_error_mm" in df and df["vertex_error_mm"].notna().any() else "eps_e"


def label_places(ms: np.ndarray, err: np.ndarray) -> list[tuple[int, int, float]]:
    """Where the labels of a log-x scatter (ms (N,) > 0, err (N,)) go so that labels of nearby points do
    not overlap: per point, the indices of the points whose x and whose y its label is placed beside and
    the label's vertical offset from there (points). Points within 0.2 decades and 6 % of the y span of
    each other form a cluster, whose labels stack 9 points apart, right of its rightmost point, from the
    height of its highest point down."""
    ms, err = np.asarray(ms, float), np.asarray(err, float)
    u = np.log10(np.maximum(ms, 1e-12))
    finite = err[np.isfinite(err)]
    span = float(finite.max() - finite.min()) if len(finite) else 0.0
    v = (err - (finite.min() if len(finite) else 0.0)) / span if span > 0 else np.zeros_like(err)
    parent = list(range(len(ms)))

    def root(i: int) -> int:
        while parent[i] != i:
            i = parent[i]
        return i

    for i in range(len(ms)):
        for j in range(i):
            if abs(u[i] - u[j]) < 0.2 and abs(v[i] - v[j]) < 0.06:
                parent[root(i)] = root(j)
    places = [(i, i, 3.0) for i in range(len(ms))]
    for c in {root(i) for i in range(len(ms))}:
        members = sorted((i for i in range(len(ms)) if root(i) == c), key=lambda i: -np.nan_to_num(err[i], nan=-np.inf))
        right = max(members, key=lambda i: ms[i])
        for k, i in enumerate(members):
            places[i] = (right, members[0], 3.0 - 9.0 * k)
    return places


def _annotate(ax, labels, ms, err, colours=None) -> None:
    """Labels beside the points (ms, err) of a log-x scatter, stacked where points crowd (:func:`label_places`),
    each joined to its point by a thin line when it is not beside it; ``colours``: one text colour per label."""
    from matplotlib.text import OffsetFrom

    ms, err = np.asarray(ms, float), np.asarray(err, float)
    colours = list(colours) if colours is not None else ["black"] * len(ms)
    for i, (label, x, y, (at_x, at_y, dy), colour) in enumerate(zip(labels, ms, err, label_places(ms, err), colours)):
        where = OffsetFrom(ax.transData, (ms[at_x], err[at_y]), unit="points")
        beside = at_x == at_y == i
        line = None if beside else dict(arrowstyle="-", lw=0.5, color=colour, shrinkA=0, shrinkB=3)
        ax.annotate(label, (x, y), xytext=(6, dy), textcoords=where, fontsize=7, color=colour,
                    va="bottom" if beside else "center", arrowprops=line)  # fmt: skip
    ax.margins(x=0.08, y=0.12)  # room for the labels of the outermost points


def _minor_labels(span: float):
    """The formatter of a log axis' minor ticks over ``span`` (max / min): every one labelled within a factor 3, those
    at 2, 3 and 5 times a power of ten within 30 (all of them crowd near each power: 0.70.80.91), none beyond."""
    import matplotlib.ticker

    def label(v: float, _) -> str:
        mantissa = round(v / 10 ** math.floor(math.log10(v) + 1e-9), 6)
        return f"{v:g}" if span < 3 or (span < 30 and mantissa in (2, 3, 5)) else ""

    return matplotlib.ticker.FuncFormatter(label)


def runtime_plot(df: pd.DataFrame, path: Path, title: str = "") -> Path:
    """Scatter of drape time (ms/frame, log x) against :func:`runtime_error`, one marker per run: its
    colour the method, its shape the scene where the runs' scenes differ (garment, body shape, motion,
    body: those that vary), each with a legend."""
    import matplotlib
    import matplotlib.ticker

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    error = runtime_error(df)
    fig, ax = plt.subplots(figsize=(8.0, 4.4))
    varying = [c for c in ("garment", "shape", "motion", "body") if c in df and df[c].nunique() > 1]
    scene = df[varying].astype(str).agg(", ".join, axis=1) if varying else pd.Series("", index=df.index)
    shapes = {k: ("os^DvPX*<>phd8H"[i % 15], i // 15 % 2 == 0) for i, k in enumerate(dict.fromkeys(scene))}  # (marker, filled)
    colour = {m: f"C{i % 10}" for i, m in enumerate(dict.fromkeys(df["method"]))}
    for (method, key), g in df.groupby([df["method"], scene], sort=False):
        marker, filled = shapes[key]
        ax.scatter(g["ms_per_frame"], g[error], marker=marker, s=36, color=colour[method] if filled else "none", edgecolors=colour[method])
    methods = [Line2D([], [], color=c, marker="o", ls="", label=m) for m, c in colour.items()]
    # both legends right of the axes (inside they can hide points), the scenes' below the methods'
    by_method = ax.add_artist(ax.legend(handles=methods, fontsize=7, title="method", title_fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0)))
    if varying:
        fig.canvas.draw()  # the methods' legend's height is known once drawn
        below = by_method.get_window_extent().transformed(ax.transAxes.inverted()).y0 - 0.02
        scenes = [Line2D([], [], color="grey", marker=m, ls="", label=k, markerfacecolor="grey" if filled else "none")
                  for k, (m, filled) in shapes.items()]  # fmt: skip
        names = {"shape": "body shape"}
        ax.legend(handles=scenes, fontsize=7, title=", ".join(names.get(c, c) for c in varying), title_fontsize=7, loc="upper left",
                  bbox_to_anchor=(1.01, below))  # fmt: skip
    ax.set_xscale("log")
    plain = matplotlib.ticker.FuncFormatter(lambda v, _: f"{v:g}")  # 2, not 2 x 10^0
    ax.xaxis.set_major_formatter(plain)
    span = df["ms_per_frame"].max() / max(df["ms_per_frame"].min(), 1e-9)
    ax.xaxis.set_minor_formatter(_minor_labels(span))
    ax.set_xlabel("drape time per frame (ms, log scale; lower is better)", fontsize=9)
    info = metric_info(error)
    ax.set_ylabel(f"{error}: {info.meaning} ({info.unit})", fontsize=9)
    ax.set_title(f"{title + ': ' if title else ''}runtime against {error} (lower left is better)", fontsize=10)
    ax.grid(alpha=0.3)
    return save_figure(fig, path)


def pareto_plot(df: pd.DataFrame, path: Path, title: str = "") -> Path:
    """Drape time (ms/frame, log x) against :func:`runtime_error`, one panel per garment, a colour per
    method (runs of a method on a garment averaged, labelled with the method); the methods no other is
    both faster and more accurate than are joined by a line (the Pareto front)."""
    import matplotlib
    import matplotlib.ticker

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    error = runtime_error(df)
    means = df.groupby(["garment", "method"], sort=False)[["ms_per_frame", error]].mean().reset_index()
    garments = list(dict.fromkeys(means["garment"]))
    colours = {m: f"C{i}" for i, m in enumerate(dict.fromkeys(means["method"]))}
    cols = len(garments) if len(garments) <= 3 else 2  # four garments: two rows of two
    rows = -(-len(garments) // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(4.6 * cols, 4.0 * rows + 0.6), squeeze=False)
    for ax in axes.flat[len(garments):]:
        ax.set_visible(False)
    for ax, garment in zip(axes.flat, garments):
        g = means[(means["garment"] == garment) & means[error].notna()].sort_values("ms_per_frame")
        for _, r in g.iterrows():
            ax.scatter(r["ms_per_frame"], r[error], color=colours[r["method"]], s=40)
        _annotate(ax, g["method"], g["ms_per_frame"], g[error], [colours[m] for m in g["method"]])
        front = g[g[error] <= g[error].cummin()]
        ax.plot(front["ms_per_frame"], front[error], color="grey", lw=0.8, ls="--", label="Pareto front")
        ax.set_xscale("log")
        ax.xaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(lambda v, _: f"{v:g}"))
        ax.set_xlabel("drape time per frame (ms, log scale)", fontsize=9)
        ax.set_ylabel(f"{error}: {metric_info(error).meaning} ({metric_info(error).unit})", fontsize=8)
        ax.set_title(garment, fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle(f"{title + chr(10) if title else ''}runtime against {error}\n(lower left is better)", fontsize=10)
    return save_figure(fig, path)


def speedups(df: pd.DataFrame, reference: str | None = None) -> str:
    """One markdown line per garment: each method's speed-up over ``reference`` (default :func:`speedup_reference`;
    its mean ms/frame over the method's); empty when the runs have no ``reference`` method."""
    reference = reference or speedup_reference()
    if reference not in set(df["method"]):
        return ""
    ms = df.groupby(["garment", "method"], sort=False)["ms_per_frame"].mean()
    lines = []
    for garment in dict.fromkeys(df["garment"]):
        if (garment, reference) not in ms:
            continue
        ref = ms[(garment, reference)]
        lines.append(f"- {garment}: " + ", ".join(f"{m} {ref / v:.3g}x" for (g, m), v in ms.items() if g == garment and m != reference))
    return f"Speed-up over `{reference}` (its ms/frame over the method's):\n" + "\n".join(lines) if lines else ""


def metric_bars_plot(df: pd.DataFrame, metrics: list[str], path: Path, title: str = "") -> Path:
    """One panel per metric of ``metrics``: a bar per method (its seeds' mean, as the tables average them) with
    the seeds' sample std as the error bar and each seed as a dot; garments side by side where there are
    several. Written to ``path`` (PNG); returns it."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    methods = list(dict.fromkeys(df["method"]))
    garments = list(dict.fromkeys(df["garment"]))
    fig, axes = plt.subplots(1, len(metrics), figsize=(3.4 * len(metrics) + 0.6, 3.6), squeeze=False)
    width = 0.8 / len(garments)
    for ax, m in zip(axes[0], metrics):
        for j, garment in enumerate(garments):
            for i, method in enumerate(methods):
                g = df[(df["method"] == method) & (df["garment"] == garment)]
                if m not in g or g[m].isna().all():
                    continue
                mean, std, _ = seed_stats(g, m)
                x = i + (j - (len(garments) - 1) / 2) * width
                ax.bar(x, mean, width * 0.9, yerr=None if np.isnan(std) else std, color=f"C{j}", capsize=3,
                       label=garment if i == 0 else None)  # fmt: skip
                per_seed = g.groupby(seed_ids(g))[m].mean()  # a dot per seed, the runs of one seed averaged
                ax.plot([x] * len(per_seed), per_seed, "k.", ms=3)
        info = metric_info(m)
        ax.set_xticks(range(len(methods)), methods, rotation=30, ha="right", fontsize=8)
        ax.set_ylabel(f"{info.label}", fontsize=9)
        ax.set_title(info.meaning, fontsize=8)
        ax.axhline(0, color="grey", lw=0.6)
        ax.grid(alpha=0.3, axis="y")
    if len(garments) > 1:
        axes[0][-1].legend(fontsize=7, title="garment", title_fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    fig.suptitle(f"{title + ': ' if title else ''}mean over seeds, error bar the seeds' std, dots the seeds", fontsize=10)
    return save_figure(fig, path)


def save_figure(fig, path: Path) -> Path:
    """Lay out ``fig``, write it to ``path`` as a PNG atomically and close it; returns ``path``."""
    import matplotlib.pyplot as plt
    from matplotlib.legend import Legend

    fig.tight_layout(rect=(0, 0, 1, 0.93) if fig.get_suptitle() else None)  # room for a figure title
    legends = [a for ax in fig.axes for a in ax.get_children() if isinstance(a, Legend)]  # those outside the axes too
    with atomic_write(path, mode=None) as tmp:
        fig.savefig(tmp, dpi=130, format="png", bbox_inches="tight", bbox_extra_artists=fig.get_default_bbox_extra_artists() + legends)
    plt.close(fig)
    return path


def loss_curve_plot(losses_csv: Path, path: Path | None = None) -> Path:
    """Plot a run's ``losses.csv`` (drapebench.train): the loss and each term against the step, log y
    (a term with values <= 0 is drawn as its absolute value, labelled |term|); written to ``path``
    (default ``losses.png`` beside the csv). Returns the path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    losses_csv = Path(losses_csv)
    df = pd.read_csv(losses_csv)
    if df.empty:
        raise ValueError(f"{losses_csv} has no steps to plot")
    path = Path(path) if path is not None else losses_csv.with_name("losses.png")
    fig, ax = plt.subplots(figsize=(6, 3.8))
    for col in [c for c in df.columns if c not in ("step", "epoch", "lr", "grad_norm")]:
        y = df[col]
        signed = bool((y <= 0).any())
        ax.plot(df["step"], y.abs() if signed else y, label=f"|{col}|" if signed else col, lw=1.6 if col == "loss" else 0.9,
                color="black" if col == "loss" else None)  # fmt: skip
    ax.set_yscale("log")
    ax.set_xlabel("step")
    ax.set_ylabel("loss term (weighted)")
    ax.set_title(f"training loss: {losses_csv.parent.name}", fontsize=9)
    ax.legend(fontsize=7, ncol=2)
    ax.grid(alpha=0.3)
    return save_figure(fig, path)


EVALUATION_LABELS = {
    "val_colliding_pct": "validation reconstructions",
    "sampled_colliding_pct": "decoded samples z ~ N(0, I)",
    "sampled_codes_colliding_pct": "decoded samples at the codes' spread",
}


def evaluation_plot(dirs, path: Path, columns=tuple(EVALUATION_LABELS), title: str = "", command: str | None = None,
                    methods: list[str] | None = None) -> Path:
    """Per-epoch evaluations of trained runs (``evaluations.csv`` beside each run's ``metrics.json``) against
    the epoch: one colour per method (``methods``, in their order; None: every method with evaluations), one line
    style per column of ``columns`` (percentages). Runs of one method sharing a training seed (a checkpoint) count
    once; several seeds draw their mean and a band from their minimum to their maximum. Written to ``path`` (PNG),
    the curves' numbers beside it (``path`` with ``.csv``: per method and quantity, each epoch's mean ± sample std
    over the seeds in %), its footer naming ``command`` (default: this module's command over ``dirs``); returns the
    PNG's path."""
    from drapebench.table_file import write_csv

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    df = only_methods(collect(dirs), methods)
    curves: dict[str, dict] = {}  # method -> training seed -> its evaluations
    for _, r in df.iterrows():
        csv = Path(r["run_dir"]) / "evaluations.csv"
        if csv.exists():
            curves.setdefault(r["method"], {}).setdefault(r.get("train_seed", r.get("seed")), pd.read_csv(csv))
    if not curves:
        raise FileNotFoundError(f"no evaluations.csv in the runs below {', '.join(map(str, dirs))} (only methods that evaluate per epoch write one)")
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    styles = ["-", "--", ":", "-."]
    cells: dict[str, dict] = {}  # method -> (quantity, "epoch k (%)") -> "mean ± sample std (n=seeds)"
    for i, (method, runs) in enumerate(curves.items()):
        ev = pd.concat(list(runs.values()))
        for j, col in enumerate(c for c in columns if c in ev):
            per_epoch = ev.groupby("epoch")[col]
            mean, std = per_epoch.mean(), per_epoch.std()
            x = np.asarray(mean.index) + 1
            text = [f"{m:.4f}" + (f" ± {s:.4f} (n={len(runs)})" if len(runs) > 1 else "") for m, s in zip(mean, std)]
            quantity = EVALUATION_LABELS.get(col, col)
            cells.setdefault(method, {}).update({**{(quantity, f"epoch {e} (%)"): t for e, t in zip(x, text)}, (quantity, "last epoch (%)"): text[-1]})
            label = f"{method}: {quantity}" + (f" ({len(runs)} seeds)" if len(runs) > 1 else "")
            ax.plot(x, per_epoch.mean(), styles[j % len(styles)], color=f"C{i}", label=label)
            if len(runs) > 1:
                ax.fill_between(x, per_epoch.min(), per_epoch.max(), color=f"C{i}", alpha=0.15, lw=0)
    ax.set_xlabel("training epoch", fontsize=9)
    ax.set_ylabel("garment vertices inside the canonical body (%)", fontsize=9)
    ax.set_title(title or "collisions in the canonical space per training epoch", fontsize=10)
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    scenes = ", ".join(sorted({f"{r['garment']} {r.get('body', '')}".strip() for _, r in df.iterrows()})) if "garment" in df else "unknown"
    command = command or f"python -m drapebench.report {' '.join(map(str, dirs))} --evaluations"
    wide = pd.DataFrame.from_dict(cells, orient="index").rename_axis("method")
    wide.columns = pd.MultiIndex.from_tuples(wide.columns, names=["quantity", "metric"])
    write_csv(Path(path).with_suffix(".csv"), [provenance(df, command), f"Per-epoch evaluations (evaluations.csv) of the runs; "
                                               f"garment(s) {scenes}.", "Legend: % of garment vertices inside the canonical "
                                               "body (lower) per training epoch, mean ± sample std over the training seeds (n)."], wide)  # fmt: skip
    return save_figure(fig, path)


def only_methods(df: pd.DataFrame, methods: list[str] | None, failed: frozenset = frozenset()) -> pd.DataFrame:
    """The rows of ``df`` whose method is in ``methods``, in the order given (all rows for None); raises
    ValueError naming a method that no run has, finished or recorded as failed (``failed``: those methods)."""
    if not methods or df.empty:
        return df
    missing = [m for m in methods if m not in set(df["method"]) | failed]
    if missing:
        raise SelectionError(f"no run of method(s) {', '.join(missing)} in the given directories; the runs have: {', '.join(dict.fromkeys(df['method']))}")
    order = {m: i for i, m in enumerate(methods)}
    return df[df["method"].isin(order)].sort_values("method", key=lambda c: c.map(order), kind="stable")


def only_garments(df: pd.DataFrame, garments: list[str] | None) -> pd.DataFrame:
    """The rows of ``df`` whose garment is in ``garments`` (all rows for None); raises ValueError naming a
    garment no run has."""
    if not garments or df.empty:
        return df
    missing = [g for g in garments if g not in set(df["garment"])]
    if missing:
        raise SelectionError(f"no run of garment(s) {', '.join(missing)} in the given directories; the runs have: {', '.join(dict.fromkeys(df['garment']))}")
    return df[df["garment"].isin(garments)]


def write_table(dirs, name: str, out: Path, command: str | None = None, methods: list[str] | None = None,
                garments: list[str] | None = None) -> list[Path]:
    """Write ``out``.md/.tex/.csv and ``out``_runtime.png for table ``name`` by its spec
    (:mod:`drapebench.table_specs`; rows: ``methods`` in that order, or every method of the runs; only the runs of
    ``garments`` when given), and ``out``_bars.png for a spec with ``bars``; returns the paths. A table whose runs
    come from several commits says so in its title."""
    failed = collect_failures(dirs)
    failed_methods = frozenset(failed["method"]) if not failed.empty else frozenset()
    df = only_garments(only_methods(collect(dirs), methods, failed_methods), garments)  # first: the runs' methods declare tables too
    ts = spec(name)
    if not ts.metrics:
        raise KeyError(f"table {name!r} is not made from runs by this command: {ts.command()}")
    metrics, group = list(ts.metrics), ts.group
    if methods and not failed.empty:
        failed = failed[failed["method"].isin(methods)]
    if garments and not failed.empty:
        failed = failed[failed["garment"].isin(garments)]
    t = run_table(df, failed, metrics) if group is None else mark_failures(table(df, metrics, group=group), failed, group=group)
    if methods and group is not None:  # a method all of whose runs failed is added last by mark_failures: back in its place
        t = t.reindex([m for m in methods if m in t.index] + [m for m in t.index if m not in methods])
    command = command or "python -m drapebench.report " + " ".join(sys.argv[1:])
    prov = provenance(pd.concat([df, failed]), command)
    about = f"{scene(pd.concat([df, failed]))}\n\n{legend(metrics)}"
    where = (lambda r: " ".join(str(r.get(c, "")) for c in CASE_COLUMNS[1:5])) if group is None else (lambda r: r[group])  # noqa: E731
    notes = failure_notes(failed, where)
    if "vertex_error_mm" in metrics:
        notes += reference_failure_notes(df, where)
    if ts.note:
        notes += "\n" + ts.note
    if "vertex_error_mm" in metrics and reference_floor(df, group):
        notes += "\n\n" + reference_floor(df, group)
    if ts.pareto and speedups(df):
        notes += "\n\n" + speedups(df)
    notes += "\n\n" + seeds_note(df, group)
    warnings = [n for n in (training_note(df), presets_note(df), time_cut_note(df), commits_note(df), trained_note(df), mixed_models_note(df)) if n]  # written to every format below
    for note in warnings:
        notes += "\n\n" + note
    out = gpu_out(Path(out), df)
    paths = [out.with_suffix(".md"), out.with_suffix(".tex"), out.with_suffix(".csv"), out.parent / f"{out.name}_runtime.png"]
    if ts.bars:
        paths.append(out.parent / f"{out.name}_bars.png")
    mixed = f" (rows from {df['commit'].nunique()} commits)" if "commit" in df and df["commit"].nunique() > 1 else ""
    header = (prov, *about.split("\n\n"), seeds_note(df, group), *(p for n in warnings for p in n.split("\n\n") if p))
    comment = "".join(f"{{c}} {line}\n" for line in header)
    with atomic_write_set(paths) as tmps:  # the table's files are replaced together, or (on an error) none is
        tmps[0].write_text(f"# {name}{mixed}\n\n{_markdown(t)}\n{notes}\n\n{about}\n\n{prov}\n")
        tmps[1].write_text(comment.format(c="%") + t.style.to_latex(hrules=True, multicol_align="c"))
        write_csv(tmps[2], header, t)
        (pareto_plot if ts.pareto else runtime_plot)(df, tmps[3], title=name)
        if ts.bars:
            metric_bars_plot(df, list(ts.bars), tmps[4], title=name)
    return paths


def gpu_out(out: Path, df: pd.DataFrame) -> Path:
    """``out`` with ``_gpu`` appended to its name when the runs ran on a CUDA device (``device=cuda``, the GPU
    track with ``train=paper``), so a GPU table stands beside the CPU one instead of replacing it."""
    devices = set(df["device"].fillna("cpu").astype(str)) if "device" in df else {"cpu"}
    on_gpu = all(d.startswith("cuda") for d in devices)
    if on_gpu and not out.name.endswith("_gpu"):
        return out.with_name(f"{out.name}_gpu")
    if not on_gpu and any(d.startswith("cuda") for d in devices):
        raise SelectionError(f"the runs mix devices ({', '.join(sorted(devices))}): make a table of the CPU runs and one of the GPU runs")
    return out


def write_summary(sweep_dir: Path) -> Path:
    """``summary.md`` and ``summary.csv`` at a sweep root: one row per finished job, per failed one (``status``
    "failed" with its message) and per unfinished one (:func:`collect_unfinished`: "unfinished", with the fix)."""
    failed = pd.concat([collect_failures([sweep_dir]), collect_unfinished([sweep_dir])])
    try:
        df = collect([sweep_dir])
    except FileNotFoundError:
        if failed.empty:
            raise
        df = pd.DataFrame(columns=["method", "garment", "motion"])
    df = pd.concat([df.assign(status="ok"), failed]) if len(failed) else df
    cols = [c for c in ["status", *SUMMARY_COLUMNS, "message"] if c in df] + ["run_dir"]
    df = df[cols]
    with atomic_write(Path(sweep_dir) / "summary.csv", "w") as f:
        df.to_csv(f, index=False)
    with atomic_write(Path(sweep_dir) / "summary.md", "w") as f:
        key = legend(df.columns)
        f.write(df.drop(columns="run_dir").to_markdown(index=False, floatfmt=".4g") + "\n" + (f"\n{key}\n" if key else ""))
    return Path(sweep_dir) / "summary.md"


class SelectionError(ValueError):
    """What the user asked of the runs (methods, garments, a table) that the runs cannot give: :func:`main` prints
    its message as a usage error; any other ValueError is a bug and keeps its traceback."""


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description="Paper-style tables from run or sweep directories.")
    parser.add_argument("dirs", nargs="*", type=Path, help="run or sweep directories (searched for metrics.json)")
    parser.add_argument("--table",
                        help="which table's spec (drapebench/table_specs.py, methods/<name>/tables.py, or the tables.py of a method the "
                        "runs name by import path): its metrics, column groups, notes and plots (default: the one table the runs' "
                        "experiment makes; baseline for plain runs)")  # fmt: skip
    parser.add_argument("--methods", type=lambda s: [m for m in s.split(",") if m],
                        help="comma-separated methods to show, in this order (default: every method of the runs)")
    parser.add_argument("--garments", type=lambda s: [g for g in s.split(",") if g],
                        help="comma-separated garments whose runs the table reads (default: every run's)")
    parser.add_argument("--out", type=Path, help="output path without suffix (default: a new folder outputs/reports/<time>/<table>; "
                        "give reports/<table> to replace a committed table)")
    parser.add_argument("--loss-curves", action="store_true", help="instead: losses.png beside every losses.csv in dirs")
    parser.add_argument("--evaluations", action="store_true",
                        help="instead: one plot of the runs' per-epoch evaluations (evaluations.csv, e.g. a method's collisions per epoch) at --out.png")
    parser.add_argument("--claims", action="store_true",
                        help="instead: the claims scoreboard from the committed CSVs in reports/ (or the dirs given) to reports/claims.md (or --out.md)")
    args = parser.parse_args(argv)
    try:
        _main(args, parser)
    except (FileNotFoundError, KeyError, SelectionError) as e:  # a path or name the user typed: the message, not a traceback
        parser.error(str(e.args[0] if e.args else e))


def _main(args: argparse.Namespace, parser: argparse.ArgumentParser) -> None:
    """What :func:`main` does with its parsed ``args`` (``parser`` reports a bad one)."""
    if args.claims:
        from drapebench.claims import write_claims

        reports = args.dirs[0] if args.dirs else PROJECT_ROOT / "reports"
        if not reports.is_dir() or not any(reports.glob("*.csv")):
            parser.error(f"--claims reads the committed tables (*.csv) of a folder; {reports} "
                         f"{'holds none' if reports.is_dir() else 'is not a folder'} (default: {PROJECT_ROOT / 'reports'})")  # fmt: skip
        print(write_claims(reports, args.out.with_suffix(".md") if args.out else None))
        return
    if not args.dirs:
        parser.error("give the run or sweep directories to read (or --claims)")
    missing = [str(d) for d in args.dirs if not d.is_dir()]
    if missing:
        parser.error(f"not a folder: {', '.join(missing)} (give run or sweep directories)")
    if args.evaluations:
        print(evaluation_plot(args.dirs, (args.out or default_out("evaluations")).with_suffix(".png")))
        return
    if args.loss_curves:
        if args.out:
            parser.error("--out is not read with --loss-curves: each losses.png is written beside its losses.csv")
        csvs = sorted(c for d in args.dirs for c in Path(d).rglob("losses.csv"))
        if not csvs:
            parser.error(f"no losses.csv below {', '.join(map(str, args.dirs))} (only runs that train write one)")
        for csv in csvs:
            print(loss_curve_plot(csv))
        return
    experiments = set()  # the runs' recorded experiments, and their methods first: one outside the registry declares its tables in its package
    for d in args.dirs:
        for f in _run_files(d, "metrics.json"):
            join_registry(f.parent)
            experiments.add(json.loads(f.read_text()).get("experiment", "default"))
    if not experiments:
        raise FileNotFoundError(f"no metrics.json below {', '.join(map(str, args.dirs))}; did the runs finish?")
    tables = sorted(n for n, t in specs().items() if t.metrics)
    if args.table is not None and args.table not in tables:
        parser.error(f"argument --table: invalid choice: {args.table!r} (choose from {', '.join(tables)})")
    table = table_for_runs(experiments, args.table, tables)
    for p in write_table(args.dirs, table, args.out or default_out(table), methods=args.methods, garments=args.garments):
        print(p)


def _recorded_experiments(sweep) -> list:
    """The ``experiment`` names the runs of ``sweep`` (a :class:`drapebench.table_specs.Sweep`) record: its
    ``experiment_name=`` override's values, else its experiment's name (each experiment config sets it so)."""
    named = [o.partition("=")[2] for o in sweep.overrides if o.startswith("experiment_name=")]
    return [n for o in named for n in o.split(",")] or [sweep.experiment]


PLAIN_RUNS_TABLE = "baseline"  # the table of runs made without an experiment (``experiment: default``)


def table_for_runs(found: set, table: str | None, tables: list) -> str:
    """The table to write for runs that recorded the ``experiment`` names ``found``: ``table`` when given (with a
    warning on stderr when no table of that name is made by the runs' experiment: its columns may be empty), else the
    one table of ``tables`` whose sweeps run that experiment (the name or the experiment config;
    :data:`PLAIN_RUNS_TABLE` for plain runs and for an experiment no table reads, said on stderr);
    :class:`SelectionError` naming the tables to choose from when there are several."""
    from drapebench.table_specs import sweeps

    made = {n: {name for s in sweeps(specs()[n]) for name in (s.experiment, *_recorded_experiments(s))} for n in tables}
    experiments = found - {"default"}
    candidates = sorted(n for n in tables if made[n] & experiments) if experiments else [PLAIN_RUNS_TABLE]
    if table is not None:
        if experiments and table not in candidates:
            print(f"warning: table {table} is made by experiment {', '.join(sorted(made[table])) or '(a benchmark)'}; the runs are "
                  f"from {', '.join(sorted(experiments))}"
                  + (f" (tables made from them: {', '.join(candidates)})" if candidates else "") + ": its columns may be empty", file=sys.stderr)  # fmt: skip
        return table
    if len(candidates) > 1:
        raise SelectionError(f"the runs are from experiment {', '.join(sorted(experiments))}, which tables {', '.join(candidates)} "
                             f"read: pass --table (choose from {', '.join(candidates)})")  # fmt: skip
    chosen = candidates[0] if candidates else PLAIN_RUNS_TABLE
    print(f"table: {chosen} (the runs' experiment: {', '.join(sorted(found))}"
          + ("" if candidates else f", which no table reads: the plain runs' layout; --table chooses another") + ")", file=sys.stderr)  # fmt: skip
    return chosen


def default_out(table: str) -> Path:
    """A new folder (relative to the working directory) for a table the user did not place:
    ``outputs/reports/<date>_<time.microseconds>/<table>``
    (the committed ``reports/`` is only written when asked for with ``--out``)."""
    from datetime import datetime

    return Path("outputs") / "reports" / datetime.now().strftime("%Y-%m-%d_%H-%M-%S.%f") / table


if __name__ == "__main__":
    main()
