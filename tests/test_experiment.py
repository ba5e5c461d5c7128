"""End-to-end runs of run.py through Hydra (low-resolution body, short sequences)."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from hydra import compose, initialize_config_dir
from hydra.errors import ConfigCompositionException

ROOT = Path(__file__).resolve().parents[1]
FAST = ["body=anny_lowres", "motion.n_frames=10", "motion.transition=3"]


def run_py(args, tmp_path, timeout=240):
    env = dict(os.environ, DRAPEBENCH_PROGRESS="0", HYDRA_FULL_ERROR="1")
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
    env = json.loads((out / "env.json").read_text())
    assert env["versions"]["torch"] and env["torch_threads"] == 2
    rerun = Path(sys.executable).parent / "rerun"
    v = subprocess.run([str(rerun), "rrd", "verify", str(out / "drape.rrd")], capture_output=True, text=True, timeout=60)
    assert v.returncode == 0, v.stderr


def test_multirun_writes_a_summary_row_per_job(tmp_path):
    sweep = tmp_path / "sweep"
    p = run_py(["-m", *FAST, "garment=tshirt,skirt", "viz=none", f"hydra.sweep.dir={sweep}"], tmp_path)
    assert p.returncode == 0, p.stderr[-3000:]
    lines = (sweep / "summary.csv").read_text().strip().splitlines()
    assert len(lines) == 3 and lines[0].startswith("method,garment")
    assert {ln.split(",")[1] for ln in lines[1:]} == {"tshirt", "skirt"}
    assert (sweep / "summary.md").exists()


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
    with pytest.raises(ConfigCompositionException, match="Error merging override motion.n_frames=abc"):
        _compose(["motion.n_frames=abc"])


def test_every_experiment_config_composes():
    for exp in sorted((ROOT / "conf" / "experiment").glob("*.yaml")):
        cfg = _compose([f"experiment={exp.stem}"])
        assert cfg.experiment_name == exp.stem


def test_second_run_reuses_the_cache_and_interrupted_runs_leave_no_metrics(tmp_path):
    from drapebench.experiment import run

    cfg = _compose([*FAST, "viz=none"])
    run(cfg, tmp_path / "a")
    assert (tmp_path / "a" / "metrics.json").exists()
    bad = _compose([*FAST, "viz=bogus"])  # fails after the prediction is written, before metrics.json
    with pytest.raises(ValueError, match="viz must be"):
        run(bad, tmp_path / "b")
    assert not (tmp_path / "b" / "metrics.json").exists()
    assert not list((tmp_path / "b").glob(".*.tmp"))


@pytest.mark.slow
def test_submitit_local_launcher_runs_a_sweep(tmp_path):
    pytest.importorskip("hydra_plugins.hydra_submitit_launcher")
    sweep = tmp_path / "sweep"
    p = run_py(["-m", "hydra/launcher=submitit_local", *FAST, "garment=skirt,pants", "viz=none", f"hydra.sweep.dir={sweep}"],
               tmp_path, timeout=600)  # fmt: skip
    assert p.returncode == 0, p.stderr[-3000:]
    assert len((sweep / "summary.csv").read_text().strip().splitlines()) == 3
