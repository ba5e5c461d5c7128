"""Golden drapes: every method's drape of one small scene, stored once (tests/fixtures/golden_drapes.npz) and compared by
tests/test_golden_drapes.py, so a change meant to leave the methods alone (a refactor) is seen to leave their output
alone.

The scene: the skirt at 3 cm on anny_lowres, a 6-frame kick (8 frames with its transition). Each method is built from
its ``method.params`` as Hydra composes ``conf/`` for ``method=<name>`` (the runs' configuration) with only its sizes,
iterations and training budget shrunk, trained for a few steps on three 8-frame motions (seeded, float32, one thread)
and draped. The VAE's diffused body and body SDF are the stand-ins of tests/methods/test_vae.py (fitting the real ones
takes minutes) and its references are the LBS drape with a ripple. pbs simulates 2 settling frames at 2 substeps of 2 iterations.

Regenerate (when a method's output is meant to change), from the repository root:
``python -m tests.golden_drapes`` (writes the file and records the commit it was made at).
"""

from __future__ import annotations

import os
import subprocess
import tempfile
from pathlib import Path

import numpy as np
import torch
from omegaconf import OmegaConf

ROOT = Path(__file__).resolve().parents[1]
GOLDEN = ROOT / "tests" / "fixtures" / "golden_drapes.npz"


def _schedule(**budget) -> dict:
    """A whole training schedule (every key of conf/train's budget that a method's ``schedule`` may set): given whole, a
    method's schedule is the same whether a partial one would be merged over its default or replace it."""
    whole = {"epochs": 1, "steps": None, "batch_size": 4, "lr": 1e-3, "lr_after": None, "lr_switch_epoch": None, "lr_decay_fraction": None,
             "grad_clip": None, "ema_decay": None, "max_minutes": None, "checkpoint_every": 1000}  # fmt: skip
    return {**whole, **budget}


# each method: (what its params are shrunk to, its training budget)
GAPS = {"hidden": 16, "layers": 1, "relax_iterations": 5, "train": {"redraw_motions": False, "schedule": _schedule(steps=6)}}
OPTIMUM = {"optimum": {"iterations": 3}}
SHRUNK = {
    "lbs": ({}, None),
    "pbs": ({"settle_frames": 2, "substeps": 2, "iterations": 2, "cache": False}, None),
    "gaps": (GAPS, {"seed": 0, "log_every": 1}),
    "gaps_optimum": ({**GAPS, **OPTIMUM}, None),
    "gensim": ({"latent": 16, "geometry": 8, "steps": 2, "arap_steps": 3,
                "train": {"garments": [["skirt", {}]], "seeds": [1], "resolutions": [0.03], "sequences": 1, "n_frames": 20,
                          "frames_per_sequence": 2, "schedule": _schedule(steps=3, batch_size=2)}},
               {"seed": 0}),
    "gensim_optimum": ({"arap_steps": 3, **OPTIMUM}, None),
    "vae": ({"val_sequences": 1, "projection": {"steps": 3},
             "vae": {"hidden": [16], "latent": 4, "steps": 12, "samples": 2, "schedule": _schedule()},
             "regressor": {"hidden": 8, "layers": 1, "window": 4, "pose_steps": 5, "betas": 4, "select": "last",
                           "schedule": _schedule(epochs=2)}},
            {"seed": 0}),
}  # fmt: skip


def method_config(name: str, overrides: dict) -> tuple[str, dict]:
    """(impl, params) of ``method=<name>`` as Hydra composes conf/ (the runs' defaults), ``overrides`` merged over the
    params (a plain dict)."""
    from hydra import compose, initialize_config_dir

    from drapebench.schema import register

    register()
    with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
        method = compose("config", overrides=[f"method={name}"]).method
    params = OmegaConf.create(OmegaConf.to_container(method.params, resolve=True))  # not in struct mode: overrides may add keys
    return method.impl, OmegaConf.to_container(OmegaConf.merge(params, overrides))


def scene():
    """(body, garment, test sequence, training sequences) of the small scene."""
    from drapebench.body import load_body, make_sequence
    from drapebench.garments import make_garment

    body = load_body("anny_lowres")
    garment = make_garment("skirt", body, resolution=0.03)
    test = make_sequence("kick", 6, seed=0, transition=2)
    train = [make_sequence(m, 8, seed=i, transition=2) for i, m in enumerate(["walk", "squat", "run"])]
    return body, garment, test, train


def drapes() -> dict[str, np.ndarray]:
    """{method: (T, V, 3) float32 drape in metres} of every method on :func:`scene`, built as the module docstring says
    (on one torch thread)."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        return _drapes()
    finally:
        torch.set_num_threads(threads)


def _drapes() -> dict[str, np.ndarray]:
    import methods
    from drapebench.data import References, TrainData
    from drapebench.physics import Material
    from tests.methods.test_vae import NearestDiffused, SphereSDF

    body, garment, test, train = scene()
    material = Material()
    lbs = methods.get("lbs")(method_config("lbs", {})[1])
    lbs.fit(TrainData(body=body, material=material, garment=garment))
    ripple = {}
    for s in train:
        t = torch.arange(s.n_frames, dtype=torch.float32)[:, None, None]
        ripple[s.name] = lbs.drape(garment, s).vertices + 0.003 * torch.sin(0.5 * t + 20 * garment.vertices[None, :, :1])
    data = TrainData(body=body, material=material, garment=garment, load_train=lambda: train,
                     references=References(lambda g, s: ripple.get(s.name)))  # fmt: skip
    out = {}
    for name, (overrides, budget) in SHRUNK.items():
        torch.manual_seed(0)
        impl, params = method_config(name, overrides)
        m = methods.get(impl)(params)
        if name == "vae":
            m.diffused, m.sdf = NearestDiffused(body), SphereSDF(c=(5.0, 5.0, 5.0), r=0.1)
        m.fit(data, budget)
        out[name] = m.drape(garment, test).vertices.detach().numpy().astype(np.float32)
    return out


def commit() -> str:
    """The checked-out commit (with "+dirty" when the working tree differs from it)."""
    head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True, text=True, check=True).stdout.strip()
    dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=ROOT, capture_output=True, text=True).stdout
    return head + ("+dirty" if dirty.strip() else "")


def main() -> None:
    """Write :data:`GOLDEN` (compressed; the drapes and the commit they were made at), through a temporary file."""
    with tempfile.TemporaryDirectory() as tmp:
        os.environ["DRAPEBENCH_DATA"] = tmp  # training checkpoints and caches stay out of data/
        arrays = drapes()
    fd, tmp_path = tempfile.mkstemp(suffix=".npz", dir=GOLDEN.parent)
    os.close(fd)
    np.savez_compressed(tmp_path, commit=np.array(commit()), **arrays)
    os.replace(tmp_path, GOLDEN)
    print(f"wrote {GOLDEN} ({GOLDEN.stat().st_size / 1e3:.0f} kB) at {commit()}")


if __name__ == "__main__":
    main()
