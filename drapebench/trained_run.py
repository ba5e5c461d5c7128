"""A finished run's trained method on its scene again, for diagnostics that look inside a run
(``python -m methods.<name>.diagnose``)."""

from __future__ import annotations

import json
from dataclasses import dataclass, fields
from pathlib import Path

import torch
from omegaconf import OmegaConf

from drapebench.scene import Scene


@dataclass
class TrainedRun(Scene):
    """The run's :class:`drapebench.scene.Scene` (its config, body, material, garment, test sequence; its reference
    and training data) and ``method``: its trained method, bound to the run's body and material."""

    method: object = None


def load_run(run_dir: str | Path, device: str | torch.device | None = None) -> TrainedRun:
    """The :class:`TrainedRun` of the run folder ``run_dir`` (its ``config.yaml`` and ``metrics.json``), built as the
    run built it (:meth:`Scene.from_config`: the run's dtype; the run's device unless ``device`` is given). A
    relative checkpoint path (an archived run's) is read under :func:`drapebench.cache.data_dir`. Raises
    FileNotFoundError when the run's checkpoint is no longer in the cache, and ValueError when the checkpoint there
    is another model than the run's (trained again since, at another commit or for another time: the cache keeps
    one model per configuration); rerun the run to get its model back. FileNotFoundError too when ``run_dir`` is
    not a finished run's folder."""
    from drapebench.cache import data_dir
    from drapebench.experiment import method_class

    run_dir = Path(run_dir)
    missing = [f for f in ("config.yaml", "metrics.json") if not (run_dir / f).is_file()]
    if missing:
        raise FileNotFoundError(f"{run_dir} has no {' or '.join(missing)}: give a finished run's folder"
                                + (" (a sweep's runs are its job folders)" if run_dir.is_dir() else ""))  # fmt: skip
    cfg = OmegaConf.load(run_dir / "config.yaml")
    metrics = json.loads((run_dir / "metrics.json").read_text())
    ckpt = metrics.get("checkpoint")
    if ckpt and not Path(ckpt).is_absolute():
        ckpt = str(data_dir() / ckpt)
    if ckpt and not Path(ckpt).exists():
        raise FileNotFoundError(f"{run_dir}: its checkpoint {ckpt!r} is not in the cache; rerun the run to train it again")
    state = torch.load(ckpt, map_location="cpu", weights_only=False) if ckpt else None
    if state is not None:
        ran = (metrics.get("trained_at"), metrics.get("train_s"))
        now = (state.get("commit", "unrecorded"), state.get("train_s"))
        if ran[0] is not None and ran != now:
            raise ValueError(f"{run_dir}: the cached checkpoint {ckpt!r} is another model than the run's (trained at {now[0]} in "
                             f"{now[1]} s; the run's: at {ran[0]} in {ran[1]} s); rerun the run to load or train its model again")
    scene = Scene.from_config(cfg, device=device)
    method = method_class(cfg)(OmegaConf.to_container(cfg.method.params, resolve=True))
    method.bind(scene.body, scene.material)
    if state is not None:  # a method with nothing to learn (a skinning, an optimum row) has no checkpoint
        method.load_state_dict(state["method"])
    return TrainedRun(**{f.name: getattr(scene, f.name) for f in fields(Scene)}, method=method)
