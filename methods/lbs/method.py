"""LBS baseline: each garment vertex copies the skinning weights and the shape blend shape of its
nearest body vertex on the canonical body (what SNUG does before its network), then follows the
sequence's joint transforms. The zero point every paper compares against."""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Iterator

import torch

from drapebench.body.lbs import LBS_CHUNK, lbs
from drapebench.body.skinning import nearest_body_vertices, nearest_weights, transfer_shape
from drapebench.progress import progress
from methods.base import DrapeResult, DrapingMethod, FitReport
from methods.params import typed_params


@dataclass(frozen=True)
class NoParams:
    """LBS's parameters: none."""


class LBSMethod(DrapingMethod):
    """Nearest-body-vertex skinning of the template (no learning, no collision handling)."""

    name = "lbs"
    generic = True
    needs_reference = False

    def __init__(self, cfg=None) -> None:
        """``cfg`` must be empty: LBS has no parameters (ValueError naming any key given)."""
        typed_params(NoParams, cfg, "lbs")
        super().__init__(cfg)

    def fit(self, data, train_cfg=None) -> FitReport:
        """Nothing to learn: binds the body and material."""
        self.bind(data.body, data.material)
        return FitReport()

    def drape(self, garment, seq) -> DrapeResult:
        """(T, V, 3): template + body shape offset (seq betas - garment betas) at the nearest vertex, skinned."""
        return DrapeResult.joined(self.drape_chunks(garment, seq), seq.n_frames)

    def drape_chunks(self, garment, seq, chunk_frames: int = LBS_CHUNK) -> Iterator[DrapeResult]:
        """The drape (:meth:`drape`) ``chunk_frames`` frames at a time, each chunk's joint transforms computed for
        its frames only (:meth:`drapebench.body.BodySequence.frame_transforms`): nothing of the size of the sequence
        is held but its poses. Timings: the nearest-vertex search in the first chunk's."""
        self._require_bound()
        ms = lambda a, b: (b - a) * 1e3  # noqa: E731
        t0 = time.perf_counter()
        idx = nearest_body_vertices(garment.vertices, self.body, garment.betas)
        t1 = time.perf_counter()
        with torch.no_grad():
            rest = transfer_shape(garment.vertices.to(self.body.dtype), idx, self.body, garment.betas, seq.betas)
            t2 = time.perf_counter()
            weights = nearest_weights(idx, self.body)
        timings = {"weights": ms(t0, t1), "body": ms(t1, t2), "skinning": ms(t2, time.perf_counter())}
        for a in progress(range(0, seq.n_frames, chunk_frames), desc="lbs drape", unit="chunk"):
            t0 = time.perf_counter()
            with torch.no_grad():
                transforms = seq.frame_transforms(self.body, a, a + chunk_frames)
                t1 = time.perf_counter()
                x = lbs(rest, weights, transforms)
            timings["body"] += ms(t0, t1)
            timings["skinning"] += ms(t1, time.perf_counter())
            yield DrapeResult(x, timings)
            timings = dict.fromkeys(timings, 0.0)  # each chunk its own share: the one-off stages counted once
