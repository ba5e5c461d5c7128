"""``gensim_optimum``: the drape that minimises GenSim's own training loss (Eq. 9, the configured reading)
directly, frame by frame from the ARAP stage, with no network (:mod:`drapebench.optimum`): the best PEN
could reach on each frame. ``optimum.space`` "vertices" (default) minimises over the free vertices, Eq. 1's
half-space not imposed, so it bounds PEN from below; "half_space" over PEN's output space, displacements
scale x [a^2 n + b t1 + c t2] in the local frame of the body normal n PEN sees (every displacement with a
non-negative part along n, as Eq. 1 allows). Nothing is learned."""

from __future__ import annotations

import logging
import time

import numpy as np
import torch

from drapebench.optimum import optimise_sequence
from methods.base import DrapeResult, FitReport
from methods.gensim.config import optimum_params
from methods.gensim.method import GenSim, garment_graph
from methods.gensim.network import local_frame_displacement

log = logging.getLogger("drapebench")

HALF_SPACE_START = 0.1  # a at the start of the half-space optimum: a^2 x magnitude_scale = 0.1 mm along n (a^2's gradient is 0 at a = 0)


class GensimOptimum(GenSim):
    """GenSim's loss minimised per frame from its ARAP stage. ``cfg``: GenSim's parameters (the loss, the ARAP
    stage, mu_fabric / sigma_fabric) plus ``optimum``, the solver settings (:class:`methods.gensim.config.GensimOptimumSettings`)."""

    name = "gensim_optimum"
    learns = False  # solved per frame: nothing trained

    def __init__(self, cfg=None):
        cfg = dict(cfg or {})
        self.o = optimum_params(cfg.pop("optimum", None))
        super().__init__(cfg)

    def fit(self, data, train_cfg=None) -> FitReport:
        """Nothing to learn: binds the body and material and reads mu_fabric / sigma_fabric."""
        self.bind(data.body, data.material)
        self.fabric = self._fabric()
        return FitReport()

    def drape(self, garment, seq) -> DrapeResult:
        """(T, V, 3) the optimum of Eq. 9 per frame; ``extras["arap"]``: the ARAP stage it starts from (world
        frame, as GenSim's), so PEN's statistics measure the optimum's displacement."""
        self._require_bound()
        if self.fabric is None:
            raise RuntimeError("gensim_optimum: call fit() first (it reads mu_fabric and sigma_fabric)")
        t0 = time.perf_counter()
        graph = garment_graph(garment, self.body, self.material)
        t1 = time.perf_counter()
        G, H, _, verts, normals, _ = self.arap_stage(graph, self.sequence_shape(seq), seq.poses)
        t2 = time.perf_counter()

        o = self.o
        drape_of = self._half_space_drape(graph, G, verts, normals) if o["space"] == "half_space" else lambda t, x: x

        def loss(t: int, window: torch.Tensor):
            terms = self.terms(graph, drape_of(t, window[-1:]), G[t : t + 1], verts[t : t + 1], normals[t : t + 1])
            return sum(terms.values()), terms

        start = G if o["space"] == "vertices" else torch.zeros_like(G).index_fill_(-1, torch.tensor([0]), HALF_SPACE_START)
        res = optimise_sequence(loss, start, 1, o["solver"], o["iterations"], o["lr"], o["history"])
        if o["space"] == "half_space":
            res.vertices = torch.cat([drape_of(t, res.vertices[t : t + 1]) for t in range(len(G))]).detach()
        t3 = time.perf_counter()
        total = lambda terms: np.mean([sum(t.values()) for t in terms])  # noqa: E731
        log.info("gensim_optimum: loss per frame %.4g at the ARAP stage -> %.4g (mean over %d frames, %.1f evaluations each)",
                 total(res.start_terms), total(res.final_terms), seq.n_frames, np.mean(res.evaluations))  # fmt: skip
        x, G = self.to_world(seq, res.vertices, G)
        ms = lambda a, b: (b - a) * 1e3  # noqa: E731
        return DrapeResult(x, {"setup": ms(t0, t1), "arap": ms(t1, t2), "optimum": ms(t2, t3)}, {"arap": G, "handles": H})

    def _half_space_drape(self, graph, G, verts, normals):
        """(t, coefficients (1, V, 3) [a, b, c]) -> frame t's drape (1, V, 3) m: G[t] moved by PEN's decoder form
        ``magnitude_scale`` x [a^2 n + b t1 + c t2] with n the body normal PEN sees at G (Eq. 1's half-space)."""
        _, body_normal = self.body_query(G, verts, normals)
        scale = self.p["magnitude_scale"]

        def drape_of(t: int, c: torch.Tensor) -> torch.Tensor:
            return G[t : t + 1] + local_frame_displacement(c[..., 0], c[..., 1], c[..., 2], body_normal[t : t + 1], scale, normal_part="square")

        return drape_of
