"""The reference set on a cluster: one Hydra job per sequence through the submitit launcher (submitit_local here),
real short simulations; a lost job's sequence is simulated again by the next run and the finished one is not."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
TINY = ["garment=skirt", "+garment.params.resolution=0.03", "body=anny_lowres", "data.name=tiny", "data.motions=[walk]",
        "data.per_motion=2", "data.n_frames=2", "data.transition=1", "data.beta_sigma=0.3", "+data.settings.settle_frames=1",
        "+data.settings.substeps=2", "+data.settings.iterations=3", "+data.settings.retry_substeps=[]"]  # fmt: skip


def _build(sweep: Path):
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]), HYDRA_FULL_ERROR="1")
    return subprocess.run([sys.executable, "-m", "drapebench.data.reference_jobs", *TINY, "hydra/launcher=submitit_local",
                           f"hydra.sweep.dir={sweep}"], cwd=sweep.parent, env=env, capture_output=True, text=True, timeout=900)  # fmt: skip


def _results(sweep: Path) -> dict[str, dict]:
    return {p.parent.name: json.loads(p.read_text()) for p in sorted(sweep.glob("*/result.json"))}


@pytest.mark.slow  # about 3 min on 2 busy cores (three commands, two submitit jobs, two short Newton simulations)
def test_a_reference_set_builds_as_one_submitit_job_per_sequence_and_resumes_after_a_lost_job(tmp_path):
    p = _build(tmp_path / "first")
    assert p.returncode == 0, p.stderr[-3000:]
    assert "reference set tiny (skirt): 2 sequences planned, 0 done, 0 failed, 2 to simulate" in p.stdout
    assert "reference set tiny (skirt, vbd): 2 ok / 0 failed of 2 sequences" in p.stdout
    first = _results(tmp_path / "first")
    assert sorted(first) == ["0_sequence0", "1_sequence1"] and not any(r["from_cache"] for r in first.values())
    assert len([d for d in (tmp_path / "first" / ".submitit").iterdir() if d.name != "%j"]) == 2  # one submitit job each
    kept, lost = Path(first["0_sequence0"]["path"]), Path(first["1_sequence1"]["path"])
    kept_mtime = kept.stat().st_mtime_ns
    lost.unlink()  # the job of sequence 1 was killed before its drape was written
    p = _build(tmp_path / "second")
    assert p.returncode == 0, p.stderr[-3000:]
    assert "2 sequences planned, 1 done, 0 failed, 1 to simulate" in p.stdout and "2 ok / 0 failed of 2 sequences" in p.stdout
    second = _results(tmp_path / "second")
    assert list(second) == ["0_sequence1"] and second["0_sequence1"]["path"] == str(lost) and lost.exists()
    assert kept.stat().st_mtime_ns == kept_mtime  # the finished sequence was not simulated again
    p = _build(tmp_path / "third")
    assert p.returncode == 0 and "2 done, 0 failed, 0 to simulate" in p.stdout and not (tmp_path / "third").exists()


@pytest.mark.parametrize("override, says", [
    ("data=paperr", "reference_jobs: In 'reference_jobs': Could not find 'data/paperr'\n\nAvailable options in 'data':"),
    ("data.n_jbs=2", "Could not override 'data.n_jbs'.\nTo append to your config use +data.n_jbs=2 (Key 'n_jbs' is not in struct)"),
])  # fmt: skip
def test_an_override_it_cannot_compose_stops_with_hydra_s_message_not_a_traceback(override, says):
    from drapebench.data.reference_jobs import main

    with pytest.raises(SystemExit) as stop:
        main([override])
    assert str(stop.value.code).startswith("reference_jobs: ") and says in str(stop.value.code)
    assert "Config search path" not in str(stop.value.code)
