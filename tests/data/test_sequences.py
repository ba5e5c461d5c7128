"""H5Sequences: a dataset file read lazily, in load_dataset's order, with shared reads across subsets."""

import h5py
import pytest
import torch

import drapebench.data.sequences as sequences
from drapebench.body.dataset import DatasetSpec, build_dataset, load_dataset
from drapebench.data import H5Sequences

TINY = DatasetSpec(("walk", "kick"), per_motion=2, n_frames=8, split="train", seed=3, transition=2)


@pytest.fixture
def opens(monkeypatch):
    """Count the h5 files opened (h5py.File is patched where H5Sequences finds it, i.e. everywhere)."""
    calls = []
    real = h5py.File

    def spy(*args, **kwargs):
        calls.append(args[0])
        return real(*args, **kwargs)

    monkeypatch.setattr(sequences.h5py, "File", spy)
    return calls


def test_nothing_is_read_until_asked_and_each_sequence_once(tmp_path, opens):
    path = build_dataset(TINY, path=tmp_path / "d.h5")
    opens.clear()
    built = []
    seqs = H5Sequences(lambda: built.append(1) or path)
    assert built == [] and opens == []  # the source is not asked for and no file is opened
    assert seqs.motions == ["kick", "kick", "walk", "walk"] and seqs.n_frames == [10] * 4 and len(seqs) == 4
    assert built == [1] and len(opens) == 1  # the index: names, motions and shapes in one read
    first = seqs[0]
    assert len(opens) == 2 and seqs[0] is first and len(opens) == 2  # a sequence is read once
    reference = load_dataset(tmp_path / "d.h5")
    assert seqs.names == [s.name for s in reference]
    assert all(torch.equal(a.poses, b.poses) and torch.equal(a.betas, b.betas) for a, b in zip(seqs, reference))


def test_a_subset_shares_the_file_and_the_reads(tmp_path, opens):
    seqs = H5Sequences(build_dataset(TINY, path=tmp_path / "d.h5"))
    opens.clear()
    sub = seqs.subset([3, 1])
    assert sub.names == [seqs.names[3], seqs.names[1]] and sub.motions == ["walk", "kick"]
    assert len(opens) == 1 and sub[1] is seqs[1] and len(opens) == 2


def test_an_incomplete_file_is_refused(tmp_path):
    path = build_dataset(TINY, path=tmp_path / "d.h5")
    with h5py.File(path, "a") as f:
        f.attrs["complete"] = False
    with pytest.raises(ValueError, match="incomplete; rebuild it"):
        H5Sequences(path).names
