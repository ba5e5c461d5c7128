import h5py
import pytest

from drapebench.body import dataset as ds
from drapebench.body.dataset import DATASETS, DatasetSpec, build_dataset, load_dataset, sequence_plan

TINY = DatasetSpec(("walk", "kick"), per_motion=2, n_frames=10, split="test", seed=4, transition=5)


def test_rebuild_is_skipped_when_identical_and_forced_on_request(tmp_path):
    path = build_dataset(TINY, path=tmp_path / "d.h5")
    stat, data = path.stat(), path.read_bytes()
    assert build_dataset(TINY, path=path) == path
    assert path.stat().st_mtime_ns == stat.st_mtime_ns and path.read_bytes() == data  # untouched
    assert build_dataset(TINY, force=True, path=path).stat().st_mtime_ns != stat.st_mtime_ns
    seqs = load_dataset(path)
    assert [s.motion for s in seqs].count("kick") == 2 and all(s.n_frames == 15 for s in seqs)
    with h5py.File(path) as f:
        assert f.attrs["spec_hash"] == TINY.hash() == ds.dataset_hash(TINY) and f.attrs["complete"]
    assert ds.dataset_hash("train_small") == DATASETS["train_small"].hash()


def test_random_body_shapes_are_clipped():
    spec = DatasetSpec(("walk",), per_motion=50, n_frames=10, split="train", beta_sigma=2.0, beta_clip=1.5)
    betas = [b for *_, b in sequence_plan(spec)]
    assert len({tuple(b.tolist()) for b in betas}) > 45  # a few may clip to the same corner
    assert all(abs(b).max() <= 1.5 and not b[spec.n_shape_betas:].any() for b in betas)
    assert max(abs(b).max() for b in betas) == 1.5  # sigma 2 hits the clip


def test_changed_spec_or_generator_rebuilds(tmp_path, monkeypatch):
    path = build_dataset(TINY, path=tmp_path / "d.h5")
    mtime = path.stat().st_mtime_ns
    other = DatasetSpec(TINY.motions, per_motion=1, n_frames=10, split="test", seed=4, transition=5)
    assert other.hash() != TINY.hash()
    assert build_dataset(other, path=path).stat().st_mtime_ns != mtime
    assert len(load_dataset(path)) == 2
    old_hash = other.hash()
    monkeypatch.setattr(ds, "MOTION_VERSION", ds.MOTION_VERSION + 1)
    assert other.hash() != old_hash  # a new motion generator invalidates stored datasets


def test_corrupt_or_incomplete_dataset_is_rebuilt(tmp_path):
    spec = DatasetSpec(("walk",), per_motion=1, n_frames=5, split="train")
    path = tmp_path / "d.h5"
    path.write_bytes(b"not an h5 file")
    build_dataset(spec, path=path)
    assert len(load_dataset(path)) == 1
    with h5py.File(path, "a") as f:
        f.attrs["complete"] = False
    with pytest.raises(ValueError, match="incomplete"):
        load_dataset(path)
    mtime = path.stat().st_mtime_ns
    assert build_dataset(spec, path=path).stat().st_mtime_ns != mtime


def test_command_line_builds_once(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("DRAPEBENCH_DATA", str(tmp_path))
    monkeypatch.setitem(DATASETS, "tiny", TINY)
    ds.main(["tiny"])
    assert "built" in capsys.readouterr().out
    path = tmp_path / "datasets" / "tiny.h5"
    mtime = path.stat().st_mtime_ns
    ds.main(["tiny"])
    assert "skipped" in capsys.readouterr().out and path.stat().st_mtime_ns == mtime
    ds.main(["tiny", "--force"])
    assert "built" in capsys.readouterr().out and path.stat().st_mtime_ns != mtime
    assert [s.name for s in load_dataset("tiny")] == sorted(f"test_{m}_{k:03d}" for m in TINY.motions for k in range(2))
    ds.main(["--list"])
    assert "train_small" in capsys.readouterr().out


def test_bad_dataset_input():
    with pytest.raises(KeyError, match="known datasets: train_small"):
        build_dataset("trian_small")
    with pytest.raises(ValueError, match="valid motions"):
        DatasetSpec(("wlak",), per_motion=1, n_frames=5, split="train")


def test_registry_splits_by_motion_kind_and_seed():
    held_out = set(ds.HELD_OUT_MOTIONS)
    assert held_out == {"kick", "stress"}
    train_seeds, other_seeds = set(), set()
    for name, spec in DATASETS.items():
        seeds = {seed for _, _, seed, _ in sequence_plan(spec)}
        assert len(seeds) == len(spec.motions) * spec.per_motion, name
        if spec.split == "train":
            assert not held_out & set(spec.motions), name
            train_seeds |= seeds
        else:
            other_seeds |= seeds
    assert held_out <= {m for spec in DATASETS.values() if spec.split == "test" for m in spec.motions}
    assert not train_seeds & other_seeds


def test_random_motion_presets_leave_the_named_training_sets_alone():
    assert "random" not in ds.TRAIN_MOTIONS and DATASETS["train_small"].motions == ds.TRAIN_MOTIONS
    for name, like in (("train_random_small", "train_small"), ("train_random", "train")):
        spec, named = DATASETS[name], DATASETS[like]
        assert spec.motions == ("random",) and spec.split == "train"
        assert spec.per_motion == len(named.motions) * named.per_motion and spec.n_frames == named.n_frames
        betas = [b for *_, b in sequence_plan(spec)]
        assert len({tuple(b.tolist()) for b in betas}) == len(betas)  # a random body shape per sequence


def test_the_build_command_checks_every_name_before_building_any(monkeypatch, capsys):
    name = next(iter(ds.DATASETS))
    monkeypatch.setattr(ds, "build_dataset", lambda *a, **k: pytest.fail("built before every name was checked"))
    with pytest.raises(SystemExit) as stop:
        ds.main([name, "trian"])
    assert stop.value.code == 2 and "unknown dataset 'trian'; known datasets:" in capsys.readouterr().err
