"""Reference training sets: the plan, resuming an interrupted build, failures recorded and never cached (the Newton
run replaced by a counting fake), and one short real simulation through the whole path."""

import numpy as np
import pytest
import torch
import yaml

import drapebench.reference.simulator as sim
from drapebench.body.dataset import HELD_OUT_MOTIONS, spec_sequences
from drapebench.cache import PROJECT_ROOT
from drapebench.data.reference_set import ReferenceSetSpec, build_reference_set, collect_reference_set, load_reference_set
from drapebench.garments import make_garment
from drapebench.physics import Material
from drapebench.reference import SimulationDiverged, reference_path

SPEC = ReferenceSetSpec(name="test", motions=("random", "walk"), per_motion=2, n_frames=3, transition=2, seed=7,
                        settings={"settle_frames": 0, "retry_substeps": []})  # fmt: skip


@pytest.fixture(scope="module")
def garment(body_lowres):
    return make_garment("skirt", body_lowres, resolution=0.03)


def test_the_plan_is_deterministic_in_the_seed_and_keeps_the_test_motions_out():
    a, b = spec_sequences(SPEC.dataset_spec()), spec_sequences(SPEC.dataset_spec())
    assert [s.motion for s in a] == ["random", "random", "walk", "walk"]
    assert all(torch.equal(x.poses, y.poses) and torch.equal(x.betas, y.betas) for x, y in zip(a, b))
    assert len({tuple(s.betas[:4].tolist()) for s in a}) == 4 and all(s.betas[4:].abs().sum() == 0 for s in a)
    other = spec_sequences(ReferenceSetSpec(**{**SPEC.__dict__, "seed": 8}).dataset_spec())
    assert not torch.equal(other[0].betas, a[0].betas) and not torch.equal(other[0].poses, a[0].poses)
    with pytest.raises(ValueError, match=r"held-out test motion\(s\) \['kick'\].*allow_held_out"):
        ReferenceSetSpec(motions=("walk", "kick"))
    assert ReferenceSetSpec(motions=("walk", "kick"), allow_held_out=True).motions == ("walk", "kick")
    vae_tests = yaml.safe_load((PROJECT_ROOT / "conf/experiment/vae_table1.yaml").read_text())["hydra"]["sweeper"]["params"]["motion"]
    for name in ("cpu", "paper"):  # the VAE trains on these sets and is tested on vae_table1's motions (squat too)
        spec = ReferenceSetSpec.preset(name)
        assert spec.name == name and "random" in spec.motions and not set(spec.motions) & set(HELD_OUT_MOTIONS)
        assert not set(spec.motions) & set(vae_tests.split(",")), f"data={name} trains on a motion vae_table1 tests on"


@pytest.fixture
def fake_run(monkeypatch, tmp_path):
    """Newton replaced by a drape that moves each vertex by the sequence's first shape coefficient x 1 mm per
    frame; it fails on train_random_001 and is interrupted (once) on train_walk_000. Returns the calls."""
    monkeypatch.setenv("DRAPEBENCH_DATA", str(tmp_path))
    calls = []

    def run(garment, seq, body, material, settings, show_progress):
        calls.append(seq.name)
        if seq.name == "train_random_001":
            raise SimulationDiverged(garment.name, seq.name, 1, seq.n_frames, "test blow-up", settings)
        if seq.name == "train_walk_000" and calls.count(seq.name) == 1:
            raise KeyboardInterrupt
        x = garment.vertices.numpy()[None] + 1e-3 * float(seq.betas[0]) * np.arange(seq.n_frames)[:, None, None]
        return x.astype(np.float32), {"setup": 1.0, "settle": 0.0, "sequence": 2.0}, {"max_speed": 0.1}

    monkeypatch.setattr(sim, "_run", run)
    return calls


def test_an_interrupted_build_resumes_and_a_failure_is_recorded_not_cached(garment, body_lowres, fake_run):
    with pytest.raises(KeyboardInterrupt):
        build_reference_set(garment, body_lowres, Material(), SPEC, progress=False)
    assert fake_run == ["train_random_000", "train_random_001", "train_walk_000"]
    refs = build_reference_set(garment, body_lowres, Material(), SPEC, progress=False)
    assert fake_run[3:] == ["train_walk_000", "train_walk_001"]  # neither the finished nor the failed one again
    assert len(refs) == 3 and [s.name for s in refs.sequences] == ["train_random_000", "train_walk_000", "train_walk_001"]
    assert [(f["garment"], f["sequence"], f["error"]) for f in refs.failed] == [("skirt", "train_random_001", "SimulationDiverged")]
    assert "test blow-up" in refs.failed[0]["cause"]
    failed_seq = [s for s in refs.planned if s.name == "train_random_001"][0]
    failed_path = reference_path(garment, failed_seq, body_lowres, Material(), "vbd", **SPEC.settings)
    assert not failed_path.exists()
    for seq, x in refs:
        expected = garment.vertices[None] + 1e-3 * float(seq.betas[0]) * torch.arange(seq.n_frames)[:, None, None]
        assert x.dtype == torch.float32 and torch.allclose(x, expected.float(), atol=1e-6)
        assert refs.references().get(garment, seq).shape == x.shape
    assert refs.sim_s == pytest.approx(9.0)
    assert refs.summary().startswith("reference set test (skirt, vbd): 3 ok / 1 failed of 4 sequences, 15 frames")
    again = load_reference_set({**SPEC.__dict__, "motions": list(SPEC.motions)}, garment, body_lowres, Material(), progress=False)
    assert len(fake_run) == 5 and len(again) == 3 and len(again.failed) == 1
    build_reference_set(garment, body_lowres, Material(), SPEC, progress=False, force=True)
    assert len(fake_run) == 9 and not failed_path.exists()


def test_the_cache_says_what_is_done_failed_and_missing_without_simulating(garment, body_lowres, fake_run):
    refs, missing = collect_reference_set(garment, body_lowres, Material(), SPEC)
    assert len(refs) == 0 and not refs.failed and [s.name for s in missing] == [s.name for s in refs.planned] and len(missing) == 4
    with pytest.raises(KeyboardInterrupt):  # done: random_000; diverged: random_001; interrupted at walk_000
        build_reference_set(garment, body_lowres, Material(), SPEC, progress=False)
    refs, missing = collect_reference_set(garment, body_lowres, Material(), SPEC)
    assert len(fake_run) == 3  # collecting simulates nothing
    assert [s.name for s in refs.sequences] == ["train_random_000"] and refs.sim_s == pytest.approx(3.0)
    assert [(f["sequence"], f["error"]) for f in refs.failed] == [("train_random_001", "SimulationDiverged")]
    assert "test blow-up" in refs.failed[0]["cause"]
    assert [s.name for s in missing] == ["train_walk_000", "train_walk_001"]


def test_unknown_keys_are_named():
    with pytest.raises(ValueError, match=r"unknown reference set key\(s\) \['frames'\]"):
        ReferenceSetSpec.from_config({"frames": 3})
    with pytest.raises(KeyError, match="presets: cpu, paper"):
        ReferenceSetSpec.preset("huge")


def test_a_short_real_simulation_through_newton(garment, body_lowres, monkeypatch, tmp_path):
    """A few frames of vbd on the low-res body: the Newton path and its failure checks run on every submission."""
    monkeypatch.setenv("DRAPEBENCH_DATA", str(tmp_path))
    spec = ReferenceSetSpec(name="real", motions=("walk",), n_frames=2, transition=1, beta_sigma=0.3,
                            settings={"settle_frames": 1, "substeps": 2, "iterations": 3, "retry_substeps": []})  # fmt: skip
    refs = build_reference_set(garment, body_lowres, Material(), spec, progress=False)
    assert len(refs) == 1 and not refs.failed
    seq, x = refs[0]
    assert x.shape == (3, garment.n_vertices, 3) and torch.isfinite(x).all()
    step = (x[1:] - x[:-1]).norm(dim=-1)
    assert float(step.max()) > 0 and float(step.max()) < 0.1  # it moved, and by less than 10 cm a frame


def test_a_failed_sequence_is_replaced_by_a_new_draw_of_its_motion_and_each_failure_recorded(garment, body_lowres, monkeypatch, tmp_path):
    """A failed place of the plan goes to ``<name>_r1``, ``_r2``... (same motion and shape, another seed) until one
    succeeds or ``replace_failed`` tries are spent; a rebuild and the cache's account find the same set."""
    monkeypatch.setenv("DRAPEBENCH_DATA", str(tmp_path))
    calls = []

    def run(garment, seq, body, material, settings, show_progress):
        calls.append(seq.name)
        if seq.name in ("train_random_001", "train_random_001_r1"):
            raise SimulationDiverged(garment.name, seq.name, 1, seq.n_frames, "test blow-up", settings)
        x = garment.vertices.numpy()[None] + 1e-3 * float(seq.poses[-1].abs().sum()) * np.arange(seq.n_frames)[:, None, None]
        return x.astype(np.float32), {"setup": 1.0, "settle": 0.0, "sequence": 2.0}, {"max_speed": 0.1}

    monkeypatch.setattr(sim, "_run", run)
    spec = ReferenceSetSpec(**{**SPEC.__dict__, "replace_failed": 2})
    refs = build_reference_set(garment, body_lowres, Material(), spec, progress=False)
    names = ["train_random_000", "train_random_001_r2", "train_walk_000", "train_walk_001"]
    assert [s.name for s in refs.sequences] == names and len(refs) == 4
    assert [f["sequence"] for f in refs.failed] == ["train_random_001", "train_random_001_r1"]
    original, replaced = [s for s in spec_sequences(SPEC.dataset_spec()) if s.name == "train_random_001"][0], refs.sequences[1]
    assert replaced.motion == original.motion and torch.equal(replaced.betas, original.betas)
    assert replaced.poses.shape == original.poses.shape and not torch.equal(replaced.poses, original.poses)
    n_calls = len(calls)
    again = build_reference_set(garment, body_lowres, Material(), spec, progress=False)
    assert len(calls) == n_calls and [s.name for s in again.sequences] == names  # cached drapes, recorded failures
    cached, missing = collect_reference_set(garment, body_lowres, Material(), spec)
    assert not missing and [s.name for s in cached.sequences] == names and len(cached.failed) == 2
    one_try = build_reference_set(garment, body_lowres, Material(), ReferenceSetSpec(**{**SPEC.__dict__, "replace_failed": 1}), progress=False)
    assert len(one_try) == 3 and [f["sequence"] for f in one_try.failed] == ["train_random_001", "train_random_001_r1"]
    with pytest.raises(ValueError, match="data.replace_failed must be >= 0"):
        ReferenceSetSpec(replace_failed=-1)


@pytest.mark.parametrize("argv, says", [
    (["--jobs", "0"], "--jobs: at least 1 worker process, got 0"),  # was read as the preset's
    (["--jobs", "-2"], "--jobs: at least 1 worker process, got -2"),  # joblib's "every core but one"
    (["--data", "paperr", "--garment", "tshrt"], "--data paperr: unknown reference set preset 'paperr'"),  # before the garment
    (["--material", "coton"], "--material coton: unknown material 'coton'"),
    (["--body", "annny"], "--body annny: body 'annny' is neither a shipped body"),
    (["--garment", "tshrt", "--body", "anny_lowres"], "--garment tshrt: unknown garment kind 'tshrt'"),
])  # fmt: skip
def test_the_build_command_refuses_a_bad_argument_before_any_simulation(argv, says, capsys, monkeypatch):
    from drapebench.data import reference_set

    monkeypatch.setattr(reference_set, "build_reference_set", lambda *a, **k: pytest.fail("simulated on a bad argument"))
    with pytest.raises(SystemExit) as stop:
        reference_set.main(argv)
    assert stop.value.code == 2 and says in capsys.readouterr().err


def test_a_build_with_no_worker_process_is_refused(garment, body_lowres, fake_run):
    with pytest.raises(ValueError, match="n_jobs: at least 1 worker process, got 0"):
        build_reference_set(garment, body_lowres, Material(), SPEC, n_jobs=0, progress=False)
    assert fake_run == []
