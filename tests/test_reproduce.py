"""One command regenerates every committed table: the table specs, the sweeps' expansion into runs, the quick
pipeline end to end, and resuming where a stopped command left off."""

import json
import os
import re
from fnmatch import fnmatch
from pathlib import Path

import pytest

from drapebench.claims_catalogue import claims
from drapebench import reproduce
from drapebench.reproduce import Job, expand, finished, main, plan, write_tables
from drapebench.reproduce_cost import summary, tally
from drapebench.table_file import read_csv, verified_text
from drapebench.table_specs import Sweep, specs, untrained

ROOT = Path(__file__).resolve().parent.parent
CLAIMS = claims()


def test_a_sweep_expands_as_hydra_sweeps_it_and_quick_keeps_every_row():
    jobs = expand(Sweep("gaps_table3", ("seed=0,1,2",)))  # the experiment's methods x shapes, crossed with the seeds
    assert len(jobs) == 2 * 3 * 3 and all(any(o.startswith("motion.betas=") for o in j) for j in jobs)
    assert {o for j in jobs for o in j if o.startswith("method=")} == {"method=gaps", "method=gaps_no_inext"}
    quick = expand(Sweep("gaps_table3", ("seed=0,1,2",)), quick=True)
    assert len(quick) == 2 and all("seed=0" in j and "train.epochs=0" in j for j in quick)
    assert len({o for j in quick for o in j if o.startswith("motion.betas=")}) == 1
    assert all("method.params.relax_iterations=20" in j for j in quick)  # GAPS's quick-only settings (methods/gaps/tables.py)
    assert not any(o.startswith("method.params.relax") for j in expand(Sweep("baseline", ()), quick=True) for o in j)  # lbs has none
    settles = {next(o for o in j if o.startswith("method=")): "method.params.settle_frames=2" in j for j in expand(Sweep("gaps_table1", ("method=lbs,pbs",)), quick=True)}
    assert settles == {"method=lbs": False, "method=pbs": True}  # the simulation's quick settle (methods/pbs/tables.py)
    one = expand(Sweep("gaps_table3", ("method=gaps", "seed=1")))  # an override replaces the experiment's list
    assert len(one) == 3 and all("method=gaps" in j and "seed=1" in j for j in one)


def test_a_glob_sweeps_every_method_config_but_the_ablations_it_excludes():
    methods = {o.split("=")[1] for j in expand(Sweep("runtime_vs_error", ("garment=tshirt",)), quick=True) for o in j if o.startswith("method=")}
    configs = {p.stem for p in (ROOT / "conf" / "method").glob("*.yaml")}
    ablations = {m for m in configs if any(fnmatch(m, p) for p in ("*_no_*", "gensim_v*", "gaps_kext1"))}
    assert ablations and methods == configs - ablations  # a newly registered method joins by itself


def test_a_method_trained_on_reference_drapes_runs_only_on_the_sweeps_reference_garments():
    jobs = expand(Sweep("runtime_vs_error", ("garment=tshirt,skirt", "method=vae,vae_mean_code,gaps", "motion.betas=[0.0]"),
                        reference_garments=("tshirt",)))  # fmt: skip
    assert sorted((j[0], j[2]) for j in jobs) == sorted([("garment=tshirt", "method=vae"), ("garment=tshirt", "method=vae_mean_code"),
                                                       ("garment=tshirt", "method=gaps"), ("garment=skirt", "method=gaps")])  # fmt: skip


def test_every_committed_table_has_one_spec_and_no_command_lives_elsewhere():
    for csv in (ROOT / "reports").glob("*.csv"):
        assert csv.stem.removesuffix("_gpu") in specs(), f"{csv.name} has no spec (drapebench/table_specs.py or methods/<name>/tables.py)"
    for c in CLAIMS:
        assert not c.table or c.table in specs(), c.id
    experiments = {p.stem for p in (ROOT / "conf" / "experiment").glob("*.yaml")}
    for s in specs().values():
        assert all(sw.experiment in experiments for sw in s.sweeps), s.name
        assert bool(s.metrics) != bool(s.bench or s.evaluations), s.name
    for y in (ROOT / "conf" / "experiment").glob("*.yaml"):  # the sweeps are the specs', not YAML comments'
        assert not re.search(r"^#.*python (run\.py|-m drapebench\.report)", y.read_text(), re.M), y.name


def test_quick_writes_a_table_and_claims_and_a_restart_reruns_nothing(tmp_path, capsys, monkeypatch):
    """The fast suite runs one table's whole pipeline (lbs, one run); the slow test below runs every table's."""
    monkeypatch.setattr(reproduce, "commit", lambda: "0" * 40)  # a committed tree, whatever this checkout's state
    args = ["--quick", "--tables", "baseline", "--runs", str(tmp_path / "runs"), "--out", str(tmp_path / "out")]
    assert main(args) == 0
    said = capsys.readouterr().out
    assert "1 runs, 0 already finished" in said and "[1/1] baseline: baseline method=lbs" in said
    table = read_csv(tmp_path / "out" / "baseline.csv")
    assert [r[1][0] for r in table.rows] == ["lbs"] and "drapebench.reproduce --tables baseline --quick" in table.comments[0]
    assert (tmp_path / "out" / "claims.md").read_text().startswith("**--quick**")
    with pytest.raises(SystemExit):  # quick tables never replace the committed ones
        main(["--quick", "--tables", "baseline", "--out", "reports"])
    (job,) = plan(["baseline"], tmp_path / "runs", quick=True)
    assert "logged to MLflow" not in job.dir.with_suffix(".log").read_text()  # not in the tables' MLflow experiments
    assert main(args) == 0 and "1 runs, 1 already finished" in capsys.readouterr().out  # resumed: nothing reruns
    (job.dir / "reproduce.json").write_text('{"overrides": [], "commit": "other"}')  # another config or commit
    assert not finished(job, "other") and main([*args, "--dry-run"]) == 0 and "todo  baseline" in capsys.readouterr().out


def test_an_archived_run_comes_back_on_a_new_machine_and_is_not_run_again(tmp_path, capsys, monkeypatch):
    """--archive records each finished run; with the runs folder gone (a new machine) the run is restored and counts
    as finished at the same commit; a dry run reports the archive without syncing it."""
    import shutil

    monkeypatch.setattr(reproduce, "commit", lambda: "0" * 40)
    archive = tmp_path / "archive"
    args = ["--quick", "--tables", "baseline", "--runs", str(tmp_path / "runs"), "--out", str(tmp_path / "out"), "--archive", str(archive)]
    assert main(args) == 0 and len(list(archive.rglob("reproduce.json"))) == 1
    capsys.readouterr()
    shutil.rmtree(tmp_path / "runs")
    assert main([*args, "--dry-run"]) == 0
    said = capsys.readouterr().out
    assert "not synced by a dry run" in said and "todo  baseline" in said and not (tmp_path / "runs").exists()
    assert main(args) == 0
    said = capsys.readouterr().out
    assert "1 runs restored from it" in said and "1 runs, 1 already finished" in said


def test_write_only_writes_another_commit_s_finished_runs_and_runs_nothing(tmp_path, capsys, monkeypatch):
    """A regeneration that ran in another checkout (at HEAD here) is written from its runs with --write-only --at; at
    this checkout's own label those runs have not finished, and nothing is run to finish them."""
    from drapebench.staleness import known

    head = known("HEAD")
    monkeypatch.setattr(reproduce, "commit", lambda: head)
    runs, out = tmp_path / "runs", tmp_path / "out"
    assert main(["--quick", "--tables", "baseline", "--runs", str(runs), "--out", str(tmp_path / "first")]) == 0
    monkeypatch.setattr(reproduce, "commit", lambda: "1" * 40)  # this checkout: another commit
    args = ["--quick", "--tables", "baseline", "--runs", str(runs), "--out", str(out), "--write-only"]
    capsys.readouterr()
    assert main(args) == 1  # a table asked for and not written is a failure, with what writes it
    said = capsys.readouterr().out
    assert "1 of its 1 runs have no result" in said and "[1/1]" not in said and not (out / "baseline.csv").exists()
    assert f"were made at {head[:12]} (1): write them with --at {head[:12]}" in said and "not written: baseline" in said
    assert main([*args, "--at", head[:10]]) == 0
    said = capsys.readouterr().out
    assert "[1/1]" not in said and "have no result" not in said
    assert read_csv(out / "baseline.csv").rows == read_csv(tmp_path / "first" / "baseline.csv").rows
    assert (out / "claims.md").exists()
    said = []  # a benchmark table is timed on its own scene: --write-only runs no script
    assert write_tables(["scaling"], runs, out, say=said.append, at=head, benches=False) == [] and "skipped by --write-only" in said[0]


@pytest.mark.parametrize("argv, said", [
    (["--tables", "", "--dry-run"], "--tables: no table named; leave --tables out"),  # would have rewritten claims.md alone
    (["--tables", ",", "--dry-run"], "--tables: no table named"),
    (["--tables", "baseline", "--dry-run", "--jobs", "0"], "--jobs: at least 1, got 0"),
    (["--tables", "baseline, nosuch", "--dry-run"], "--tables: no table nosuch;"),  # spaces after commas are not part of a name
    (["--tables", "baseline", "--at", "HEAD"], "--at HEAD: only with --write-only"),
    (["--tables", "baseline", "--write-only", "--at", "nosuchcommit"], "--at nosuchcommit: not a commit of this repository"),
    (["--tables", "baseline", "--write-only", "--dry-run"], "--write-only --dry-run: both run nothing"),
])
def test_bad_arguments_are_refused_before_anything_runs_or_is_written(argv, said, capsys):
    with pytest.raises(SystemExit):
        main(argv)
    assert said in capsys.readouterr().err


@pytest.mark.parametrize("flag", ["--out", "--runs", "--archive"])
def test_a_file_where_a_folder_is_needed_is_refused_before_any_run(tmp_path, flag, capsys):
    """--out a file failed only when the tables were written, after every run."""
    (tmp_path / "afile").write_text("mine\n")
    with pytest.raises(SystemExit):
        main(["--tables", "baseline", "--dry-run", "--runs", str(tmp_path / "runs"), flag, str(tmp_path / "afile")])
    assert f"{flag} {tmp_path / 'afile'}: a file, where a folder is needed" in capsys.readouterr().err
    assert (tmp_path / "afile").read_text() == "mine\n"


def test_a_table_with_runs_missing_is_not_written(tmp_path, monkeypatch):
    """A cell averaged over fewer scenes than planned would change silently: the committed table stays instead."""
    monkeypatch.setattr(reproduce, "commit", lambda: "0" * 40)
    jobs = plan(["gensim_fig10"], tmp_path / "runs", quick=True)
    assert len(jobs) > 1
    jobs[0].dir.mkdir(parents=True)
    (jobs[0].dir / "metrics.json").write_text("{}")
    (jobs[0].dir / "reproduce.json").write_text(json.dumps({"overrides": list(jobs[0].overrides), "commit": "0" * 40}))
    said = []
    assert write_tables(["gensim_fig10"], tmp_path / "runs", tmp_path / "out", quick=True, say=said.append) == []
    assert f"{len(jobs) - 1} of its {len(jobs)} runs have no result" in said[0] and not (tmp_path / "out").exists()


def test_runs_on_other_uncommitted_edits_or_unknown_code_never_count_as_finished(tmp_path, monkeypatch):
    """Two sittings on different uncommitted edits share git's ``<sha>-dirty`` label: the diff's hash tells them apart."""
    (job,) = plan(["baseline"], tmp_path / "runs", quick=True)
    job.dir.mkdir(parents=True)
    (job.dir / "metrics.json").write_text("{}")
    for at in ("a" * 40, "a" * 40 + "-dirty+0123456789ab", "unknown"):
        (job.dir / "reproduce.json").write_text(json.dumps({"overrides": list(job.overrides), "commit": at}))
        assert finished(job, at) == (at != "unknown")
    assert not finished(job, "a" * 40 + "-dirty+ba9876543210")  # another edit of the same commit
    import drapebench.results

    monkeypatch.setattr(drapebench.results, "_COMMIT_AT_IMPORT", "a" * 40 + "-dirty")
    assert re.fullmatch("a{40}-dirty\\+[0-9a-f]{12}", reproduce.commit())


def test_the_label_of_uncommitted_code_ignores_what_a_regeneration_writes(tmp_path, monkeypatch):
    """A table written into reports/ (or the archive synced there) midway must not change the label of the runs the
    next table reads; an edit of the code must."""
    import subprocess

    import drapebench.results

    git = lambda *a: subprocess.run(["git", "-C", str(tmp_path), *a], check=True, capture_output=True)  # noqa: E731
    git("init", "-q")
    (tmp_path / "reports").mkdir()
    for name in ("code.py", "reports/table.md", "README.md"):
        (tmp_path / name).write_text("0\n")
    git("add", ".")
    git("-c", "user.name=t", "-c", "user.email=t@t", "commit", "-qm", "c")
    monkeypatch.setattr(reproduce, "PROJECT_ROOT", tmp_path)
    monkeypatch.setattr(drapebench.results, "_COMMIT_AT_IMPORT", "a" * 40 + "-dirty")
    (tmp_path / "code.py").write_text("1\n")
    label = reproduce.commit()
    (tmp_path / "reports/table.md").write_text("a table\n")
    (tmp_path / "README.md").write_text("its status\n")
    assert reproduce.commit() == label
    (tmp_path / "code.py").write_text("2\n")
    assert reproduce.commit() != label


@pytest.mark.parametrize("where, said", [
    ("runs", "a folder apart from the runs folder"),  # recording a run into itself would strip it to its record
    ("runs/archive", "a folder apart from the runs folder"),  # each sync would record the archive into itself
    (".", "a folder apart from the runs folder"),
])
def test_an_archive_that_is_or_holds_or_sits_in_the_runs_folder_is_refused(tmp_path, where, said, capsys):
    with pytest.raises(SystemExit):
        main(["--tables", "baseline", "--runs", str(tmp_path / "runs"), "--archive", str(tmp_path / where)])
    assert said in capsys.readouterr().err


def test_quick_runs_never_enter_the_committed_archive(capsys):
    with pytest.raises(SystemExit):
        main(["--quick", "--tables", "baseline", "--archive", str(ROOT / "reports" / "runs")])
    assert "would enter the committed archive" in capsys.readouterr().err


@pytest.mark.pipeline
def test_quick_runs_every_table_s_pipeline(tmp_path):
    """Every table's sweeps on the tiny scene, its table and the claims, a run per core: a table whose pipeline breaks
    goes red in CI (about 13 min on 2 cores from the session's empty data folder)."""
    jobs = str(min(2, os.cpu_count() or 1))
    assert main(["--quick", "--jobs", jobs, "--runs", str(tmp_path / "runs"), "--out", str(tmp_path / "out")]) == 0
    for name, s in specs().items():
        if s.metrics:
            path = tmp_path / "out" / f"{name}.csv"
            assert read_csv(path).rows if s.group else verified_text(path), name


def test_every_sweep_of_every_table_composes():
    """A mistyped key in a spec's overrides fails here, not hours into `make reports` (each sweep's first run)."""
    from hydra import compose, initialize_config_dir
    from hydra.core.override_parser.overrides_parser import OverridesParser

    from drapebench.schema import register

    register()
    parser = OverridesParser.create()
    first = lambda o: f"{o.get_key_element()}={next(iter(o.sweep_string_iterator()))}" if o.is_sweep_override() else o.input_line  # noqa: E731
    runs = {(sw.experiment, *map(first, parser.parse_overrides([o for o in sw.overrides if "glob(" not in o])))
            for s in specs().values() for sw in s.sweeps}  # fmt: skip
    with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
        for experiment, *overrides in sorted(runs):
            compose("config", overrides=[f"experiment={experiment}", *overrides])


def _jobs(sweep: Sweep) -> list:
    return [Job("t", sweep, overrides, Path("unused")) for overrides in expand(sweep)]


def test_the_cost_tally_counts_a_training_per_model_not_per_run():
    """gaps_table3: 2 methods x 3 shapes x 3 seeds = 18 runs on one garment need 6 trainings (the shape is a test
    input); the untrained rows need none; GenSim, one model for every garment, one per seed over 3 garments."""
    counts = tally(_jobs(Sweep("gaps_table3", ("seed=0,1,2",))))[0]
    assert {m: (r["runs"], len(r["trainings"])) for m, r in counts.items()} == {"gaps": (9, 3), "gaps_no_inext": (9, 3)}
    (before,) = untrained("gaps_table3", ("gaps",))
    assert {m: len(r["trainings"]) for m, r in tally(_jobs(before))[0].items()} == {"gaps_untrained": 0}
    pen = tally(_jobs(Sweep("gensim_pen", ("seed=0,1",))))[0]
    assert (pen["gensim"]["runs"], len(pen["gensim"]["trainings"])) == (6, 2)
    assert (pen["gensim_arap"]["runs"], len(pen["gensim_arap"]["trainings"])) == (6, 0)  # the ARAP stage learns nothing
    lines = summary(_jobs(Sweep("gaps_table3", ("seed=0,1,2",))))
    assert lines[-1].split() == ["all", "18", "6", "0"]  # the test's empty cache holds none of them


def test_the_cost_counts_the_reference_sets_that_uncached_trainings_build_first(monkeypatch):
    """The VAE trains on the reference drapes of its data preset: a dry run on a machine without them said "2
    trainings" and left out the simulations before them (about 40 minutes a garment). Its runs on one garment share
    one set; a set whose trainings are all cached is not built."""
    from omegaconf import OmegaConf

    import drapebench.reproduce_cost as cost
    from drapebench.body.dataset import spec_sequences
    from drapebench.cache import PROJECT_ROOT
    from drapebench.data.reference_spec import ReferenceSetSpec
    from drapebench.reference.settings import SimSettings

    jobs = _jobs(Sweep("vae_table1", ("method=vae,vae_mean_code", "seed=0,1", "motion=kick", "motion.betas=[1.0,-1.0]", "garment=tshirt")))
    data = ReferenceSetSpec.from_config(OmegaConf.to_container(OmegaConf.load(PROJECT_ROOT / "conf" / "data" / "cpu.yaml")))
    planned = spec_sequences(data.dataset_spec())
    settle = SimSettings.for_solver(data.solver, **data.settings).settle_frames
    lines = summary(jobs)
    assert sum(x.startswith("reference set") for x in lines) == 1  # four trainings (two methods, two seeds), one set
    line = lines[-1]  # the test's empty reference cache
    assert line.startswith(f"reference set data=cpu on the tshirt: {len(planned)} of {len(planned)} sequences to simulate, "
                           f"{sum(s.n_frames + settle for s in planned):,} frames")  # fmt: skip
    monkeypatch.setattr(cost, "_sealed", lambda cfg, scenes: True)
    assert summary(jobs)[-1].split()[0] == "all"


def test_the_cost_counts_a_cached_checkpoint_where_the_run_would_load_it():
    """A checkpoint stored at the path the run computes (drapebench.experiment.checkpoint_path) is counted as cached for
    its training alone; one stored under another seed's key is not."""
    import torch
    from omegaconf import OmegaConf

    from drapebench.experiment import CHECKPOINTS, checkpoint_path, method_class
    from drapebench.reproduce_cost import cached
    from drapebench.scene import Scene

    counts = tally(_jobs(Sweep("gaps_table3", ("method=gaps", "seed=0,1"))))[0]
    configs = list(counts["gaps"]["trainings"].values())
    assert len(configs) == 2 and cached(configs) == [False, False]
    cfg = next(c for c in configs if c.seed == 1)
    scene = Scene.from_config(cfg, device="cpu")
    method = method_class(cfg)(OmegaConf.to_container(cfg.method.params, resolve=True))
    CHECKPOINTS.store(checkpoint_path(method, cfg, scene.garment, scene.body), lambda tmp: torch.save({"method": {}, "commit": "unrecorded"}, tmp))
    assert cached(configs) == [c.seed == 1 for c in configs]


def test_runs_that_share_a_model_or_a_reference_set_are_grouped_to_run_in_turn(monkeypatch):
    """gaps_table3 with 2 seeds: a group per (method, seed), its 3 test shapes in order; the untrained rows train nothing
    (a group each); the VAE's runs on one garment share its reference set: a group per seed over its methods (which
    share a VAE), the second seed's waiting for the first run of the first; runs whose training is in the checkpoint
    cache only load it: a group each, waiting for nothing."""
    import drapebench.reproduce_cost as cost
    from drapebench.reproduce_cost import groups

    monkeypatch.setattr(cost, "_sealed", lambda cfg, scenes: False)  # nothing trained yet, whatever this machine's cache holds
    jobs = _jobs(Sweep("gaps_table3", ("seed=0,1",)))
    found = groups(jobs)
    assert len(found) == 4 and all(len(g) == 3 for g in found) and sorted(j.overrides for g in found for j in g) == sorted(j.overrides for j in jobs)
    model = lambda j: tuple(o for o in j.overrides if o.startswith(("method=", "seed=")))  # noqa: E731
    assert all(len({model(j) for j in g}) == 1 for g in found) and len({model(g[0]) for g in found}) == 4
    assert all(g == [j for j in jobs if model(j) == model(g[0])] for g in found)  # in the sweep's order
    (before,) = untrained("gaps_table3", ("gaps",))
    assert [len(g) for g in groups(_jobs(before))] == [1, 1, 1]
    vae = _jobs(Sweep("vae_table1", ("method=vae,vae_mean_code", "seed=0,1", "motion=kick", "motion.betas=[1.0,-1.0]")))
    seed = lambda j: next(o for o in j.overrides if o.startswith("seed="))  # noqa: E731
    first, second = groups(vae)
    assert len(vae) == 4 and [{seed(j) for j in g} for g in (first, second)] == [{"seed=0"}, {"seed=1"}]
    assert first.after is None and second.after is first[0] and all(g.after is None for g in found)
    untrained_vae = _jobs(Sweep("vae_table1", ("method=vae,vae_mean_code", "seed=0", "motion=kick", "motion.betas=[1.0,-1.0]", "train.epochs=0")))
    assert [len(g) for g in groups(untrained_vae)] == [2]  # still reads its reference set (--quick): one worker, not two at once
    monkeypatch.setattr(cost, "_sealed", lambda cfg, scenes: True)  # every training cached (cached() tests the path)
    assert [len(g) for g in groups(vae)] == [1, 1, 1, 1] and [len(g) for g in groups(jobs)] == [1] * 12
    assert all(g.after is None for g in groups(vae))


def test_a_run_that_cannot_be_planned_is_its_own_group_and_the_rest_still_plan(monkeypatch):
    """One run whose overrides do not compose, and one whose method refuses its parameters: each is a group of its own,
    named with its error (the run then reports it), and neither stops the plan or the dry run of the others."""
    import dataclasses

    import drapebench.reproduce_cost as cost

    monkeypatch.setattr(cost, "_sealed", lambda cfg, scenes: False)
    jobs = _jobs(Sweep("gaps_table3", ("method=gaps", "seed=0")))
    bad_key = dataclasses.replace(jobs[0], overrides=(*jobs[0].overrides, "method.params.no_such_key=1"), dir=jobs[0].dir.with_name("bad_key"))
    bad_value = dataclasses.replace(jobs[0], overrides=(*jobs[0].overrides, "method.params.rbf_k=0"), dir=jobs[0].dir.with_name("bad_value"))
    found, trains, unplanned = cost.grouped([bad_key, *jobs, bad_value])
    assert [len(g) for g in found] == [1, len(jobs), 1] and set(unplanned) == {bad_key.dir, bad_value.dir}
    assert "no_such_key" in unplanned[bad_key.dir] and "rbf_k" in unplanned[bad_value.dir]
    assert trains == {jobs[0].dir}
    lines = summary([bad_key, *jobs, bad_value])
    assert sum(x.startswith("could not plan") for x in lines) == 2 and "all" in [x.split()[0] for x in lines]
    vae = _jobs(Sweep("vae_table1", ("method=vae", "seed=0", "motion=kick", "motion.betas=[1.0,-1.0]", "garment=tshirt")))

    def no_scene(cfg, scenes):
        raise ValueError("garment.resolution must be > 0")

    monkeypatch.undo()  # the real cache check, which builds the scene
    monkeypatch.setattr(cost, "_scene", no_scene)  # a scene that cannot be built: named, with its reference set
    lines = summary(vae)
    assert any(x.startswith("could not build the scene") for x in lines) and any("its scene cannot be built" in x for x in lines)


def _ends_with_a_result(job, commit="c"):
    """Leave ``job``'s folder as a finished run at ``commit`` leaves it: metrics and the reproduce stamp."""
    job.dir.mkdir(parents=True)
    (job.dir / "metrics.json").write_text("{}")
    (job.dir / "reproduce.json").write_text(json.dumps({"overrides": list(job.overrides), "commit": commit}))


def test_run_all_starts_a_group_only_after_the_run_it_waits_for(tmp_path, monkeypatch):
    """Two workers and three groups, the second waiting for the first group's first run (a reference set it
    builds): the third starts at once beside the first, the second only once that run has ended."""
    import threading

    import drapebench.reproduce_cost as cost
    from drapebench.reproduce import run_all
    from drapebench.reproduce_cost import Group

    jobs = [Job("t", Sweep("x"), (f"k={i}",), tmp_path / str(i)) for i in range(5)]
    first, second, third = Group(jobs[0:2]), Group(jobs[2:4]), Group(jobs[4:])
    second.after = jobs[0]
    monkeypatch.setattr(cost, "grouped", lambda todo: ([first, second, third], set(), {}))
    events, lock, free_worker_started = [], threading.Lock(), threading.Event()

    def runner(job, at, cpus):
        with lock:
            events.append(("start", job.dir.name))
        if job is jobs[4]:
            free_worker_started.set()
        if job is jobs[0]:  # the set's first run lasts until the other worker has taken a group (or 10 s)
            free_worker_started.wait(10)
        _ends_with_a_result(job)
        with lock:
            events.append(("end", job.dir.name))
        return 0

    assert run_all(jobs, "c", say=lambda s: None, workers=2, runner=runner) == []
    assert events.index(("start", "2")) > events.index(("end", "0"))  # waited for the set's first run
    assert events.index(("start", "4")) < events.index(("end", "0"))  # the free worker took the group that waits for nothing
    assert sorted(name for kind, name in events if kind == "end") == [str(i) for i in range(5)]


def test_run_all_with_two_workers_runs_each_group_in_turn_on_one_worker(tmp_path, monkeypatch):
    """Two workers, each pinned to its own cores: a group's runs go in order on one worker, the groups spread over
    both, a run that ends without a result is returned as failed."""
    import threading
    import time

    import drapebench.reproduce_cost as cost
    from drapebench.reproduce import run_all, worker_cpus

    jobs = [Job("t", Sweep("x"), (f"k={i}",), tmp_path / str(i)) for i in range(6)]
    monkeypatch.setattr(cost, "grouped", lambda todo: ([todo[0:3], todo[3:5], todo[5:]], {todo[0].dir}, {}))
    ran = []

    def runner(job, at, cpus):
        ran.append((threading.get_ident(), job, frozenset(cpus) if cpus else None))
        time.sleep(0.2)  # long enough for the other worker to take the next group
        if job is jobs[4]:
            return 1  # no result
        _ends_with_a_result(job)
        return 0

    failed = run_all(jobs, "c", say=lambda s: None, workers=2, runner=runner)
    assert failed == [jobs[4]] and sorted(j.dir.name for _, j, _ in ran) == [str(i) for i in range(6)]
    by_thread = {}
    for thread, job, _ in ran:
        by_thread.setdefault(thread, []).append(job)
    assert len(by_thread) == 2  # both workers
    assert all(len({c for t, _, c in ran if t == thread}) == 1 for thread in by_thread)  # each pinned to its cores
    for group in (jobs[0:3], jobs[3:5]):  # each group on one worker, in order
        (thread,) = {t for t, j, _ in ran if j in group}
        assert [j for j in by_thread[thread] if j in group] == group
    cpus = worker_cpus(2)
    assert len(cpus) == 2 and all(c is None or len(c) >= 1 for c in cpus)
    if cpus[0] is not None and len(os.sched_getaffinity(0)) >= 2:
        assert not cpus[0] & cpus[1]  # two cores or more: each worker its own


def test_the_time_left_counts_the_trainings_left_at_a_trainings_time_and_the_other_runs_at_theirs(tmp_path):
    """A regeneration starts with trainings (minutes each) and goes on with runs that load them (seconds): the
    estimate weighs each kind by its own mean, not every run by the first trainings'."""
    from drapebench.reproduce import time_left

    jobs = [Job("t", Sweep("x"), (f"k={i}",), tmp_path / str(i)) for i in range(10)]
    trains = {jobs[0].dir, jobs[1].dir, jobs[5].dir}
    assert time_left({}, jobs, trains, 1) == ""  # nothing finished: no estimate
    took = {jobs[0].dir: (600.0, True, "t")}  # one training of 10 minutes so far: the other runs are not priced as trainings
    assert time_left(took, jobs[2:], trains, 2) == ", about 0:05:00 left (1 trainings; 7 other runs not timed yet)"
    took[jobs[2].dir] = (6.0, False, "t")
    assert time_left(took, jobs[3:], trains, 1) == ", about 0:10:36 left (1 trainings, 6 other runs)"


def test_the_time_left_prices_each_run_at_its_own_methods_mean(tmp_path):
    """Optimisations to a loss's optimum (minutes) are not priced as a trained model's evaluations (seconds): a run
    whose method has finished runs takes their mean; one whose method has none takes its class's."""
    from drapebench.reproduce import run_kind, time_left

    def job(i, *overrides):
        return Job("t", Sweep("x"), overrides, tmp_path / str(i))

    optimum = [job(i, "garment=dress", "method=gaps_optimum") for i in range(4)]
    variant = job(4, "method=gaps_optimum", "method.name=gaps_kext1_optimum")
    evals = [job(5 + i, "method=gaps") for i in range(3)]
    assert run_kind(optimum[0]) == "gaps_optimum" and run_kind(variant) == "gaps_kext1_optimum"
    assert run_kind(job(9, "garment=dress")) == "t"  # no method override: its table
    took = {optimum[0].dir: (300.0, False, "gaps_optimum"), evals[0].dir: (10.0, False, "gaps")}
    # 3 optimum runs at 300 s, 2 evaluations at 10 s, the variant (none finished) at the other runs' mean 155 s
    assert time_left(took, optimum[1:] + evals[1:] + [variant], set(), 1) == ", about 0:17:55 left (6 other runs)"


def test_the_time_left_does_not_price_a_long_run_at_the_short_runs_mean(tmp_path):
    """Stability's 10,000-frame runs take minutes where its 300-frame ones take seconds: a run that sets its own
    length is priced only at the mean of finished runs of its method and length, else named as not timed yet."""
    from drapebench.reproduce import run_kind, time_left

    short = Job("t", Sweep("x"), ("method=lbs",), tmp_path / "0")
    long_runs = [Job("t", Sweep("x"), ("method=lbs", "motion.n_frames=10000"), tmp_path / str(i)) for i in (1, 2)]
    assert run_kind(long_runs[0]) == "lbs, 10000 frames" and run_kind(short) == "lbs"
    took = {tmp_path / "9": (10.0, False, "lbs")}
    assert time_left(took, [short] + long_runs, set(), 1) == ", about 0:00:10 left (1 other runs; 2 other runs not timed yet)"
    took[long_runs[0].dir] = (600.0, False, "lbs, 10000 frames")
    assert time_left(took, [short, long_runs[1]], set(), 1) == ", about 0:10:10 left (2 other runs)"


def test_a_benchmark_table_names_an_output_path_anyone_can_rerun(monkeypatch):
    """A benchmark's table (its script writes it) is made with --out relative to the project, so that the command
    its footer names runs in any checkout, not only in the one (or worktree) that made it."""
    import subprocess

    import drapebench.reproduce as reproduce

    calls = []
    monkeypatch.setattr(subprocess, "run", lambda argv, **kw: calls.append(argv))
    reproduce.write_tables(["vae_table2"], Path("unused"), ROOT / "reports", say=lambda s: None)
    assert len(calls) == 1 and "reports/vae_table2" in calls[0] and not any(str(ROOT) in a for a in calls[0][1:])


def test_a_benchmark_script_imports_this_checkouts_code(monkeypatch):
    """A script under benchmarks/ has its own folder first on sys.path: the benchmark runs with this checkout first on
    PYTHONPATH, so that in a worktree it times (and its footer names) the worktree's code, not the installed one's."""
    import os
    import subprocess

    import drapebench.reproduce as reproduce

    envs = []
    monkeypatch.setenv("PYTHONPATH", "/elsewhere")
    monkeypatch.setattr(subprocess, "run", lambda argv, **kw: envs.append(kw.get("env")))
    reproduce.write_tables(["vae_table2"], Path("unused"), ROOT / "reports", say=lambda s: None)
    assert envs[0] is not None and envs[0]["PYTHONPATH"].split(os.pathsep) == [str(reproduce.PROJECT_ROOT), "/elsewhere"]


def test_a_run_that_recorded_its_failure_has_finished(tmp_path):
    """on_failure=record: the failure is the run's result (a "failed" cell); a restart must not run it again."""
    (job,) = plan(["baseline"], tmp_path / "runs", quick=True)
    job.dir.mkdir(parents=True)
    (job.dir / "failed.json").write_text(json.dumps({"message": "diverged"}))
    (job.dir / "reproduce.json").write_text(json.dumps({"overrides": list(job.overrides), "commit": "a" * 40}))
    assert finished(job, "a" * 40)
    (job.dir / "failed.json").unlink()
    assert not finished(job, "a" * 40)  # a stamp alone is no result


def test_a_per_garment_method_needs_a_training_per_garment():
    counts = tally(_jobs(Sweep("gaps_table3", ("method=gaps", "motion.betas=[0.0]", "seed=0", "garment=tshirt,skirt"))))[0]
    assert {m: (r["runs"], len(r["trainings"])) for m, r in counts.items()} == {"gaps": (2, 2)}


def test_a_run_another_process_holds_is_not_started_again_and_its_folder_is_kept(tmp_path):
    """A run whose lock another process holds (an orphan of a stopped command, or a second command over the same
    runs folder) is not started a second time, and the folder it writes into is not removed under it; nor is a run
    that another command finished after this one listed it."""
    import fcntl

    from drapebench.reproduce import BUSY, run_job

    job = Job("t", Sweep("x"), ("k=1",), tmp_path / "runs" / "0")
    job.dir.mkdir(parents=True)
    (job.dir / "losses.csv").write_text("step\n1\n")
    with open(tmp_path / "runs" / "0.lock", "a") as held:
        fcntl.flock(held, fcntl.LOCK_EX | fcntl.LOCK_NB)
        assert run_job(job, "c") == BUSY
    assert (job.dir / "losses.csv").read_text() == "step\n1\n" and not (tmp_path / "runs" / "0.log").exists()
    (job.dir / "metrics.json").write_text("{}")  # finished by the other command, lock released
    (job.dir / "reproduce.json").write_text(json.dumps({"overrides": ["k=1"], "commit": "c"}))
    assert run_job(job, "c") == 0 and (job.dir / "losses.csv").exists() and not (tmp_path / "runs" / "0.log").exists()


STOPPED_COMMAND = """
import sys, time
from pathlib import Path
import drapebench.reproduce as reproduce
import drapebench.reproduce_cost as cost
from drapebench.table_specs import Sweep

root = Path(sys.argv[1])
reproduce.PROJECT_ROOT = root  # run.py here is a stand-in that notes its pid and sleeps
cost.grouped = lambda todo: ([[j] for j in todo], set(), {})
jobs = [reproduce.Job("t", Sweep("x"), (f"k={i}",), root / "runs" / str(i)) for i in range(3)]
reproduce.stop_runs_on_signals()
reproduce.run_all(jobs, "c", say=lambda s: None, workers=int(sys.argv[2]))
"""


@pytest.mark.parametrize("workers", [1, 2])
def test_a_stopped_command_stops_its_runs_and_starts_no_other(tmp_path, workers):
    """SIGTERM to the command terminates the runs it started (left running, they would write beside a restarted
    command's copies of them, in the same folders) and starts none of the runs left; it exits 128 + 15. One worker
    or two: the runs start in worker threads, so the handler never runs between a run's start and its listing."""
    import signal
    import subprocess
    import sys
    import time

    (tmp_path / "run.py").write_text("import os, pathlib, sys, time\n"
                                     "pathlib.Path(sys.argv[0]).parent.joinpath('pids').open('a').write(f'{os.getpid()}\\n')\n"
                                     "time.sleep(120)\n")  # fmt: skip
    command = subprocess.Popen([sys.executable, "-c", STOPPED_COMMAND, str(tmp_path), str(workers)], cwd=ROOT)
    pids_file, deadline = tmp_path / "pids", time.monotonic() + 60
    while (not pids_file.exists() or len(pids_file.read_text().split()) < workers) and time.monotonic() < deadline:
        time.sleep(0.1)
    time.sleep(0.3)  # a second run would have started by now
    pids = [int(p) for p in pids_file.read_text().split()]
    assert len(pids) == workers  # one run per worker
    command.send_signal(signal.SIGTERM)
    assert command.wait(timeout=30) == 128 + signal.SIGTERM

    def alive(pid: int) -> bool:
        try:
            state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
        except (FileNotFoundError, ProcessLookupError):
            return False
        return state != "Z"  # a zombie has ended

    time.sleep(0.5)
    assert not [p for p in pids if alive(p)], "the command's runs outlived it"
    assert len(pids_file.read_text().split()) == workers  # the runs left never started


def test_run_all_stops_when_the_code_changes_under_it(tmp_path, monkeypatch):
    """An edit of the code while a regeneration runs: the runs left are not started (they would carry the first
    commit's stamp with other code), and the command says why."""
    import drapebench.reproduce_cost as cost
    from drapebench.reproduce import run_all

    jobs = [Job("t", Sweep("x"), (f"k={i}",), tmp_path / str(i)) for i in range(3)]
    monkeypatch.setattr(cost, "grouped", lambda todo: ([todo], set(), {}))
    ran, said = [], []

    def runner(job, at, cpus):
        ran.append(job)
        _ends_with_a_result(job)
        return 0

    labels = iter(["c", "c", "c-dirty+0123456789ab", "c-dirty+0123456789ab"])  # at the start, then before each run
    failed = run_all(jobs, "c", say=said.append, runner=runner, code_now=lambda: next(labels))
    assert ran == jobs[:1] and failed == jobs[1:]
    assert any("the code changed since the regeneration started (it was c, it is c-dirty+0123456789ab)" in s for s in said)
    assert not any("another process is running it" in s for s in said)


def test_code_against_names_an_edit_of_the_tracked_code_only(monkeypatch):
    """The label of the tree measured from the regeneration's commit: the commit itself while only what a
    regeneration writes differs, an edit label otherwise; a commit git cannot compare with leaves the label as given."""
    from drapebench.reproduce import code_against

    diffs = {"a" * 40: b"", "b" * 40: b"diff --git a/methods/x.py", "c" * 40: None}
    monkeypatch.setattr(reproduce, "_diff_from", lambda base: diffs[base])
    assert code_against("a" * 40) == "a" * 40 and code_against("a" * 40 + "-dirty+0123456789ab") == "a" * 40
    assert code_against("b" * 40).startswith("b" * 40 + "-dirty+") and code_against("c" * 40) == "c" * 40


def _project_of_one_commit(root: Path, monkeypatch) -> str:
    """A git repository at ``root`` with one commit of a ``run.py``, made the project that labels are read from;
    returns its commit."""
    import subprocess

    from drapebench import results

    git = lambda *a: subprocess.run(["git", "-C", str(root), *a], check=True, capture_output=True, text=True)  # noqa: E731
    root.mkdir(exist_ok=True)
    git("init", "-q")
    (root / "run.py").write_text("x = 1\n")
    git("add", "-A")
    git("-c", "user.name=t", "-c", "user.email=t@t", "commit", "-qm", "c")
    monkeypatch.setattr(reproduce, "PROJECT_ROOT", root)
    monkeypatch.setattr(results, "PROJECT_ROOT", root)
    return git("rev-parse", "HEAD").stdout.strip()


def test_an_untracked_config_where_runs_read_code_changes_the_label(tmp_path, monkeypatch):
    """A new, uncommitted ``conf/method/x.yaml`` (which a sweep's ``glob(*)`` would run) is code: the label moves off
    the commit, and changes with the file's content; an untracked file outside the code does not count."""
    from drapebench.reproduce import code_against

    head = _project_of_one_commit(tmp_path, monkeypatch)
    (tmp_path / "scratch.txt").write_text("notes\n")
    assert code_against(head) == head
    (tmp_path / "conf" / "method").mkdir(parents=True)
    (tmp_path / "conf" / "method" / "x.yaml").write_text("name: x\n")
    first = code_against(head)
    assert first.startswith(head + "-dirty+")
    (tmp_path / "conf" / "method" / "x.yaml").write_text("name: y\n")
    assert code_against(head) not in (first, head)



def test_an_edit_behind_an_untracked_symlink_changes_the_label(tmp_path, monkeypatch):
    """git lists a symlink to a folder as one file: the files behind it are what the label hashes."""
    from drapebench.reproduce import code_against

    repo, outside = tmp_path / "repo", tmp_path / "ext_method"
    head = _project_of_one_commit(repo, monkeypatch)
    outside.mkdir()
    (outside / "method.py").write_text("SCALE = 1.0\n")
    (repo / "methods").mkdir()
    (repo / "methods" / "ext").symlink_to(outside, target_is_directory=True)
    first = code_against(head)
    (outside / "method.py").write_text("SCALE = 2.0\n")
    assert first.startswith(head + "-dirty+") and code_against(head) not in (first, head)

def test_a_run_that_raises_ends_and_does_not_hold_up_the_runs_waiting_for_it(tmp_path, monkeypatch):
    """Two workers; the second group waits for the first group's run, whose runner raises (a full disk, a failed
    start): the error is said, the run counts as failed, and the waiting group still runs (no hang)."""
    import drapebench.reproduce_cost as cost
    from drapebench.reproduce import run_all
    from drapebench.reproduce_cost import Group

    jobs = [Job("t", Sweep("x"), (f"k={i}",), tmp_path / str(i)) for i in range(2)]
    first, second = Group(jobs[:1]), Group(jobs[1:])
    second.after = jobs[0]
    monkeypatch.setattr(cost, "grouped", lambda todo: ([first, second], set(), {}))
    said = []

    def runner(job, at, cpus):
        if job is jobs[0]:
            raise OSError(28, "No space left on device")
        _ends_with_a_result(job)
        return 0

    import threading

    result = []
    thread = threading.Thread(target=lambda: result.append(run_all(jobs, "c", say=said.append, workers=2, runner=runner,
                                                                   code_now=lambda: "c")), daemon=True)  # fmt: skip
    thread.start()
    thread.join(30)
    assert not thread.is_alive(), "run_all hangs after a run raised: the runs waiting for it never start"
    assert result == [jobs[:1]]
    assert any("raised OSError" in s and "No space left on device" in s for s in said) and finished(jobs[1], "c")


def test_a_stamp_that_is_not_json_names_its_file_and_the_fix(tmp_path):
    job = Job("t", Sweep("x"), ("k=0",), tmp_path / "0")
    _ends_with_a_result(job)
    (job.dir / "reproduce.json").write_text('<<<<<<< HEAD\n{"commit": "c"}\n=======\n')
    with pytest.raises(ValueError, match=r"reproduce.json is not valid JSON .*a merge conflict.*delete"):
        finished(job, "c")


def test_at_expands_an_edit_label_and_refuses_a_malformed_one():
    from drapebench.staleness import known, run_label

    head = known("HEAD")
    assert run_label(head[:10]) == head
    assert run_label(f"{head[:10]}-dirty+0123456789ab") == f"{head}-dirty+0123456789ab"  # as the runs' stamps hold it
    assert run_label(f"{head[:10]}-dirty+xyz") is None and run_label("nosuchcommit-dirty+0123456789ab") is None


def test_a_checkout_git_cannot_name_is_refused_up_front(monkeypatch, capsys):
    """Without a commit no run would ever count as finished and no table would be written: say so before running."""
    monkeypatch.setattr(reproduce, "commit", lambda: "unknown")
    with pytest.raises(SystemExit):
        main(["--tables", "baseline", "--quick"])
    assert "git cannot name this checkout's commit" in capsys.readouterr().err
