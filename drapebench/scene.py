"""The scene of a run: the one place a config becomes the body, material, test sequence, garment, reference drape,
training data, dtype and device. The experiment (``run.py``), :func:`drapebench.trained_run.load_run`, the export and
the diagnose scripts all build it here, so a reloaded run is the run (a ``dtype=float64`` run is float64 again)."""

from __future__ import annotations

import logging
from dataclasses import dataclass
from functools import cache

import torch
from omegaconf import DictConfig, OmegaConf

from drapebench.schema import choice

log = logging.getLogger("drapebench")


def config_dtype(cfg: DictConfig) -> torch.dtype:
    """The torch dtype a config's ``dtype`` names (a Precision member once validated by the schema, or its name)."""
    return getattr(torch, choice(cfg.dtype))


@dataclass
class Scene:
    """cfg: the resolved config; body (``drapebench.body.BodyModel``) in the run's dtype on its device; material
    (``drapebench.physics.Material``); seq: the test ``BodySequence``; garment (``drapebench.garments.Garment``), its topology in
    the run's dtype (its vertices stay the float32 record)."""

    cfg: DictConfig
    body: object
    material: object
    seq: object
    garment: object

    @property
    def dtype(self) -> torch.dtype:
        return self.body.dtype

    @property
    def device(self) -> torch.device:
        return self.body.device

    @classmethod
    def from_config(cls, cfg: DictConfig, device: str | torch.device | None = None) -> Scene:
        """The scene ``cfg`` describes (``body``, ``material``, ``motion``, ``garment``, ``dtype``; ``device`` unless
        given here). Raises ValueError for a motion whose float32 positions lie too far from the origin
        (:func:`drapebench.metrics.check_near_origin`; float64 runs without a reference solver are measured anywhere)
        and for any bad motion or garment key (naming the key)."""
        from drapebench.body import load_body
        from drapebench.body.motion_source import sequence_from_config
        from drapebench.garments import garment_from_config
        from drapebench.metrics import check_near_origin
        from drapebench.physics import Material

        dtype = config_dtype(cfg)
        body = load_body(cfg.body.name, dtype=dtype, device=cfg.device if device is None else device)
        material = Material.from_config(OmegaConf.to_container(cfg.material, resolve=True))
        seq = sequence_from_config(OmegaConf.to_container(cfg.motion, resolve=True), body)
        if dtype != torch.float64 or cfg.reference.solver is not None:  # refused before any drape (the simulator is float32)
            check_near_origin(seq.trans, "motion's root")
        garment = garment_from_config(OmegaConf.to_container(cfg.garment, resolve=True), body, seq.betas).in_dtype(dtype)
        return cls(cfg, body, material, seq, garment)

    def reference(self) -> torch.Tensor | None:
        """The physics-based drape (T, V, 3) m of the test sequence in the garment's dtype (cached by
        ``drapebench.reference``; simulated the first time), or None when ``reference.solver`` is null."""
        ref = OmegaConf.to_container(self.cfg.reference, resolve=True)
        solver = ref.pop("solver")
        if solver is None:
            return None
        from drapebench.reference import simulate_record

        rec = simulate_record(self.garment, self.seq, self.body, self.material, solver, force=bool(self.cfg.force), **ref)
        log.info("reference %s: %s", solver, f"loaded from {rec.path}" if rec.from_cache else f"simulated in {rec.sim_s:.1f} s")
        return rec.vertices.to(self.garment.vertices.dtype)

    def train_data(self, method, body=None):
        """The :class:`drapebench.data.TrainData` ``method`` trains on, read the first time training asks for it: the
        reference set of ``cfg.data`` (simulated on the scene's body) when the method declares ``needs_reference``
        (supervised on reference drapes), else the sequences of ``cfg.train.dataset``. ``body``: the body the method
        trains on (the scene's body on the run's device; default the scene's body)."""
        from drapebench.data import H5Sequences, References, TrainData

        cfg = self.cfg
        common = dict(body=self.body if body is None else body, material=self.material, garment=self.garment, test_sequences=[self.seq])
        if not method.needs_reference:
            from drapebench.body.dataset import build_dataset

            return TrainData(**common, load_train=lambda: H5Sequences(build_dataset(cfg.train.dataset, force=cfg.force)))
        from drapebench.data.reference_set import load_reference_set

        @cache
        def reference_set():
            refs = load_reference_set(cfg.data, self.garment, self.body, self.material, force=bool(cfg.force))
            log.info("%s", refs.summary())
            return refs

        return TrainData(**common, load_train=lambda: reference_set().sequences,
                         references=References(lambda g, s: reference_set().references().get(g, s)))  # fmt: skip
