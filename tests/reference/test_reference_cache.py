"""Reference cache, start-state checks and the pbs method, with the Newton run replaced by a stub (fast)."""

import dataclasses
import time

import numpy as np
import pytest
import torch

import drapebench.reference.simulator as sim
from drapebench.body import make_sequence
from drapebench.garments import make_garment
from drapebench.physics import Material
from drapebench.reference import SimulationDiverged, simulate, simulate_record


@pytest.fixture(scope="module")
def scene(body_lowres):
    return make_garment("skirt", body_lowres, resolution=0.03), make_sequence("walk", 6, transition=2, seed=3)


@pytest.fixture
def stub(monkeypatch, tmp_path):
    """Replace the Newton run by a deterministic fake that counts calls; cache in tmp_path."""
    monkeypatch.setenv("DRAPEBENCH_DATA", str(tmp_path))
    calls = []

    def fake_run(garment, seq, body, material, settings, show_progress):
        calls.append(settings)
        if settings.max_speed < 1.0:
            raise SimulationDiverged(garment.name, seq.name, 3, seq.n_frames, "test blow-up", settings)
        x = garment.vertices.numpy()[None].repeat(seq.n_frames, 0) + 1e-3 * np.arange(seq.n_frames)[:, None, None]
        return x.astype(np.float32), {"setup": 1.0, "settle": 2.0, "sequence": 3.0}, {"max_speed": 0.1}

    monkeypatch.setattr(sim, "_run", fake_run)
    return calls


def test_second_call_loads_from_cache_with_the_original_timings(scene, body_lowres, stub, tmp_path):
    g, seq = scene
    a = simulate_record(g, seq, body_lowres, Material(), progress=False)
    t = time.perf_counter()
    b = simulate_record(g, seq, body_lowres, Material(), progress=False)
    assert time.perf_counter() - t < 1.0
    assert len(stub) == 1 and not a.from_cache and b.from_cache
    assert b.sim_s == pytest.approx(6.0) and b.timings_s == a.timings_s
    assert torch.equal(a.vertices, b.vertices) and b.vertices.dtype == torch.float32
    assert simulate(g, seq, body_lowres, progress=False, dtype=torch.float64).dtype == torch.float64
    files = list((tmp_path / "cache" / "reference").glob("*.npz"))
    assert len(files) == 1 and files[0].name.startswith("skirt_walk_s3_vbd_")


def test_cache_key_follows_material_solver_and_settings(scene, body_lowres, stub):
    g, seq = scene
    simulate(g, seq, body_lowres, Material(), progress=False)
    simulate(g, seq, body_lowres, Material().with_(friction=0.2), progress=False)
    simulate(g, seq, body_lowres, Material(), solver="style3d", progress=False)
    simulate(g, seq, body_lowres, Material(), substeps=3, progress=False)
    simulate(g, seq, body_lowres, Material(), progress=False, cache=False)
    assert len(stub) == 5
    simulate(g, seq, body_lowres, Material(), substeps=3, progress=False)
    assert len(stub) == 5


def test_a_diverged_run_caches_no_drape_and_its_recorded_failure_is_raised_at_once_until_forced(scene, body_lowres, stub, tmp_path):
    g, seq = scene
    with pytest.raises(SimulationDiverged, match=r"'skirt'.*frame 3 of 8.*substeps=") as err:
        simulate(g, seq, body_lowres, progress=False, max_speed=0.5)
    assert err.value.frame == 3 and err.value.garment == "skirt"
    cache = tmp_path / "cache" / "reference"
    assert not list(cache.glob("*.npz")) and len(list(cache.glob("*.failed.json"))) == 1
    runs = len(stub)
    with pytest.raises(SimulationDiverged) as again:
        simulate(g, seq, body_lowres, progress=False, max_speed=0.5)
    assert len(stub) == runs and str(again.value) == str(err.value) and again.value.attempts == err.value.attempts
    with pytest.raises(SimulationDiverged):
        simulate_record(g, seq, body_lowres, progress=False, max_speed=0.5, force=True)
    assert len(stub) > runs  # force runs it again
    simulate(g, seq, body_lowres, progress=False, max_speed=0.6 + 0.5)  # other settings: another key, simulated
    next(cache.glob("*.failed.json")).write_text("{not json")
    runs = len(stub)
    with pytest.raises(SimulationDiverged):  # an unreadable record is dropped and the simulation runs
        simulate(g, seq, body_lowres, progress=False, max_speed=0.5)
    assert len(stub) > runs


def test_garment_inside_the_body_is_rejected(scene, body_lowres, monkeypatch, tmp_path):
    monkeypatch.setenv("DRAPEBENCH_DATA", str(tmp_path))
    g, seq = scene
    centre = g.vertices.mean(0)
    shrunk = centre + (g.vertices - centre) * torch.tensor([0.5, 0.5, 1.0])
    with pytest.raises(ValueError, match=r"garment 'skirt' starts inside the body: \d+ of"):
        simulate(dataclasses.replace(g, vertices=shrunk), seq, body_lowres, progress=False)
    assert not list((tmp_path / "cache" / "reference").glob("*"))


def test_pbs_method_reports_the_original_simulation_time(scene, body_lowres, stub):
    import methods

    g, seq = scene
    m = methods.get("pbs")({"solver": "vbd"})
    assert m.generic and not m.needs_reference
    m.bind(body_lowres, Material())
    first, second = m.drape(g, seq), m.drape(g, seq)
    assert first.vertices.shape == (seq.n_frames, g.n_vertices, 3)
    assert first.timings_ms == {"simulate": pytest.approx(6000.0)}
    assert second.timings_ms["simulate"] == pytest.approx(6000.0) and "cache_load" in second.timings_ms
    with pytest.raises(ValueError, match="unknown reference setting"):
        methods.get("pbs")({"solver": "vbd", "substep": 2})


def test_diverged_error_survives_pickling_for_parallel_sweeps(scene, body_lowres):
    import pickle

    from drapebench.errors import DrapeFailed
    from drapebench.reference import SimSettings

    g, seq = scene
    err = SimulationDiverged(g.name, seq.name, 5, seq.n_frames, "12 vertices became NaN/Inf", SimSettings.for_solver("vbd"))
    back = pickle.loads(pickle.dumps(err))
    assert type(back) is SimulationDiverged and isinstance(back, DrapeFailed)
    assert str(back) == str(err) and back.frame == 5 and back.garment == g.name


def test_force_makes_the_pbs_method_simulate_again_once(scene, body_lowres, stub):
    """``force=true`` of a run (drapebench.cache.forcing) reaches the cached reference the pbs method reads."""
    import methods
    from drapebench.cache import forcing

    g, seq = scene
    m = methods.get("pbs")({"solver": "vbd"})
    m.bind(body_lowres, Material())
    m.drape(g, seq)
    assert len(stub) == 1
    with forcing():
        forced, again = m.drape(g, seq), m.drape(g, seq)
    assert len(stub) == 2, "force=true read the cached reference (or simulated it twice)"
    assert "cache_load" not in forced.timings_ms and "cache_load" in again.timings_ms


SIGNED_DISTANCE = ("import torch; from drapebench.body import load_body; from drapebench.geometry.sdf import signed_distance; "
                   "b = load_body('anny_lowres'); signed_distance(torch.zeros(1, 2, 3), b.shaped()[0], b.faces)")  # fmt: skip


@pytest.mark.parametrize("code", ["import drapebench.reference.scene", SIGNED_DISTANCE], ids=["simulator", "metrics"])
def test_warp_prints_no_cuda_warning_without_cuda(code):
    import subprocess
    import sys

    from drapebench.warp_env import cuda_driver_present

    if cuda_driver_present():
        pytest.skip("this machine has a CUDA driver: warp's messages are kept there")
    code += "; import warp as wp; assert wp.get_cuda_device_count() == 0"
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    assert "CUDA" not in p.stderr and "CUDA" not in p.stdout, p.stderr


def test_cache_key_follows_the_sequences_body_shape(scene, body_lowres, stub):
    g, seq = scene
    other = make_sequence("walk", 6, transition=2, seed=3, betas=[1.0, -1.0])
    assert other.name == seq.name and torch.equal(other.poses, seq.poses)  # only the body shape differs
    simulate(g, seq, body_lowres, Material(), progress=False)
    simulate(g, other, body_lowres, Material(), progress=False)
    assert len(stub) == 2
