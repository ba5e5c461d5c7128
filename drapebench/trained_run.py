"""A finished run's trained method, scene and reference again, for diagnostics that look inside a run
(``python -m methods.vae.diagnose``, ``python -m methods.gaps.diagnose --run``)."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import torch
from omegaconf import DictConfig, OmegaConf


@dataclass
class TrainedRun:
    """cfg: the run's resolved config; method: its trained method, bound to the run's body and material;
    garment and seq: the run's garment and test sequence."""

    cfg: DictConfig
    method: object
    body: object
    material: object
    garment: object
    seq: object

    def reference(self) -> torch.Tensor | None:
        """The run's reference drape (T, V, 3) m (from the cache, or simulated), None without a reference solver."""
        from drapebench.experiment import _reference

        return _reference(self.cfg, self.garment, self.seq, self.body, self.material)


def load_run(run_dir: str | Path) -> TrainedRun:
    """The :class:`TrainedRun` of the run folder ``run_dir`` (its ``config.yaml`` and ``metrics.json``). Raises
    FileNotFoundError when the run's checkpoint is no longer in the cache (rerun the run to train it again)."""
    import methods
    from drapebench.body import load_body
    from drapebench.body.motion_source import sequence_from_config
    from drapebench.garments import garment_from_config
    from drapebench.physics import Material

    run_dir = Path(run_dir)
    cfg = OmegaConf.load(run_dir / "config.yaml")
    ckpt = json.loads((run_dir / "metrics.json").read_text()).get("checkpoint")
    if ckpt and not Path(ckpt).exists():
        raise FileNotFoundError(f"{run_dir}: its checkpoint {ckpt!r} is not in the cache; rerun the run to train it again")
    body = load_body(cfg.body.name)
    material = Material.from_config(OmegaConf.to_container(cfg.material, resolve=True))
    seq = sequence_from_config(OmegaConf.to_container(cfg.motion, resolve=True), body)
    garment = garment_from_config(OmegaConf.to_container(cfg.garment, resolve=True), body, seq.betas)
    method = methods.get(cfg.method.impl)(OmegaConf.to_container(cfg.method.params, resolve=True))
    method.bind(body, material)
    if ckpt:  # a method with nothing to learn (lbs, an optimum row) has no checkpoint
        method.load_state_dict(torch.load(ckpt, map_location="cpu", weights_only=False)["method"])
    return TrainedRun(cfg, method, body, material, garment, seq)
