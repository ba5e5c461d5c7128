"""drapebench.scene: the one place a config becomes a scene; a run reloaded by load_run or by the export is the run
(its dtype, its numbers)."""

from pathlib import Path

import numpy as np
import pytest
import torch
from hydra import compose, initialize_config_dir

from drapebench.experiment import run
from drapebench.export import Drape, drape_from_run
from drapebench.metrics import evaluate
from drapebench.results import read_prediction
from drapebench.scene import Scene
from drapebench.schema import register
from drapebench.trained_run import load_run

ROOT = Path(__file__).resolve().parents[1]
SCENE = ["body=anny_lowres", "garment=skirt", "motion=kick", "motion.n_frames=6", "motion.transition=2", "viz=none"]


def _compose(overrides):
    register()
    with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
        return compose("config", overrides=overrides)


def test_the_scene_is_built_in_the_configs_dtype():
    for dtype in (torch.float32, torch.float64):
        scene = Scene.from_config(_compose([*SCENE, f"dtype={str(dtype).removeprefix('torch.')}"]))
        assert scene.dtype == scene.body.dtype == scene.garment.topology.dtype == dtype
        assert scene.device.type == "cpu" and scene.seq.n_frames == 8 and scene.reference() is None


def test_a_float64_run_reloaded_by_load_run_and_by_the_export_gives_the_runs_own_numbers(tmp_path):
    cfg = _compose([*SCENE, "method=lbs", "dtype=float64"])
    record = run(cfg, tmp_path / "run")
    again = load_run(tmp_path / "run")
    assert again.dtype == again.body.dtype == again.garment.topology.dtype == torch.float64
    drape = again.method.drape(again.garment, again.seq).vertices
    assert drape.dtype == torch.float64
    stored = read_prediction(tmp_path / "run" / "prediction.h5")[0]
    np.testing.assert_allclose(drape.numpy(), stored, rtol=0, atol=1e-6)  # prediction.h5 holds float32
    summary, _ = evaluate(again.garment, again.seq, again.body, drape, reference=again.reference(), material=again.material,
                          skip_transition=bool(cfg.eval.skip_transition), energies=bool(cfg.eval.energies))  # fmt: skip
    for key in ("eps_e", "eps_a", "eps_c", "max_strain", "edge_mm", "smoothness", "energy_stvk"):
        assert summary[key] == pytest.approx(record[key], rel=1e-12, abs=1e-15), key
    exported = drape_from_run(tmp_path / "run")
    in_run = Drape.from_scene(torch.from_numpy(stored).double(), again.garment, again.seq, again.body, exported.label)
    for field in ("garment", "garment_rest", "strain", "body", "body_rest"):
        assert np.array_equal(getattr(exported, field), getattr(in_run, field)), field


def test_load_run_reads_an_archived_runs_relative_checkpoint_and_refuses_a_model_trained_since(tmp_path, monkeypatch):
    """The cache keeps one model per configuration: a model trained again since the run (another commit or time)
    is not the run's, and loading it would diagnose another model without a word."""
    import json

    monkeypatch.setenv("DRAPEBENCH_DATA", str(tmp_path / "data"))
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    (run_dir / "config.yaml").write_text("method:\n  name: gaps\n")
    metrics = {"checkpoint": "cache/checkpoints/gaps_0.pt", "trained_at": "a" * 40, "train_s": 12.5}
    (run_dir / "metrics.json").write_text(json.dumps(metrics))
    with pytest.raises(FileNotFoundError, match=str(tmp_path / "data" / "cache" / "checkpoints")):
        load_run(run_dir)
    (tmp_path / "data" / "cache" / "checkpoints").mkdir(parents=True)
    torch.save({"method": {}, "commit": "b" * 40, "train_s": 30.0}, tmp_path / "data" / "cache" / "checkpoints" / "gaps_0.pt")
    with pytest.raises(ValueError, match="another model than the run's"):
        load_run(run_dir)
