"""End-to-end runs of run.py through Hydra (low-resolution body, short sequences)."""

import json
import logging
import math
import os
import shlex
import subprocess
import sys
from pathlib import Path

import pytest
import torch
import yaml
from hydra import compose, initialize_config_dir
from hydra.errors import ConfigCompositionException
from omegaconf import OmegaConf

from methods.base import DrapingMethod

ROOT = Path(__file__).resolve().parents[1]
FAST = ["body=anny_lowres", "motion.n_frames=10", "motion.transition=3"]


def run_py(args, tmp_path, timeout=240):
    env = dict(os.environ, DRAPEBENCH_PROGRESS="0", HYDRA_FULL_ERROR="1", CI="1")
    return subprocess.run([sys.executable, str(ROOT / "run.py"), *args], cwd=tmp_path, env=env, capture_output=True,
                          text=True, timeout=timeout)  # fmt: skip


def test_single_run_writes_every_output(tmp_path):
    out = tmp_path / "run"
    p = run_py([*FAST, f"hydra.run.dir={out}"], tmp_path)
    assert p.returncode == 0, p.stderr[-3000:]
    for name in ("metrics.json", "frames.csv", "prediction.h5", "drape.rrd", "config.yaml", "env.json"):
        assert (out / name).exists(), name
    rec = json.loads((out / "metrics.json").read_text())
    for key in ("method", "garment", "motion", "body", "n_vertices", "n_frames", "eps_e", "eps_a", "eps_c", "eps_c_std",
                "edge_mm", "smoothness", "penetration_mm", "jitter", "ms_per_frame", "train_s"):  # fmt: skip
        assert key in rec, key
    assert rec["method"] == "lbs" and rec["body"] == "anny_lowres" and rec["n_frames"] == 13
    assert rec["total_s"] >= rec["eval_s"] > 0 and rec["ms_per_frame"] > 0
    env = json.loads((out / "env.json").read_text())
    assert env["versions"]["torch"] and env["torch_threads"] == len(os.sched_getaffinity(0))  # threads=null: all cores
    rerun = Path(sys.executable).parent / "rerun"
    # CI=1 keeps the rerun CLI from writing its analytics settings into ~/.config
    v = subprocess.run([str(rerun), "rrd", "verify", str(out / "drape.rrd")], capture_output=True, text=True, timeout=60,
                       env=dict(os.environ, CI="1"))  # fmt: skip
    assert v.returncode == 0, v.stderr


def test_multirun_writes_a_summary_row_per_job(tmp_path):
    sweep = tmp_path / "sweep"
    p = run_py(["-m", *FAST, "garment=tshirt,skirt_flared", "viz=none", f"hydra.sweep.dir={sweep}"], tmp_path)
    assert p.returncode == 0, p.stderr[-3000:]
    lines = (sweep / "summary.csv").read_text().strip().splitlines()
    assert len(lines) == 3 and lines[0].startswith("method,garment")
    assert {ln.split(",")[1] for ln in lines[1:]} == {"tshirt", "skirt_flared"}  # a skirt config is not "skirt"
    assert (sweep / "summary.md").exists()


def test_every_garment_config_has_a_name_of_its_own():
    """Two garment configs of one kind (skirt, skirt_flared) would share a table row under the kind's name."""
    from drapebench.garments import garment_label

    labels = {p.stem: garment_label(yaml.safe_load(p.read_text())) for p in (ROOT / "conf" / "garment").glob("*.yaml")}
    assert all(label == stem for stem, label in labels.items()), labels


def _compose(overrides):
    from drapebench.schema import register

    register()
    with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
        return compose("config", overrides=overrides)


def test_unknown_names_list_the_valid_choices():
    with pytest.raises(ConfigCompositionException, match=r"Available options in 'method':") as err:
        _compose(["method=nope"])
    listed = str(err.value).split("Available options in 'method':")[1].split("Config search path")[0].split()
    assert {"lbs", "gaps", "snug_like", "ncs_like"} <= set(listed)
    with pytest.raises(ConfigCompositionException, match="skirt"):
        _compose(["garment=poncho"])
    with pytest.raises(ConfigCompositionException, match="viz_mode"):
        _compose(["viz_mode=1"])
    with pytest.raises(ConfigCompositionException) as err:
        _compose(["viz=rr"])
    assert "expected one of [rerun, none]" in str(err.value.__cause__)
    with pytest.raises(ConfigCompositionException) as err:
        _compose(["reference.substep=3"])
    assert "Key 'substep' not in 'ReferenceConf'" in str(err.value.__cause__)
    with pytest.raises(ConfigCompositionException, match="Error merging override motion.n_frames=abc"):
        _compose(["motion.n_frames=abc"])


def test_every_experiment_config_composes():
    for exp in sorted((ROOT / "conf" / "experiment").glob("*.yaml")):
        cfg = _compose([f"experiment={exp.stem}"])
        assert cfg.experiment_name == exp.stem
        assert cfg.on_failure.name == ("stop" if exp.stem == "smoke" else "record")  # a table sweep records failures
    assert _compose([]).on_failure.name == "stop"


def test_default_training_is_the_cpu_budget_and_paper_is_opt_in():
    default = _compose(["method=gaps"]).train
    assert default.name == "cpu" and default.max_minutes <= 10  # `python run.py method=gaps` ends on a CPU
    paper = _compose(["method=gaps", "train=paper"]).train
    assert paper.epochs == 1000 and paper.max_minutes is None


def test_the_run_seed_is_the_training_seed_and_a_new_seed_trains_a_new_checkpoint():
    from drapebench.experiment import CHECKPOINTS

    for preset in ("cpu", "paper"):
        assert _compose([f"train={preset}"]).train.seed == 0
        assert _compose([f"train={preset}", "seed=2"]).train.seed == 2  # `-m seed=0,1,2`: one model per seed

    def key(overrides):
        cfg = _compose(["method=gaps", *overrides])
        return CHECKPOINTS.path(OmegaConf.to_container(cfg.method, resolve=True), OmegaConf.to_container(cfg.train, resolve=True))

    assert key(["seed=0"]) == key([]) != key(["seed=1"])


def test_gaps_reads_its_own_training_keys_per_budget_and_a_wrong_train_key_fails():
    import methods
    from drapebench.experiment import method_params

    def gaps_train(overrides):  # the training keys the GAPS built from a composed config reads
        cfg = _compose(overrides)
        return methods.get(cfg.method.impl)(method_params(cfg, set())).p["train"]

    cpu = gaps_train(["method=gaps"])
    assert cpu["lr_output_factor"] == 0.1 and cpu["output_adam_eps"] == 1.0 and cpu["kext_ramp_epochs"] == 2 and cpu["window"] == 3  # gaps_budget/cpu.yaml
    assert cpu["redraw_motions"] and cpu["schedule"]["lr"] == 1e-3 and cpu["schedule"]["lr_after"] == 1e-4 and cpu["schedule"]["grad_clip"] == 90.0  # the paper's rates
    assert _compose(["method=gaps"]).train.dataset == "train_gaps"
    for ablation in ("gaps_kext1", "gaps_no_inext", "snug_like", "ncs_like"):
        paper = gaps_train([f"method={ablation}", "train=paper"])  # no gaps_budget/paper.yaml: GapsTrain's defaults
        assert paper["lr_output_factor"] == 1.0 and paper["kext_ramp_epochs"] == 100 and paper["window"] == 3, ablation
    with pytest.raises(ConfigCompositionException) as err:
        _compose(["train.kext_ramp_epochs=3"])  # a GAPS key is not a budget key
    assert "Key 'kext_ramp_epochs' not in 'TrainConf'" in str(err.value.__cause__)
    with pytest.raises(ConfigCompositionException, match="Error merging override train.steps=many"):
        _compose(["train.steps=many"])


def test_gaps_optimum_composes_with_gaps_loss_and_its_solver_settings():
    import methods

    cfg = _compose(["method=gaps_optimum"]).method
    assert cfg.impl == "gaps_optimum" and cfg.params.optimum.solver == "lbfgs" and cfg.params.train.kext_ramp_epochs == 2
    m = methods.get(cfg.impl)(OmegaConf.to_container(cfg.params, resolve=True))
    assert m.kext_epoch() == 2 and m.p["inextensibility_weight"] == 2e8  # k_ext at the end of the budget's ramp


def test_training_writes_losses_and_evaluations_csv_into_the_run_directory_and_a_loaded_checkpoint_too(tmp_path, monkeypatch, body_lowres):
    from drapebench.experiment import _checkpoint
    from drapebench.results import git_commit
    from methods.base import FitReport

    monkeypatch.setenv("DRAPEBENCH_DATA", str(tmp_path / "data"))

    class Learned(DrapingMethod):
        fits, settings = [], None

        def settings_key(self):
            return self.settings

        def fit(self, data, train_cfg=None):
            self.fits.append(dict(train_cfg))
            return FitReport(train_s=1.0, n_steps=1, history=[{"step": 1, "loss": 0.5}], evaluations=[{"epoch": 0, "step": 1, "colliding": 2.0}])

        def drape(self, garment, seq):
            raise NotImplementedError

        def state_dict(self):
            return {"w": torch.ones(2)}

        def load_state_dict(self, state):
            assert torch.equal(state["w"], torch.ones(2))

    cfg = _compose(["method=lbs", "body=anny_lowres"])
    garment = type("G", (), {"vertices": torch.zeros(3, 3), "faces": torch.zeros(1, 3, dtype=torch.long)})()
    data = type("D", (), {"body": body_lowres, "material": None})()
    train_cfg = {**OmegaConf.to_container(cfg.train, resolve=True), "dataset": None}
    models = set()
    for run_dir in (tmp_path / "a", tmp_path / "b"):  # a rerun in a new run directory loads the checkpoint
        run_dir.mkdir()
        trained = _checkpoint(Learned(), cfg, garment, data, train_cfg, log_dir=run_dir)
        assert trained.trained_at == git_commit() and trained.steps == 1 and trained.body == "anny_lowres"  # the code, steps and body that trained it
        models.add(trained.model)
        assert (run_dir / "losses.csv").read_text().splitlines() == ["step,loss", "1,0.5"]
        assert (run_dir / "evaluations.csv").read_text().splitlines() == ["epoch,step,colliding", "0,1,2.0"]
    assert len(Learned.fits) == 1 and Learned.fits[0]["log_dir"] == str(tmp_path / "a")
    assert len(models) == 1 and len(models.pop()) == 12  # the trained state's hash, the same when the checkpoint is loaded
    Learned.settings = {"width": 64}  # a changed code default of the method retrains
    (tmp_path / "c").mkdir()
    _checkpoint(Learned(), cfg, garment, data, train_cfg, log_dir=tmp_path / "c")
    assert len(Learned.fits) == 2


def test_a_checkpoint_trained_by_since_changed_method_code_is_trained_again(tmp_path, monkeypatch, body_lowres, caplog):
    """A checkpoint is keyed by configuration; it stores the fingerprint of the ``methods/<impl>`` code that trained it
    (uncommitted edits included), and one trained by other code than today's would give a stale row, so the run
    trains it again and the dry run counts it as not cached."""
    import drapebench.experiment as experiment
    import drapebench.staleness as staleness
    from methods.base import FitReport

    monkeypatch.setenv("DRAPEBENCH_DATA", str(tmp_path / "data"))

    class Learned(_ConstantState):
        fits = []

        def fit(self, data, train_cfg=None):
            self.fits.append(1)
            return FitReport(train_s=1.0, n_steps=1)

    cfg = _compose(["method=lbs", "body=anny_lowres"])
    garment = type("G", (), {"vertices": torch.zeros(3, 3), "faces": torch.zeros(1, 3, dtype=torch.long)})()
    data = type("D", (), {"body": body_lowres, "material": None})()
    train_cfg = {**OmegaConf.to_container(cfg.train, resolve=True), "dataset": None}
    path = experiment._checkpoint(Learned(), cfg, garment, data, train_cfg).checkpoint
    assert torch.load(path, weights_only=False)["code"] == staleness.fingerprint("lbs")
    experiment._checkpoint(Learned(), cfg, garment, data, train_cfg)
    assert len(Learned.fits) == 1 and experiment.loadable_checkpoint(Path(path), "lbs")  # the same code: loaded
    # the code changed since (edited on disk: the training commit's code, fingerprinted again, differs from it too)
    monkeypatch.setattr(staleness, "fingerprint", lambda impl, commit=None, track=None: "edited" if commit is None else "committed")
    assert not experiment.loadable_checkpoint(Path(path), "lbs")
    with caplog.at_level(logging.WARNING, logger="drapebench"):
        experiment._checkpoint(Learned(), cfg, garment, data, train_cfg)
    assert len(Learned.fits) == 2 and "which is edited now" in caplog.text


def test_a_checkpoint_without_its_code_is_judged_by_its_commit(monkeypatch):
    """A checkpoint stored before its code's fingerprint was recorded is judged by its training commit; one that cannot be
    checked (unrecorded, a commit git does not know, an implementation that is no folder) is loaded."""
    import drapebench.staleness as staleness

    head, old = staleness.known("HEAD"), "a" * 40
    monkeypatch.setattr(staleness, "known", lambda c: {"HEAD": head, old: old}.get(c))
    monkeypatch.setattr(staleness, "fingerprint", lambda impl, commit=None, track=None: "old" if commit == old else "disk" if commit is None else "head")
    assert "as of aaaaaaa" in staleness.trained_by_changed_code("gaps", {"commit": old})
    assert staleness.trained_by_changed_code("gaps_optimum", {"commit": old}) is not None  # methods/gaps
    assert staleness.trained_by_changed_code("gaps", {"commit": "unrecorded"}) is None
    assert staleness.trained_by_changed_code("gaps", {"commit": "b" * 40}) is None
    assert staleness.trained_by_changed_code("nowhere", {"commit": old}) is None and staleness.code_of(None) is None
    assert staleness.trained_by_changed_code("gaps", {"commit": old, "code": "disk"}) is None  # its own code: loaded
    # a code stored under an older definition of the fingerprint: its clean commit's code, fingerprinted today's way
    monkeypatch.setattr(staleness, "known", lambda c: {"HEAD": head, head: head, old: old}.get(c))
    monkeypatch.setattr(staleness, "fingerprint", lambda impl, commit=None, track=None: "today" if commit in (None, head) else "other")
    assert staleness.trained_by_changed_code("gaps", {"commit": head, "code": "olddef"}) is None  # the same code: loaded
    assert "code olddef" in staleness.trained_by_changed_code("gaps", {"commit": old, "code": "olddef"})  # other code: retrained
    assert staleness.trained_by_changed_code("gaps", {"commit": head + "-dirty", "code": "olddef"}) is not None  # unchecked edits


def test_changed_since_compares_the_fingerprints_at_a_known_commit(monkeypatch):
    import drapebench.staleness as staleness

    head, old = staleness.known("HEAD"), "a" * 40
    monkeypatch.setattr(staleness, "known", lambda c: {"HEAD": head, old: old}.get(c))
    monkeypatch.setattr(staleness, "fingerprint", lambda impl, commit=None, track=None: "old" if commit == old else "disk" if commit is None else "head")
    assert staleness.changed_since("gaps", old) == old  # trained by other code than the checked-out commit's
    assert staleness.changed_since("gaps", head) is None  # the disk (an untracked file, say) differs: not a reason to retrain
    assert staleness.changed_since("gaps", "b" * 40) is None  # a commit git does not know: loaded


def test_a_method_trained_on_reference_drapes_gets_them_before_its_fit_clock_starts(tmp_path, monkeypatch, body_lowres):
    """Simulating the reference set is making data, not training: it happens before ``fit``, so the training time
    (``train_s``, timed by the fit) leaves it out."""
    from drapebench.data import TrainData
    from drapebench.experiment import _checkpoint
    from methods.base import FitReport

    monkeypatch.setenv("DRAPEBENCH_DATA", str(tmp_path / "data"))
    made = []

    class Supervised(_ConstantState):
        needs_reference, seen = True, []

        def fit(self, data, train_cfg=None):
            self.seen.append(list(made))
            return FitReport(train_s=1.0, n_steps=1)

    cfg = _compose(["method=lbs", "body=anny_lowres"])
    garment = type("G", (), {"vertices": torch.zeros(3, 3), "faces": torch.zeros(1, 3, dtype=torch.long)})()
    data = TrainData(body_lowres, None, load_train=lambda: made.append("reference set") or [])
    _checkpoint(Supervised(), cfg, garment, data, {**OmegaConf.to_container(cfg.train, resolve=True), "dataset": None})
    assert Supervised.seen == [["reference set"]]  # made once, before the fit


def _fresh(extra=()):
    """A config whose test sequence nothing has cached yet (a new motion seed), so cache use is observable."""
    seed = int.from_bytes(os.urandom(3), "little")
    return _compose([*FAST, "viz=none", "motion.n_frames=4", "motion.transition=1", f"motion.seed={seed}", *extra]), f"walk_s{seed}"


def test_second_run_reuses_the_evaluation_and_a_corrupt_cache_entry_is_rebuilt(tmp_path, monkeypatch):
    import drapebench.metrics
    from drapebench.cache import cache_dir
    from drapebench.experiment import run

    calls = []
    evaluate = drapebench.metrics.evaluate
    monkeypatch.setattr(drapebench.metrics, "evaluate", lambda *a, **k: calls.append(1) or evaluate(*a, **k))
    cfg, seq_name = _fresh()
    first = run(cfg, tmp_path / "a")
    assert len(calls) == 1
    second = run(cfg, tmp_path / "b")
    assert len(calls) == 1, "identical second run evaluated again"
    assert second["eps_c"] == first["eps_c"] and second["jitter"] == first["jitter"]
    (entry,) = cache_dir("evaluations").glob(f"tshirt_{seq_name}_*.npz")
    data = bytearray(entry.read_bytes())
    data[len(data) // 2] ^= 0xFF
    entry.write_bytes(bytes(data))
    third = run(cfg, tmp_path / "c")
    assert len(calls) == 2, "corrupt cache entry was used"
    assert third["eps_c"] == first["eps_c"]
    run(cfg, tmp_path / "d")
    assert len(calls) == 2  # the rebuilt entry is valid again


def test_a_bad_method_parameter_fails_before_the_scene_and_its_reference_are_built(tmp_path, monkeypatch):
    import drapebench.experiment
    from drapebench.experiment import run

    def built(*args, **kwargs):
        raise AssertionError("the scene was built before the method's parameters were checked")

    monkeypatch.setattr(drapebench.experiment.Scene, "from_config", built)
    with pytest.raises(ValueError, match=r"unknown gaps train parameter\(s\) \['windw'\] \(method.params.train\) \(did you mean 'window'\?\)"):
        run(_compose(["method=gaps", "method.params.train.windw=4", *FAST]), tmp_path / "run")  # no "+" needed
    with pytest.raises(ValueError, match="gaps parameter bending must be one of blend, flat, template, not 'flt'"):
        run(_compose(["method=gaps", "+method.params.bending=flt", *FAST]), tmp_path / "run2")


def test_any_method_parameter_is_set_from_the_command_line_without_a_plus_and_other_nodes_stay_closed():
    """A key the method's yaml does not name (GAPS's collision_distance, a GapsTrain key, GenSim's arap_iterations) is set
    with ``method.params.<key>=v`` and reaches the method's typed parameters; the defaults the yaml leaves out are
    the dataclass's; a typo elsewhere still fails as Hydra composes the config."""
    from hydra.errors import ConfigCompositionException

    import methods
    from drapebench.experiment import method_params

    cfg = _compose(["method=gaps", "method.params.collision_distance=vertex", "method.params.train.hidden_init_std=0.2"])
    gaps = methods.get("gaps")(method_params(cfg, set()))
    assert gaps.p["collision_distance"] == "vertex" and gaps.p["train"]["hidden_init_std"] == 0.2
    assert gaps.p["train"]["window"] == 3 and gaps.p["canonical"] == "relaxed"  # GapsTrain's default; gaps.yaml's own value
    assert gaps.p["train"]["lr_output_factor"] == 0.1  # train=cpu's gaps_budget/cpu.yaml
    gensim = methods.get("gensim")(method_params(_compose(["method=gensim", "method.params.arap_iterations=7"]), set()))
    assert gensim.p["arap_iterations"] == 7
    with pytest.raises(ConfigCompositionException, match="garment.sede"):
        _compose(["method=gaps", "garment.sede=1"])


def test_interrupted_run_leaves_no_complete_looking_file(tmp_path, monkeypatch):
    import drapebench.viz
    from drapebench.cache import atomic_write
    from drapebench.experiment import run

    def crash(path, *args, **kwargs):
        with atomic_write(path, "w") as f:
            f.write("half a recording")
            raise KeyboardInterrupt

    monkeypatch.setattr(drapebench.viz, "record_drape", crash)
    cfg = _compose(FAST)
    out = tmp_path / "run"
    out.mkdir()
    (out / "config.yaml").write_text(OmegaConf.to_yaml(cfg, resolve=True))  # an earlier run of this config ...
    (out / "metrics.json").write_text("{}")  # ... left its result in the same folder
    with pytest.raises(KeyboardInterrupt):
        run(cfg, out)
    assert not (out / "metrics.json").exists() and not (out / "drape.rrd").exists()
    assert not list(out.glob(".*.tmp"))


def test_a_run_into_a_folder_with_another_runs_results_is_refused_and_the_same_run_clears_it(tmp_path, caplog):
    from drapebench.experiment import RunFolderInUse, run

    cfg, _ = _fresh()
    out = tmp_path / "run"
    run(cfg, out)
    before = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    assert {"metrics.json", "frames.csv", "prediction.h5", "config.yaml"} <= set(before)
    other = _compose([*FAST, "viz=rerun", f"motion.seed={cfg.motion.seed}"])  # its drape.rrd would sit beside the other's results
    with pytest.raises(RunFolderInUse, match=r"holds results of another run \(its config.yaml differs\): metrics.json, frames.csv, prediction.h5.*hydra.run.dir"):
        run(other, out)
    assert {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()} == before  # nothing lost or added
    with caplog.at_level(logging.WARNING, logger="drapebench"):
        record = run(cfg, out)  # the same config again: its earlier files are replaced, and the log says so
    assert "held files of an earlier run of this config (metrics.json, frames.csv" in caplog.text
    assert json.loads((out / "metrics.json").read_text()) == record
    stray = tmp_path / "stray"
    stray.mkdir()
    (stray / "losses.csv").write_text("mine")  # a file no run claims: refused, kept
    with pytest.raises(RunFolderInUse, match="no run of this config"):
        run(cfg, stray)
    assert (stray / "losses.csv").read_text() == "mine"


def test_a_refused_run_leaves_the_earlier_runs_hydra_folder_as_it_was(tmp_path):
    """Hydra writes ``.hydra/`` (config, overrides) into the run folder before the run starts; a run refused because the
    folder holds another run's results once left that run's command overwritten by its own."""
    out = tmp_path / "run"
    first = ["body=anny_lowres", "motion.n_frames=4", "reference=none", "viz=none", "tracker=none", f"hydra.run.dir={out}"]
    assert run_py(first, tmp_path).returncode == 0
    earlier = {p.name: p.read_bytes() for p in (out / ".hydra").iterdir()}
    refused = run_py([*first, "motion.n_frames=5"], tmp_path)
    assert refused.returncode != 0 and "RunFolderInUse" in refused.stderr
    assert {p.name: p.read_bytes() for p in (out / ".hydra").iterdir()} == earlier
    assert sorted(p.name for p in out.iterdir() if p.name.startswith(".hydra")) == [".hydra"]  # nothing left aside
    misspelt = run_py([*first, "+motion.n_framez=5"], tmp_path)  # refused by check_keys, before the folder is claimed
    assert misspelt.returncode != 0 and "motion.n_framez" in misspelt.stderr
    assert {p.name: p.read_bytes() for p in (out / ".hydra").iterdir()} == earlier


def test_reference_adds_vertex_error(tmp_path, monkeypatch):
    import torch

    import drapebench.reference
    from drapebench.experiment import run
    from drapebench.reference import SimSettings, SimulationRecord
    from methods.lbs import LBSMethod

    seen = {}

    def fake_simulate_record(garment, seq, body, material, solver, **settings):
        """A 'reference' 2 mm above the LBS drape."""
        seen.update(settings, solver=solver)
        lbs = LBSMethod({})
        lbs.bind(body, material)
        x = lbs.drape(garment, seq).vertices + torch.tensor([0.0, 0.0, 0.002])
        return SimulationRecord(x, {"sequence": 1.0}, SimSettings(), from_cache=False)

    monkeypatch.setattr(drapebench.reference, "simulate_record", fake_simulate_record)
    cfg, _ = _fresh(["reference.solver=vbd", "reference.substeps=3", "viz=rerun"])
    rec = run(cfg, tmp_path / "r")
    assert seen["solver"] == "vbd" and seen["substeps"] == 3 and seen["force"] is False
    assert rec["vertex_error_mm"] == pytest.approx(2.0, rel=1e-3)
    assert rec["reference_s"] >= 0 and (tmp_path / "r" / "drape.rrd").exists()


@pytest.mark.slow
def test_joblib_launcher_runs_jobs_in_parallel_with_their_share_of_threads(tmp_path):
    sweep = tmp_path / "sweep"
    p = run_py(["-m", "hydra/launcher=joblib", "hydra.launcher.n_jobs=2", *FAST, "garment=tshirt,skirt", "viz=none",
                f"hydra.sweep.dir={sweep}"], tmp_path)  # fmt: skip
    assert p.returncode == 0, p.stderr[-3000:]
    assert len((sweep / "summary.csv").read_text().strip().splitlines()) == 3
    cores = len(os.sched_getaffinity(0))
    for env in sweep.glob("*/env.json"):
        assert json.loads(env.read_text())["torch_threads"] == max(1, cores // min(cores, 2))


@pytest.mark.slow
def test_submitit_local_launcher_runs_a_sweep(tmp_path):
    pytest.importorskip("hydra_plugins.hydra_submitit_launcher")
    sweep = tmp_path / "sweep"
    p = run_py(["-m", "hydra/launcher=submitit_local", *FAST, "garment=skirt,pants", "viz=none", f"hydra.sweep.dir={sweep}"],
               tmp_path, timeout=600)  # fmt: skip
    assert p.returncode == 0, p.stderr[-3000:]
    assert len((sweep / "summary.csv").read_text().strip().splitlines()) == 3


def test_ms_per_frame_of_a_cached_drape_is_the_original_computation_not_the_load():
    from drapebench.experiment import drape_ms_per_frame

    assert drape_ms_per_frame({"simulate": 2000.0, "cache_load": 5.0}, drape_s=0.005, n_frames=10) == pytest.approx(200.0)
    assert drape_ms_per_frame({"rollout": 30.0}, drape_s=0.04, n_frames=10) == pytest.approx(4.0)
    assert drape_ms_per_frame({"setup": 1500.0, "network": 5.0}, drape_s=1.51, n_frames=10) == pytest.approx(1.0)  # set-up is not per frame
    assert drape_ms_per_frame({"setup": 1500.0, "network": 5.0, "cache_load": 2.0}, drape_s=0.002, n_frames=10) == pytest.approx(0.5)
    with pytest.raises(ValueError, match="n_frames"):
        drape_ms_per_frame({}, drape_s=0.0, n_frames=0)


@pytest.mark.parametrize("on_failure", ["stop", "record"])
def test_a_diverged_method_stops_the_run_or_is_recorded(tmp_path, monkeypatch, on_failure):
    from drapebench.errors import DrapeFailed
    from drapebench.experiment import run
    from methods.lbs.method import LBSMethod

    def diverge(self, garment, seq, chunk_frames):
        raise DrapeFailed(f"{garment.kind} diverged at frame 3")

    monkeypatch.setattr(LBSMethod, "drape_chunks", diverge)  # what a run calls
    cfg = _compose([*FAST, "viz=none", f"on_failure={on_failure}"])
    out = tmp_path / "run"
    if on_failure == "stop":
        with pytest.raises(DrapeFailed, match="tshirt diverged at frame 3"):
            run(cfg, out)
        assert not (out / "failed.json").exists()
    else:
        rec = run(cfg, out)
        saved = json.loads((out / "failed.json").read_text())
        assert rec == saved and saved["status"] == "failed" and saved["error"] == "DrapeFailed"
        assert saved["method"] == "lbs" and saved["garment"] == "tshirt" and "frame 3" in saved["message"]
    assert not (out / "metrics.json").exists()


@pytest.mark.parametrize("generic, fits", [(True, 1), (False, 2)])
def test_a_generic_method_trains_once_for_every_garment(generic, fits, tmp_path, monkeypatch, body_lowres):
    from drapebench.experiment import _checkpoint
    from methods.base import FitReport

    monkeypatch.setenv("DRAPEBENCH_DATA", str(tmp_path / "data"))

    class Learned(_ConstantState):
        calls = []

        def fit(self, data, train_cfg=None):
            self.calls.append(1)
            return FitReport(train_s=1.0, n_steps=1)

    Learned.generic = generic
    cfg = _compose(["method=lbs", "body=anny_lowres"])
    data = type("D", (), {"body": body_lowres, "material": None})()
    train_cfg = {**OmegaConf.to_container(cfg.train, resolve=True), "dataset": None}
    for n in (3, 4):  # two garments of different sizes
        garment = type("G", (), {"vertices": torch.zeros(n, 3), "faces": torch.zeros(1, 3, dtype=torch.long)})()
        _checkpoint(Learned(), cfg, garment, data, train_cfg)
    assert len(Learned.calls) == fits


def test_two_runs_started_in_the_same_second_get_their_own_directories():
    import re

    from drapebench.schema import register

    register()
    with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
        cfg = compose("config", overrides=[], return_hydra_config=True)
    run_dir, sweep_dir = cfg.hydra.run.dir, cfg.hydra.sweep.dir  # the sub-second field keeps two runs apart
    assert re.search(r"/\d\d-\d\d-\d\d\.\d{6}_lbs_tshirt_walk$", run_dir), run_dir
    assert re.search(r"/\d\d-\d\d-\d\d\.\d{6}$", sweep_dir), sweep_dir


def test_a_failed_sweep_says_what_failed_and_leaves_no_empty_folder(tmp_path):
    sweep = tmp_path / "multirun" / "2026-01-01" / "12-00-00"
    p = run_py(["-m", *FAST, "garment=tshirt,nope", "viz=none", f"hydra.sweep.dir={sweep}"], tmp_path)
    assert p.returncode != 0 and "nope" in p.stderr
    assert not (tmp_path / "multirun" / "2026-01-01").exists(), "a sweep that never started left its folder"
    p = run_py(["-m", "body=anny_lowres", "motion.n_frames=0", "garment=tshirt,skirt", "viz=none", f"hydra.sweep.dir={sweep}"], tmp_path)
    assert p.returncode != 0
    failed = [json.loads(f.read_text()) for f in sorted(sweep.glob("*/failed.json"))]
    assert [f["garment"] for f in failed] == ["tshirt", "skirt"] and all("n_frames" in f["message"] for f in failed)
    summary = (sweep / "summary.md").read_text()
    assert summary.count("| failed ") == 2 and "n_frames" in summary


def test_an_interrupted_sweep_job_is_listed_unfinished_with_the_command_that_finishes_it(tmp_path):
    """A job killed mid-run (no metrics.json, no failed.json) was once missing from summary.md, as if never planned."""
    from drapebench.experiment import run
    from drapebench.report import write_summary

    sweep = tmp_path / "sweep"
    run(_compose([*FAST, "reference=none", "viz=none", "tracker=none"]), sweep / "0")
    killed = sweep / "1"
    (killed / ".hydra").mkdir(parents=True)
    (killed / "config.yaml").write_text((sweep / "0" / "config.yaml").read_text().replace("name: walk", "name: kick"))
    given = ["experiment=gensim_pen", "motion=kick", "viz=none", "experiment_name=two words"]  # the sweep set MULTIRUN
    (killed / ".hydra" / "overrides.yaml").write_text(yaml.safe_dump(given))
    summary = write_summary(sweep).read_text()
    rows = {line.split("|")[1].strip(): line for line in summary.splitlines() if line.startswith("| ") and "status" not in line}
    assert set(rows) == {"ok", "unfinished"} and "kick" in rows["unfinished"] and "walk" in rows["ok"]
    command = shlex.split(rows["unfinished"].split("finish it with ")[1].split(" (a training")[0])
    assert command == ["python", "run.py", *given, f"hydra.run.dir={killed}", "hydra.mode=RUN"]
    from drapebench.schema import register

    register()
    with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
        hydra_cfg = compose("config", overrides=command[2:], return_hydra_config=True).hydra
    assert str(hydra_cfg.mode) == "RunMode.RUN" and hydra_cfg.run.dir == str(killed)  # one run, into the job's folder


def test_viz_body_draws_another_body_while_collisions_follow_the_runs_body(tmp_path, monkeypatch, body_full, body_lowres):
    import drapebench.viz
    from drapebench.experiment import run

    seen = {}

    def capture(path, body_vertices, body_faces, garment_vertices, topology, fps, penetrating=None, metrics=None, **kw):
        seen.update(n_body=body_vertices.shape[1], inside=penetrating, metrics=metrics)
        Path(path).write_bytes(b"rrd")

    monkeypatch.setattr(drapebench.viz, "record_drape", capture)
    rec = run(_compose([*FAST, "viz_body=anny"]), tmp_path / "r")
    assert seen["n_body"] == body_full.n_vertices != body_lowres.n_vertices
    assert float(seen["inside"][3:].double().mean() * 100) == pytest.approx(rec["eps_c"], rel=1e-6)  # magenta: the run's body
    assert list(seen["metrics"]["frame"])[0] == 3 and "eps_c" in seen["metrics"]  # the evaluated frames, plotted


def test_a_bad_viz_body_is_refused_before_the_drape_and_ignored_with_a_warning_without_a_recording(tmp_path, monkeypatch, caplog):
    """``viz_body=foo`` was once found only when the recording began, after the reference, training and drape."""
    import drapebench.drape_stream
    from drapebench.experiment import run

    monkeypatch.setattr(drapebench.drape_stream, "stream_drape", lambda *a, **k: pytest.fail("the drape ran"))
    with pytest.raises(ValueError, match=r"viz_body=foo cannot be loaded \(.*\); give viz_body a shipped body \(anny, anny_lowres\)"):
        run(_compose([*FAST, "reference=none", "viz_body=foo"]), tmp_path / "a")
    monkeypatch.undo()
    with caplog.at_level("WARNING", logger="drapebench"):
        rec = run(_compose([*FAST, "reference=none", "viz=none", "viz_body=foo"]), tmp_path / "b")
    assert "viz_body=foo is read only by viz=rerun" in caplog.text and rec["eps_e"] > 0


def test_a_drape_with_nan_is_a_failure_naming_its_frames(tmp_path, monkeypatch):
    from drapebench.experiment import run
    from methods.base import DrapeResult
    from methods.lbs.method import LBSMethod

    drape_chunks = LBSMethod.drape_chunks

    def nan_at_2_and_9(self, garment, seq, chunk_frames):  # streamed in chunks of 4 frames: frames 2 and 9 in two of them
        for a, chunk in zip(range(0, seq.n_frames, chunk_frames), drape_chunks(self, garment, seq, chunk_frames)):
            x = chunk.vertices.clone()
            x[[f - a for f in (2, 9) if a <= f < a + len(x)], 7, 1] = float("nan")
            yield DrapeResult(x, {})

    monkeypatch.setattr(LBSMethod, "drape_chunks", nan_at_2_and_9)
    out = tmp_path / "run"
    rec = run(_compose([*FAST, "viz=none", "on_failure=record", "chunk_frames=4"]), out)
    assert rec["error"] == "NonFiniteDrape" and "NaN/Inf vertex positions in 2 of 13" in rec["message"] and "frames 2, 9)" in rec["message"]
    assert not (out / "metrics.json").exists() and not (out / "prediction.h5").exists()
    assert [p.name for p in out.iterdir() if p.name.startswith(".")] == []  # no temporary file left


def test_dtype_float64_runs_body_garment_method_and_metrics_in_double(tmp_path, monkeypatch):
    from drapebench.experiment import run
    from methods.lbs.method import LBSMethod

    seen = {}
    drape_chunks = LBSMethod.drape_chunks

    def spy(self, garment, seq, chunk_frames):
        for result in drape_chunks(self, garment, seq, chunk_frames):
            seen.update(body=self.body.dtype, topology=garment.topology.dtype, drape=result.vertices.dtype)
            yield result

    monkeypatch.setattr(LBSMethod, "drape_chunks", spy)
    rec64 = run(_compose([*FAST, "viz=none", "dtype=float64"]), tmp_path / "a")
    assert seen == {"body": torch.float64, "topology": torch.float64, "drape": torch.float64} and rec64["dtype"] == "float64"
    rec32 = run(_compose([*FAST, "viz=none"]), tmp_path / "b")
    assert rec32["dtype"] == "float32" and seen["drape"] == torch.float32
    assert rec64["eps_e"] == pytest.approx(rec32["eps_e"], rel=1e-4) and rec64["max_strain"] == pytest.approx(rec32["max_strain"], rel=1e-3)
    with pytest.raises(Exception, match="float16"):
        _compose([*FAST, "dtype=float16"])


@pytest.mark.slow
@pytest.mark.parametrize("method", [["method=lbs"], ["method=gaps", "method.params.train.schedule.steps=0"]])
def test_a_slice_of_the_stability_matrix_is_finite_and_the_same_in_float32_and_float64(tmp_path, method):
    from drapebench.experiment import run

    scene = ["experiment=stability", *method, "garment=tshirt", "motion=stress", "motion.n_frames=40", "motion.betas=[2.0,2.0]", "viz=none"]
    recs = {d: run(_compose([*scene, f"dtype={d}"]), tmp_path / d) for d in ("float32", "float64")}
    for rec in recs.values():
        assert rec["dtype"] in recs and all(math.isfinite(rec[k]) for k in ("max_strain", "max_penetration_mm", "eps_c", "drift_mm"))
    for k in ("max_strain", "max_penetration_mm", "eps_c", "eps_e"):
        assert recs["float64"][k] == pytest.approx(recs["float32"][k], rel=1e-3, abs=1e-4)


def test_a_shipped_motion_written_in_amass_layout_drapes_as_the_original(tmp_path, body_lowres):
    """kick through motion=kick, and the same kick sampled at AMASS's 120 fps, written as an SMPL-H file (SMPL's joint
    order, T-pose rest, Z up) and read back through motion=amass at 30 fps: the same drape. The file holds the motion's
    own transition from the rest pose, so the reader adds none; root=file: its trans is the body's."""
    import numpy as np
    import pandas as pd

    from drapebench.body import make_sequence
    from drapebench.body.amass import to_smpl_layout
    from drapebench.experiment import run
    from drapebench.results import read_prediction

    n, tr = 8, 3
    kick120 = make_sequence("kick", 4 * n - 3, 120.0, seed=1000, transition=4 * tr)  # frame 4k at 120 fps = frame k at 30 fps
    np.savez(tmp_path / "kick.npz", **to_smpl_layout(kick120, body_lowres, "SMPL-H"), betas=np.zeros(16), gender=np.array("female"))
    common = ["body=anny_lowres", "viz=none", "method=lbs"]
    original = run(_compose([*common, "motion=kick", f"motion.n_frames={n}", f"motion.transition={tr}"]), tmp_path / "kick")
    read = run(_compose([*common, "motion=amass", f"motion.path={tmp_path / 'kick.npz'}", f"motion.n_frames={n + tr}",
                         "motion.transition=0", "motion.root=file"]), tmp_path / "amass")  # fmt: skip
    assert read["motion"] == "amass" and read["n_frames"] == original["n_frames"] == n + tr
    x_original, faces, _ = read_prediction(tmp_path / "kick" / "prediction.h5")
    x_read, faces_read, attrs = read_prediction(tmp_path / "amass" / "prediction.h5")
    assert np.array_equal(faces, faces_read) and attrs["fps"] == 30.0
    assert np.abs(x_read - x_original).max() < 1e-5  # m
    a = pd.read_csv(tmp_path / "kick" / "frames.csv").set_index("frame")
    b = pd.read_csv(tmp_path / "amass" / "frames.csv").set_index("frame").loc[a.index]  # the original skips its transition
    for column in ("eps_e", "eps_a", "eps_c", "penetration_mm", "max_strain"):
        assert np.allclose(a[column], b[column], rtol=1e-4, atol=1e-4), column


def test_a_method_s_scored_variants_get_the_same_metrics_suffixed_with_their_name(tmp_path, monkeypatch):
    from drapebench.experiment import run
    from drapebench.results import legend, metric_label
    from methods.lbs.method import LBSMethod

    monkeypatch.setattr(LBSMethod, "scored_variants", lambda self, seq, result: {"lifted": result.vertices + torch.tensor([0.0, 0.0, 0.05])})
    rec = run(_compose([*FAST, "viz=none"]), tmp_path / "run")
    assert rec["eps_c@lifted"] != rec["eps_c"] and "eps_e@lifted" in rec and not any(k.endswith("@lifted") and k.startswith("ms_") for k in rec)
    assert metric_label("eps_c@lifted") == "ε_c (%) [lifted]" and "variant" in legend(["eps_c@lifted"])


def test_the_vae_on_data_cpu_has_no_shape_input_and_the_paper_preset_keeps_the_papers():
    import methods

    for overrides, betas in ((["method=vae"], 0), (["method=vae_no_collision"], 0), (["method=vae", "data=paper"], None)):
        cfg = _compose(overrides).method
        params = OmegaConf.to_container(cfg.params, resolve=True)
        assert params.get("regressor", {}).get("betas") == betas, overrides
        expected = 10 if betas is None else betas  # the code's default is the paper's beta in R^10
        assert methods.get(cfg.impl)(params).p["regressor"]["betas"] == expected


def test_a_float64_run_30_km_from_the_origin_measures_what_it_measures_at_the_origin(tmp_path, body_lowres):
    """A walk 30 km from the origin (an SMPL file read with root=file, so nothing moves it back): in float64 its
    metrics are those of the same walk at the origin to float64's resolution at the body's scale (a skinning weight
    row that sums to 1 within 4e-8 once moved the drape 1.2 mm there, a float32 root 0.9 mm per frame), and its
    prediction.h5 is float64; in float32 the run is refused, naming dtype=float64."""
    import numpy as np
    import pandas as pd

    from drapebench.body import make_sequence
    from drapebench.body.amass import to_smpl_layout
    from drapebench.experiment import run
    from drapebench.metrics import FarFromOrigin
    from drapebench.results import read_prediction

    d = to_smpl_layout(make_sequence("walk", 8, 30.0, seed=1000, transition=3), body_lowres)
    offset = np.array([30000.123456789, -12000.987654321, 0.0])  # m: float32 would round it to 2 mm
    np.savez(tmp_path / "here.npz", **d)
    np.savez(tmp_path / "far.npz", **{**d, "trans": d["trans"] + offset})
    common = ["body=anny_lowres", "viz=none", "method=lbs", "motion=amass", "motion.root=file", "motion.transition=0", "dtype=float64"]
    here, far = (run(_compose([*common, f"motion.path={tmp_path / n}.npz"]), tmp_path / n) for n in ("here", "far"))
    assert here["eps_e"] > 0.1 and here["n_frames"] == far["n_frames"] == 11
    for key in ("eps_e", "eps_a", "eps_c", "edge_mm", "max_strain", "penetration_mm", "garment_body_mm"):
        assert far[key] == pytest.approx(here[key], rel=1e-9, abs=1e-9), key
    assert far["jitter"] == pytest.approx(here["jitter"], abs=1e-6)  # mm
    a, b = (pd.read_csv(tmp_path / n / "frames.csv") for n in ("here", "far"))
    assert np.abs(a["eps_e"] - b["eps_e"]).max() < 1e-7, np.abs(a["eps_e"] - b["eps_e"]).max()  # % (float64 at 30 km: 4e-12 m apart)
    x_here, _, _ = read_prediction(tmp_path / "here" / "prediction.h5")
    x_far, _, _ = read_prediction(tmp_path / "far" / "prediction.h5")
    assert x_far.dtype == np.float64
    assert np.abs(x_far - offset - x_here).max() < 1e-9  # m: the same drape, moved
    with pytest.raises(FarFromOrigin, match="dtype=float64"):
        run(_compose([*common[:-1], f"motion.path={tmp_path / 'far'}.npz"]), tmp_path / "far32")


def _numbers(record: dict) -> dict:
    """A run record's measurements: its numbers other than timings."""
    timing = ("ms_per_frame", "train_s", "setup_s")
    return {k: v for k, v in record.items() if isinstance(v, (int, float)) and not k.startswith("ms_") and not k.endswith("_s") and k not in timing}


def test_a_streamed_lbs_drape_writes_and_scores_what_a_whole_one_does(tmp_path):
    """chunk_frames=4: the lbs drape is made, written to prediction.h5 and scored 4 frames at a time (issue 59); the
    file is that of the drape made whole (chunk_frames=1000), frames.csv and the metrics too, to float32 rounding."""
    import numpy as np
    import pandas as pd

    from drapebench.experiment import run
    from drapebench.results import read_prediction

    scene = [*FAST, "viz=none", "motion.n_frames=20", f"motion.seed={int.from_bytes(os.urandom(3), 'little')}"]  # nothing cached
    whole = run(_compose([*scene, "chunk_frames=1000"]), tmp_path / "whole")
    streamed = run(_compose([*scene, "chunk_frames=4"]), tmp_path / "streamed")
    (xw, fw, aw), (xs, fs, as_) = (read_prediction(tmp_path / d / "prediction.h5") for d in ("whole", "streamed"))
    assert xs.shape == (23, 2796, 3) and np.array_equal(xs, xw) and np.array_equal(fs, fw) and as_ == aw
    assert _numbers(streamed).keys() == _numbers(whole).keys() and "eps_e" in _numbers(whole)
    for k, v in _numbers(whole).items():
        assert streamed[k] == pytest.approx(v, rel=1e-6, abs=1e-9, nan_ok=True), k  # float32 metrics of other batches
    frames = [pd.read_csv(tmp_path / d / "frames.csv") for d in ("whole", "streamed")]
    pd.testing.assert_frame_equal(frames[1], frames[0], rtol=1e-6)


def test_a_streamed_lbs_run_holds_no_garment_array_that_grows_with_its_frames(tmp_path):
    """The largest array of garment positions (a tensor with a dimension of the garment's 2,796 vertices) that any torch
    operation of a whole lbs run reads or makes (drape, checks, prediction.h5, metrics, frames.csv) is the same for 10
    and 40 frames with chunk_frames=4: the drape is never held whole; with chunk_frames=1000 it is, and grows."""
    from torch.utils._python_dispatch import TorchDispatchMode
    from torch.utils._pytree import tree_leaves

    from drapebench.experiment import run

    class Largest(TorchDispatchMode):
        bytes = 0

        def __torch_dispatch__(self, func, types, args=(), kwargs=None):
            out = func(*args, **(kwargs or {}))
            for t in tree_leaves((args, kwargs, out)):
                if isinstance(t, torch.Tensor) and t.layout == torch.strided and 2796 in t.shape:
                    self.bytes = max(self.bytes, t.untyped_storage().nbytes())
            return out

    def largest(n_frames: int, chunk_frames: int) -> int:
        seed = int.from_bytes(os.urandom(3), "little")  # nothing cached: the metrics run
        cfg = _compose([*FAST, "viz=none", f"motion.n_frames={n_frames}", f"motion.seed={seed}", f"chunk_frames={chunk_frames}"])
        with Largest() as mode:
            run(cfg, tmp_path / f"{n_frames}_{chunk_frames}")
        return mode.bytes

    drape = 43 * 2796 * 3 * 4  # bytes: the 40 + 3 frames of the float32 drape
    short, long = largest(10, 4), largest(40, 4)
    assert short == long < drape / 2
    assert largest(40, 1000) >= drape  # held whole


def test_a_training_cut_by_max_minutes_is_recorded_and_warned_on_every_load(tmp_path, monkeypatch, body_lowres, caplog):
    """A model whose training the time guard cut depends on the machine's speed: its checkpoint says so, the run
    that trains it and every run that loads it return "time" (metrics.json's train_stopped) and a load warns."""
    from drapebench.experiment import _checkpoint
    from methods.base import FitReport

    monkeypatch.setenv("DRAPEBENCH_DATA", str(tmp_path / "data"))

    class Cut(_ConstantState):
        stopped = "time"

        def fit(self, data, train_cfg=None):
            return FitReport(train_s=1.0, n_steps=3, stopped=self.stopped)

    cfg = _compose(["method=lbs", "body=anny_lowres"])
    garment = type("G", (), {"vertices": torch.zeros(3, 3), "faces": torch.zeros(1, 3, dtype=torch.long)})()
    data = type("D", (), {"body": body_lowres, "material": None})()
    train_cfg = {**OmegaConf.to_container(cfg.train, resolve=True), "dataset": None}
    assert _checkpoint(Cut(), cfg, garment, data, train_cfg).stopped == "time"
    with caplog.at_level("WARNING", logger="drapebench"):
        assert _checkpoint(Cut(), cfg, garment, data, train_cfg).stopped == "time"  # loaded, not retrained
    assert "cut by train.max_minutes" in caplog.text and "3 steps done" in caplog.text
    Cut.stopped = "clock"  # every step, its lr decayed by the clock: recorded and warned on a load too
    assert _checkpoint(Cut(), cfg, garment, data, {**train_cfg, "seed": 98}).stopped == "clock"
    caplog.clear()
    with caplog.at_level("WARNING", logger="drapebench"):
        assert _checkpoint(Cut(), cfg, garment, data, {**train_cfg, "seed": 98}).stopped == "clock"
    assert "decayed by train.max_minutes' clock" in caplog.text
    Cut.stopped = "done"
    assert _checkpoint(Cut(), cfg, garment, data, {**train_cfg, "seed": 99}).stopped == "done"


class _ConstantState(DrapingMethod):
    """A learned method whose state is a constant tensor and that never drapes (checkpoint tests)."""

    def fit(self, data, train_cfg=None):
        raise NotImplementedError

    def drape(self, garment, seq):
        raise NotImplementedError

    def state_dict(self):
        return {"w": torch.ones(2)}

    def load_state_dict(self, state):
        pass


def test_a_run_whose_reference_fails_keeps_its_own_metrics_and_says_why_it_has_no_vertex_error(tmp_path, monkeypatch):
    """The reference is what the drape is compared with; when its simulation diverges the method's drape and its
    own metrics still stand: the run ends with them, metrics.json names the failure, the table says so."""
    import drapebench.experiment
    from drapebench.errors import DrapeFailed
    from drapebench.experiment import run
    from drapebench.report import write_table

    def diverged(self):
        raise DrapeFailed("reference simulation (vbd) of garment 'tshirt' diverged at frame 3")

    monkeypatch.setattr(drapebench.experiment.Scene, "reference", diverged)
    cfg, _ = _fresh(["reference=vbd"])
    record = run(cfg, tmp_path / "run")
    assert "vertex_error_mm" not in record and math.isfinite(record["eps_e"])
    assert record["reference_error"].endswith("diverged at frame 3")
    assert json.loads((tmp_path / "run" / "metrics.json").read_text())["reference_error"] == record["reference_error"]
    md = write_table([tmp_path], "runtime_vs_error", tmp_path / "t", command="pytest")[0].read_text()  # a table with the vertex error
    assert "- lbs on tshirt have no vertex error, their reference failed: reference simulation (vbd)" in md


def test_what_the_user_types_as_train_keys_wins_over_a_method_s_own_budget():
    """GAPS's train=cpu budget sets steps; a typed train.epochs=0 (an untrained row) drops it, so the method trains
    nothing, instead of its 3,300 steps; a typed train.lr drops only the schedule's lr; untyped keys stay."""
    from drapebench.experiment import method_params

    cfg = _compose(["method=gaps", "train=cpu"])
    schedule = OmegaConf.to_container(cfg.method.params.train.schedule)
    assert {"steps", "lr", "grad_clip"} <= set(schedule)
    untrained = method_params(cfg, {"epochs"})["train"]["schedule"]
    assert "steps" not in untrained and untrained["lr"] == schedule["lr"]
    assert "steps" not in method_params(cfg, {"steps"})["train"]["schedule"]
    lr = method_params(cfg, {"lr"})["train"]["schedule"]
    assert "lr" not in lr and lr["steps"] == schedule["steps"]
    assert method_params(cfg, set())["train"]["schedule"] == schedule
    assert method_params(_compose(["method=lbs"]), {"epochs"}) == OmegaConf.to_container(_compose(["method=lbs"]).method.params)


def test_without_git_every_commit_reads_unknown(monkeypatch):
    """No git binary: the history cannot be read, so no commit is known (rows read stale, checkpoints load as
    "cannot be checked") instead of a FileNotFoundError out of every run."""
    import subprocess

    import drapebench.staleness as staleness

    def no_git(*args, **kwargs):
        raise FileNotFoundError("git")

    monkeypatch.setattr(subprocess, "run", no_git)
    staleness.known.cache_clear()
    try:
        assert staleness.known("HEAD") is None and staleness.changed_since("gaps", "a" * 40) is None
    finally:
        staleness.known.cache_clear()


def test_a_method_config_without_impl_is_its_names_implementation_everywhere():
    """The schema's impl defaults to the name: the checkpoint's code fingerprint must follow it too (None would never
    tell a model trained by changed code)."""
    from omegaconf import OmegaConf

    from drapebench.experiment import method_impl
    from drapebench.staleness import code_of

    cfg = OmegaConf.create({"method": {"impl": None, "name": "gaps"}})
    assert method_impl(cfg) == "gaps" and code_of(method_impl(cfg)) == code_of("gaps") is not None


def test_an_inference_setting_loads_the_model_trained_without_it():
    """GenSim's inference-only keys (its arithmetic, compilation, threads) are left out of the checkpoint key, so typing
    one loads the trained model instead of training another; a key the model depends on still makes its own."""
    from omegaconf import OmegaConf

    from drapebench.experiment import checkpoint_path, method_class
    from drapebench.scene import Scene

    def path(*overrides):
        cfg = _compose(["method=gensim", "garment=skirt", "body=anny_lowres", *overrides])
        scene = Scene.from_config(cfg, device="cpu")
        method = method_class(cfg)(OmegaConf.to_container(cfg.method.params, resolve=True))
        return checkpoint_path(method, cfg, scene.garment, scene.body)

    plain = path()
    assert path("method.params.pen_precision=bf16", "method.params.workers=2", "method.params.pen_compile=true") == plain
    assert path("method.params.latent=32") != plain
