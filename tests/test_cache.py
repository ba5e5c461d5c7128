"""The cache API: every kind of cache file, truncated or with one byte flipped, is rebuilt with a
warning naming it, never loaded; ``forcing`` rebuilds each entry once."""

import logging
import os
from types import SimpleNamespace

import numpy as np
import pytest
import torch
from omegaconf import OmegaConf

from drapebench.cache import Cache, forcing


@pytest.fixture(autouse=True)
def _own_data_dir(monkeypatch, tmp_path):
    monkeypatch.setenv("DRAPEBENCH_DATA", str(tmp_path))


def _truncate(path):
    path.write_bytes(path.read_bytes()[: os.path.getsize(path) // 2])


def _flip(path):
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0x01
    path.write_bytes(bytes(data))


def test_session_data_dir_is_not_the_projects(monkeypatch):
    from drapebench.cache import PROJECT_ROOT, data_dir

    monkeypatch.undo()  # the session-wide directory from conftest, not this module's
    assert not data_dir().resolve().is_relative_to(PROJECT_ROOT.resolve())


def _entry(tmp_path):
    cache = Cache("unit", 1)
    path = cache.path("a", np.arange(3))
    built = []

    def get(**kw):
        return cache.get_or_build(path, lambda: built.append(1) or {"x": np.arange(5)}, _pickle_write, _pickle_read, **kw)

    return cache, path, built, get


def _pickle_write(value, p):
    import pickle

    with open(p, "wb") as f:
        pickle.dump(value, f)


def _pickle_read(p):
    import pickle

    with open(p, "rb") as f:
        return pickle.load(f)


def test_key_follows_version_and_content():
    a = Cache("unit", 1)
    assert a.path(np.zeros(3)) == a.path(np.zeros(3))
    assert a.path(np.zeros(3)) != a.path(np.ones(3))
    assert a.path(np.zeros(3)) != Cache("unit", 2).path(np.zeros(3))


@pytest.mark.parametrize("damage", [_truncate, _flip, lambda p: p.with_name(p.name + ".sha256").unlink()])
def test_damaged_or_unsealed_entry_is_rebuilt_with_a_warning(damage, tmp_path, caplog):
    cache, path, built, get = _entry(tmp_path)
    first = get()
    assert get() is not first and len(built) == 1  # loaded, not rebuilt
    damage(path)
    with caplog.at_level(logging.WARNING, logger="drapebench.cache"):
        again = get()
    assert len(built) == 2 and np.array_equal(again["x"], first["x"])
    assert str(path) in caplog.text and "rebuilding" in caplog.text
    get()
    assert len(built) == 2  # the rebuilt entry is sealed again


def test_forcing_rebuilds_each_entry_once_and_force_always(tmp_path):
    cache, path, built, get = _entry(tmp_path)
    get()
    with forcing():
        get()
        get()
    assert len(built) == 2
    with forcing(False):
        get()
    get(force=True)
    assert len(built) == 3



def _slow_build(path: str, log: str) -> None:
    """A process asking for the entry ``path``, whose build takes 1 s and appends a line to ``log``."""
    import time

    def build():
        with open(log, "a") as f:
            f.write("built\n")
        time.sleep(1.0)
        return {"x": np.arange(3)}

    value = Cache("lockdemo", 1).get_or_build(path, build, _pickle_write, _pickle_read)
    assert value["x"].tolist() == [0, 1, 2]


def test_two_processes_asking_for_one_missing_entry_build_it_once(tmp_path):
    """Two reproduce workers once relaxed the same GAPS canonical garment side by side (about 30 s each)."""
    import multiprocessing

    path, log = str(tmp_path / "entry.pkl"), str(tmp_path / "builds.txt")
    ctx = multiprocessing.get_context("spawn")
    workers = [ctx.Process(target=_slow_build, args=(path, log)) for _ in range(2)]
    for w in workers:
        w.start()
    for w in workers:
        w.join(60)
    assert [w.exitcode for w in workers] == [0, 0]
    assert open(log).read() == "built\n"

# ---- every kind of cache file in the suite, through its real code path ------------------------------


def _counting(monkeypatch, module, name):
    calls = []
    fn = getattr(module, name)
    monkeypatch.setattr(module, name, lambda *a, **k: calls.append(1) or fn(*a, **k))
    return calls


def _topology(monkeypatch, body):
    import drapebench.geometry.topology as topo

    calls = _counting(monkeypatch, topo, "build_topology_arrays")
    x = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0.2]], float)
    f = np.array([[0, 1, 2], [1, 3, 2]])

    def call():
        topo._MEMORY.clear()
        return topo.get_topology(x, f).vertex_areas

    return "topology", calls, call


def _sdf(monkeypatch, body):
    import drapebench.garments.fields as fields

    calls = _counting(monkeypatch, fields, "_exact_sdf")
    V = np.array([[0, 0, 0], [0.1, 0, 0], [0, 0.1, 0], [0, 0, 0.1]], float)
    F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    return "sdf", calls, lambda: fields.signed_distance_grid(V, F, 0.02, levels=2)[1]


_BUILT: dict = {}


def _garment(monkeypatch, body):
    """The garment cache around a construction that is computed once per session (a real build costs seconds)."""
    import drapebench.garments.factory as factory

    calls, build = [], factory._build

    def memo_build(*args):
        calls.append(1)
        if "skirt" not in _BUILT:
            _BUILT["skirt"] = build(*args)
        return _BUILT["skirt"]

    monkeypatch.setattr(factory, "_build", memo_build)
    return "garments", calls, lambda: factory.make_garment("skirt", body, resolution=0.03).vertices


def _reference(monkeypatch, body):
    import drapebench.reference.simulator as sim
    from drapebench.body import make_sequence
    from drapebench.physics import Material

    calls = []

    def fake_run(garment, seq, body, material, settings, show_progress):
        calls.append(1)
        x = garment.vertices.numpy()[None].repeat(seq.n_frames, 0)
        return x.astype(np.float32), {"sequence": 1.0}, {"max_speed": 0.1}

    monkeypatch.setattr(sim, "_run", fake_run)
    from drapebench.geometry import get_topology

    v, f = torch.rand(5, 3), torch.tensor([[0, 1, 2], [2, 3, 4]])
    g = SimpleNamespace(name="patch", vertices=v, faces=f, pins=torch.zeros(0, dtype=torch.long), betas=torch.zeros(10),
                        n_vertices=5, topology=get_topology(v.numpy(), f.numpy(), cache=False))  # fmt: skip
    seq = make_sequence("walk", 3, transition=1, seed=3)
    return "reference", calls, lambda: sim.simulate_record(g, seq, body, Material(), progress=False).vertices


def _dataset(monkeypatch, body):
    import drapebench.body.dataset as ds

    calls = _counting(monkeypatch, ds, "spec_sequences")
    spec = ds.DatasetSpec(("walk",), per_motion=1, n_frames=3, split="train", transition=1)
    return "datasets", calls, lambda: torch.as_tensor(ds.load_dataset(ds.build_dataset(spec))[0].poses)


def _fake_evaluate(garment, seq, body, prediction, **kw):
    import pandas as pd

    return {"eps_c": float(prediction.sum())}, pd.DataFrame({"frame": np.arange(len(prediction))})


def _evaluation(monkeypatch, body):
    import drapebench.metrics
    from drapebench.experiment import _evaluate

    calls = []
    monkeypatch.setattr(drapebench.metrics, "evaluate", lambda *a, **k: calls.append(1) or _fake_evaluate(*a, **k))
    cfg = OmegaConf.create({"force": False, "chunk_frames": 64, "eval": {"skip_transition": True, "energies": False}})
    g = SimpleNamespace(kind="skirt", vertices=torch.zeros(3, 3), faces=torch.zeros(1, 3, dtype=torch.long))
    seq = SimpleNamespace(name="walk", betas=np.zeros(4), poses=np.zeros((2, 3)), trans=np.zeros((2, 3)), n_transition=0)
    pred = torch.ones(2, 3, 3)
    return "evaluations", calls, lambda: torch.tensor(_evaluate(cfg, g, seq, body, pred, None, None)[0]["eps_c"])


class _Method:
    generic = False
    needs_reference = False

    def __init__(self, calls):
        self.calls, self.w = calls, None

    def fit(self, data, train_cfg):
        self.calls.append(1)
        self.w = torch.arange(4.0)
        from methods.base import FitReport

        return FitReport(train_s=1.0)

    def settings_key(self):
        return None

    def trained_body(self, run_body):
        return run_body

    def state_dict(self):
        return {"w": self.w}

    def bind(self, body, material):
        pass

    def load_state_dict(self, state):
        self.w = state["w"]


def _checkpoint(monkeypatch, body):
    from drapebench.experiment import _checkpoint

    calls = []
    cfg = OmegaConf.create({"force": False, "method": {"name": "fake", "impl": "lbs"}, "material": {"density": 0.2}})
    g = SimpleNamespace(vertices=torch.zeros(3, 3), faces=torch.zeros(1, 3, dtype=torch.long))
    data = SimpleNamespace(body=body, material=None)

    def call():
        m = _Method(calls)
        _checkpoint(m, cfg, g, data, {"steps": 1})
        return m.w

    return "checkpoints", calls, call


KINDS = [_topology, _sdf, _garment, _reference, _dataset, _evaluation, _checkpoint]


@pytest.mark.parametrize("damage", [_truncate, _flip], ids=["truncated", "flipped"])
@pytest.mark.parametrize("kind", KINDS, ids=[k.__name__[1:] for k in KINDS])
def test_every_cache_kind_rebuilds_a_damaged_file(kind, damage, body_lowres, monkeypatch, tmp_path, caplog):
    folder, calls, call = kind(monkeypatch, body_lowres)
    first = call()
    n = len(calls)
    assert n >= 1
    assert torch.equal(torch.as_tensor(call()), torch.as_tensor(first)) and len(calls) == n  # loaded from the cache
    root = tmp_path / "datasets" if folder == "datasets" else tmp_path / "cache" / folder
    (path,) = [p for p in root.iterdir() if not p.name.endswith(".sha256")]
    damage(path)
    with caplog.at_level(logging.WARNING):
        again = call()
    assert len(calls) > n, "a damaged cache file was loaded"
    assert torch.equal(torch.as_tensor(again), torch.as_tensor(first))
    assert str(path) in caplog.text
    n = len(calls)
    call()
    assert len(calls) == n  # the rebuilt file is valid again


def test_key_follows_an_arrays_dtype_and_shape_not_only_its_bytes():
    from drapebench.cache import content_hash

    a = np.zeros((2, 3))
    assert content_hash(a) != content_hash(a.reshape(3, 2))
    assert content_hash(a) != content_hash(np.zeros(12, dtype=np.float32))  # the same 48 zero bytes


def test_key_does_not_depend_on_dict_insertion_order():
    from drapebench.cache import content_hash

    a = {"lr": 1e-3, "steps": 10, "nested": {"a": 1, "b": [1, 2]}}
    b = {"nested": {"b": [1, 2], "a": 1}, "steps": 10, "lr": 1e-3}
    assert content_hash(a) == content_hash(b) != content_hash({**a, "steps": 11})


def test_body_key_follows_every_array_of_the_body_including_its_pose_blend_shapes():
    from drapebench.cache import body_key

    def body(posedirs):
        return SimpleNamespace(v_template=torch.zeros(4, 3), shapedirs=torch.zeros(4, 3, 2), J_regressor=torch.eye(4)[:2],
                               weights=torch.full((4, 2), 0.5), faces=torch.tensor([[0, 1, 2]]), parents=[-1, 0], posedirs=posedirs)

    a, b, c = body(torch.zeros(9, 12)), body(torch.ones(9, 12)), body(torch.zeros(9, 12))
    assert body_key(a) != body_key(b) and body_key(a) == body_key(c)
