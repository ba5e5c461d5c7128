"""device=cuda for the learned methods (issue 60): each one fits, drapes and reloads its checkpoint on the run's
device, none of its code creates a tensor without naming a device, and none uses a CPU record (garment, body
sequence, reference drape) on the device without moving it (:mod:`tests.devices`), so the same test finds on the CPU
what would break a CUDA run. Parametrised over the devices torch sees (cuda on a GPU machine:
``benchmarks/gpu_check.sh``)."""

import io

import pytest
import torch

import methods
from drapebench.body import load_body, make_sequence
from drapebench.data import TrainData
from drapebench.garments import make_garment
from drapebench.physics import Material
from tests.devices import StrayTensors, device_params, host

QUICK = {"batch_size": 2, "log_every": 1, "checkpoint_every": 1000}


@pytest.fixture(autouse=True)
def _data_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("DRAPEBENCH_DATA", str(tmp_path))  # training checkpoints and cached training frames


def _reloaded(method, cfg, body, garment, test, **fields):
    """The drape of ``test`` by a fresh ``method.name`` of ``cfg`` bound to ``body`` and loaded from ``method``'s state
    as a checkpoint is (saved, read onto the CPU); ``fields`` are set on it first (stand-in body fields)."""
    buf = io.BytesIO()
    torch.save(method.state_dict(), buf)
    buf.seek(0)
    again = methods.get(method.name)(cfg)
    again.__dict__.update(fields)
    again.bind(body, Material())
    again.load_state_dict(torch.load(buf, map_location="cpu", weights_only=False))
    return again.drape(garment, test)


def _on(device: str, result, method) -> None:
    """The drape is finite and on ``device``, and so is every parameter of the method's networks."""
    assert result.vertices.device.type == device and torch.isfinite(result.vertices).all()
    nets = [n for n in (getattr(method, k, None) for k in ("net", "vae", "regressor", "pose")) if isinstance(n, torch.nn.Module)]
    assert nets and all(t.device.type == device for n in nets for t in [*n.parameters(), *n.buffers()])


@device_params
def test_gaps_trains_and_drapes_on_the_run_device(device, body_lowres):
    body = load_body("anny_lowres", device=device)
    garment = host(make_garment("skirt", body_lowres, resolution=0.03))  # a scene's garment is made on the CPU
    seqs, test = [host(make_sequence("walk", 8, seed=s, transition=2)) for s in range(2)], host(make_sequence("kick", 5, seed=0, transition=2))
    cfg = {"collision_postprocess": True, "train": {"window": 3}}
    m = methods.get("gaps")(cfg)
    with StrayTensors() as stray:
        m.fit(TrainData(body=body, material=Material(), garment=garment, load_train=lambda: seqs), {**QUICK, "steps": 2, "seed": 0})
        out = m.drape(garment, test)
        m.scored_variants(test, out)
        again = _reloaded(m, cfg, body, garment, test)
    assert not stray.sites, "tensors off the run's device:\n" + "\n".join(stray.sites)
    _on(device, out, m)
    torch.testing.assert_close(again.vertices, out.vertices)  # a checkpoint read onto the CPU drapes on the device


GENSIM = {"latent": 16, "geometry": 8, "steps": 2, "fabric_mean": 1e-3, "fabric_std": 2e-3, "arap_steps": 3,
          "train": {"garments": [["skirt", {}]], "seeds": [1], "resolutions": [0.03], "sequences": 1, "n_frames": 12, "frames_per_sequence": 2}}  # fmt: skip


@device_params
def test_gensim_trains_and_drapes_on_the_run_device(device, body_lowres):
    body = load_body("anny_lowres", device=device)
    garment, test = host(make_garment("shorts", body_lowres, resolution=0.025)), host(make_sequence("kick", 3, seed=0, transition=2))
    m = methods.get("gensim")(GENSIM)
    with StrayTensors() as stray:
        m.fit(TrainData(body=body, material=Material()), {**QUICK, "steps": 2, "seed": 0})
        out = m.drape(garment, test)
        m.diagnostics(garment, test, out)
        again = _reloaded(m, GENSIM, body, garment, test)
    assert not stray.sites, "tensors off the run's device:\n" + "\n".join(stray.sites)
    _on(device, out, m)
    torch.testing.assert_close(again.vertices, out.vertices)  # a checkpoint read onto the CPU drapes on the device
    assert out.extras["arap"].device.type == device


@device_params
def test_vae_trains_and_drapes_on_the_run_device(device, body_lowres):
    from drapebench.data import References
    from tests.methods.test_vae import TINY, NearestDiffused, SphereSDF, _tiny_model, _tiny_scene

    body = load_body("anny_lowres", device=device)
    garment, cpu_data, _, seqs = _tiny_scene(body_lowres)  # the scene and its reference drapes are CPU records
    garment, seqs = host(garment), [host(s) for s in seqs]
    references = References(lambda g, s: host(cpu_data.references.get(g, s)))
    data = TrainData(body, Material(), garment, load_train=lambda: seqs, references=references)
    sdf = SphereSDF(c=(5.0, 5.0, 5.0), r=0.1)
    sdf.c = sdf.c.to(device)  # the stand-in fields on the run's device, as _body_fields puts the fitted ones
    cfg = {**TINY, "regressor": {**TINY["regressor"], "pose": "learned"}}
    m = _tiny_model(body, NearestDiffused(body), sdf, cfg)
    test = host(make_sequence("kick", 6, seed=9, transition=2))
    with StrayTensors() as stray:
        m.fit(data, {"seed": 0})
        out = m.drape(garment, test)
        m.diagnostics(garment, test, out)
        again = _reloaded(m, cfg, body, garment, test, diffused=m.diffused, sdf=m.sdf)
    assert not stray.sites, "tensors off the run's device:\n" + "\n".join(stray.sites)
    _on(device, out, m)
    torch.testing.assert_close(again.vertices, out.vertices)  # a checkpoint read onto the CPU drapes on the device
