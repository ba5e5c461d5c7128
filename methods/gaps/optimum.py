"""``gaps_optimum``: the drape that minimises GAPS's own training loss directly over the garment vertices,
frame by frame, with no network (:mod:`drapebench.optimum`): the best any network trained on this loss
could do per frame. Nothing is learned."""

from __future__ import annotations

import logging
import time

import numpy as np
import torch

from drapebench.optimum import optimise_sequence
from methods.base import DrapeResult, DrapingMethod, FitReport
from methods.gaps.config import optimum_params
from methods.gaps.method import GAPS

log = logging.getLogger("drapebench")


class GapsOptimum(GAPS):
    """GAPS's loss minimised per frame from its untrained skinning (network output zero). ``cfg``: GAPS's
    parameters (the loss and the skinning) plus ``optimum``, the solver settings
    (:class:`methods.gaps.config.GapsOptimumSettings`)."""

    name = "gaps_optimum"
    learns = False  # solved per frame: nothing trained
    displaced_from = ("start",)  # the optimum's move from the untrained skinning

    def __init__(self, cfg=None):
        cfg = dict(cfg or {})
        self.o = optimum_params(cfg.pop("optimum", {}))  # absent: the defaults; null: refused
        super().__init__(cfg)

    def fit(self, data, train_cfg=None) -> FitReport:
        """Nothing to learn: binds the body and material."""
        self.bind(data.body, data.material)
        return FitReport()

    def kext_epoch(self) -> int:
        """The training epoch whose k_ext the loss uses: ``optimum.kext_epoch``, else the end of the ramp."""
        return self.p["train"]["kext_ramp_epochs"] if self.o["kext_epoch"] is None else int(self.o["kext_epoch"])

    def drape(self, garment, seq) -> DrapeResult:
        """(T, V, 3) the optimum of GAPS's loss per frame (``extras["start"]``: the untrained skinning it starts from)."""
        self._require_bound()
        t0 = time.perf_counter()
        self._setup(garment)
        t1 = time.perf_counter()
        start = self.untrained_drape(seq)
        t2 = time.perf_counter()
        o = self.o
        res = optimise_sequence(self.window_loss(seq, self.kext_epoch()), start, self.p["train"]["window"], o["solver"],
                                o["iterations"], o["lr"], o["history"])  # fmt: skip
        t3 = time.perf_counter()
        total = lambda terms: np.mean([sum(t.values()) for t in terms])  # noqa: E731
        log.info("gaps_optimum: loss per window %.4g at the untrained skinning -> %.4g (mean over %d frames, %.1f evaluations each)",
                 total(res.start_terms), total(res.final_terms), seq.n_frames, np.mean(res.evaluations))  # fmt: skip
        ms = lambda a, b: (b - a) * 1e3  # noqa: E731
        return DrapeResult(res.vertices, {"setup": ms(t0, t1), "skinning": ms(t1, t2), "optimum": ms(t2, t3)}, {"start": start})

    def scored_variants(self, seq, result: DrapeResult) -> dict:
        """GAPS's untrained skinning (network output zero) the optimum starts from, "untrained" (T, V, 3) m."""
        return {"untrained": result.extras["start"]}

    state_dict = DrapingMethod.state_dict  # nothing learned: no checkpoint
    load_state_dict = DrapingMethod.load_state_dict
