"""TrainData: lazy sequences, one or many garments, held-out motions, windows, reference drapes."""

from types import SimpleNamespace

import h5py
import numpy as np
import pytest
import torch

import drapebench.reference
from drapebench.body.dataset import DatasetSpec, build_dataset
from drapebench.data import H5Sequences, References, TrainData, Windows
from drapebench.results import write_prediction

TINY = DatasetSpec(("walk", "kick"), per_motion=2, n_frames=8, split="train", seed=3, transition=2)


def _garment(name, n_vertices=4):
    return SimpleNamespace(name=name, n_vertices=n_vertices)


def _seq(name, n_frames=3, motion="walk"):
    return SimpleNamespace(name=name, n_frames=n_frames, motion=motion)


def test_sequences_load_once_lazily_and_are_shared_by_garment_views():
    calls = []
    seqs = [_seq("a"), _seq("b", 5)]
    data = TrainData(None, None, garments=[_garment("tshirt"), _garment("skirt")],
                     load_train=lambda: calls.append("train") or seqs, load_val=lambda: calls.append("val") or seqs[:1])  # fmt: skip
    assert calls == []
    view = data.for_garment(data.garments[1])
    assert view.garment.name == "skirt" and view.train_sequences == seqs and data.train_sequences == seqs
    assert data.val_sequences == seqs[:1] and view.val_sequences == seqs[:1]
    assert calls == ["train", "val"]


def test_garment_is_the_single_one_and_an_error_otherwise():
    g = _garment("tshirt")
    assert TrainData(None, None, g).garment is g and TrainData(None, None, g).garments == [g]
    with pytest.raises(ValueError, match=r"holds 2 garments \(tshirt, skirt\); train once per garment"):
        TrainData(None, None, garments=[g, _garment("skirt")]).garment
    with pytest.raises(ValueError, match="holds 0 garments"):
        TrainData(None, None).garment
    with pytest.raises(ValueError, match="not both"):
        TrainData(None, None, g, garments=[g])


def test_the_dataset_file_is_not_read_until_asked(tmp_path, monkeypatch):
    path = build_dataset(TINY, path=tmp_path / "d.h5")
    opened = []
    real = h5py.File
    monkeypatch.setattr(h5py, "File", lambda *a, **k: opened.append(a[0]) or real(*a, **k))
    data = TrainData(None, None, _garment("tshirt"), load_train=lambda: H5Sequences(path))
    assert opened == []
    w = data.windows(3, first=1)
    assert len(opened) == 1 and not data.train_source._shared["loaded"]  # the index only, no poses
    assert np.array_equal(w.index, Windows.over([10] * 4, 3, first=1).index)
    assert [s.n_frames for s in data.train_sequences] == [10] * 4 and len(opened) == 5


def test_a_held_out_motion_in_the_training_set_is_an_error(tmp_path):
    path = build_dataset(TINY, path=tmp_path / "d.h5")
    data = TrainData(None, None, _garment("tshirt"), load_train=lambda: H5Sequences(path), held_out_motions=("kick",))
    with pytest.raises(ValueError, match=r"kick \(2 sequences\) appear in the training set"):
        data.train_sequences
    data = TrainData(None, None, _garment("tshirt"), load_train=lambda: [_seq("a", motion="random")], held_out_motions=("kick",))
    assert len(data.train_sequences) == 1


def test_reference_files_are_read_on_first_use_and_checked(tmp_path):
    g, walk, kick, other = _garment("tshirt"), _seq("walk_0"), _seq("kick_0"), _seq("other")
    drape = torch.rand(3, 4, 3)
    write_prediction(tmp_path / "walk.h5", drape, torch.tensor([[0, 1, 2]]))
    np.savez(tmp_path / "kick.npz", vertices=2 * drape.numpy())
    refs = References.from_files({("tshirt", "walk_0"): tmp_path / "walk.h5", ("tshirt", "kick_0"): tmp_path / "kick.npz"})
    data = TrainData(None, None, g, references=refs)
    assert torch.equal(data.reference(g, walk), drape) and torch.equal(data.reference(g, kick), 2 * drape)
    assert data.reference(g, other) is None and TrainData(None, None, g).reference(g, walk) is None
    (tmp_path / "walk.h5").unlink()
    assert torch.equal(data.reference(g, walk), drape)  # kept after the first read
    with pytest.raises(ValueError, match=r"shape \(3, 4, 3\), expected \(5, 4, 3\)"):
        References.from_files({("tshirt", "long"): tmp_path / "kick.npz"}).get(g, _seq("long", 5))
    with pytest.raises(ValueError, match="NaN or Inf"):
        References(lambda g_, s_: torch.full((3, 4, 3), float("nan"))).get(g, walk)


def test_simulated_references_come_from_the_reference_module(monkeypatch):
    calls = []

    def fake(garment, seq, body, material, solver, **kw):
        calls.append((garment.name, seq.name, body, material, solver, kw))
        return SimpleNamespace(vertices=torch.zeros(seq.n_frames, garment.n_vertices, 3))

    monkeypatch.setattr(drapebench.reference, "simulate_record", fake)
    refs = References.from_simulator("body", "cotton", "style3d", substeps=4)
    g, s = _garment("skirt"), _seq("walk_0")
    assert calls == [] and refs.get(g, s).shape == (3, 4, 3) and refs.get(g, s).shape == (3, 4, 3)
    assert calls == [("skirt", "walk_0", "body", "cotton", "style3d", {"progress": False, "substeps": 4})]
