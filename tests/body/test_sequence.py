import h5py
import torch

from drapebench.body import BodySequence, make_sequence
from drapebench.body.dataset import DATASETS, DatasetSpec, build_dataset, load_dataset


def test_h5_round_trip_is_exact(tmp_path):
    seq = make_sequence("dance", 40, seed=7, betas=torch.randn(10), amplitude=0.8)
    seq.save(tmp_path / "s.h5")
    back = BodySequence.load(tmp_path / "s.h5")
    for key in ("betas", "poses", "trans"):
        assert torch.equal(getattr(seq, key), getattr(back, key))
    assert (back.name, back.motion, back.fps, back.seed, back.n_transition, back.params) == (
        seq.name, seq.motion, seq.fps, seq.seed, seq.n_transition, seq.params)  # fmt: skip


def test_posed_geometry_is_cached_and_consistent(body_lowres):
    seq = make_sequence("walk", 20, seed=0)
    v = seq.vertices(body_lowres)
    assert v.shape == (seq.n_frames, body_lowres.n_vertices, 3)
    assert seq.vertices(body_lowres) is v
    n = seq.vertex_normals(body_lowres)
    assert torch.allclose(n.norm(dim=-1), torch.ones(()), atol=1e-4)
    assert seq.transforms(body_lowres).shape == (seq.n_frames, 22, 4, 4)
    part = seq.slice(5, 15)
    assert torch.allclose(part.vertices(body_lowres), v[5:15], atol=1e-6)


def test_dataset_build_is_skipped_when_identical(tmp_path):
    spec = DatasetSpec(("walk", "kick"), per_motion=2, n_frames=10, split="test", seed=4)
    path = build_dataset(spec, path=tmp_path / "d.h5")
    mtime = path.stat().st_mtime_ns
    assert build_dataset(spec, path=tmp_path / "d.h5").stat().st_mtime_ns == mtime
    assert build_dataset(spec, force=True, path=tmp_path / "d.h5").stat().st_mtime_ns != mtime
    seqs = load_dataset(path)
    assert [s.motion for s in seqs].count("kick") == 2
    assert len({tuple(s.betas.tolist()) for s in seqs}) == 4  # random body shapes
    assert all(s.betas[4:].abs().max() == 0 and s.betas.abs().max() <= spec.beta_clip for s in seqs)


def test_corrupt_or_incomplete_dataset_is_rebuilt(tmp_path):
    spec = DatasetSpec(("walk",), per_motion=1, n_frames=5, split="train")
    path = tmp_path / "d.h5"
    path.write_bytes(b"not an h5 file")
    build_dataset(spec, path=path)
    assert len(load_dataset(path)) == 1
    with h5py.File(path, "a") as f:
        f.attrs["complete"] = False
    mtime = path.stat().st_mtime_ns
    assert build_dataset(spec, path=path).stat().st_mtime_ns != mtime


def test_training_sets_hold_out_motion_kinds():
    held_out = {"kick", "stress"}
    for name, spec in DATASETS.items():
        if spec.split == "train":
            assert not held_out & set(spec.motions), name
