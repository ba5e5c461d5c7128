"""LBS baseline: each garment vertex copies the skinning weights and the shape blend shape of its
nearest body vertex on the canonical body (what SNUG does before its network), then follows the
sequence's joint transforms. The zero point every paper compares against."""

from __future__ import annotations

import time

import torch
from scipy.spatial import cKDTree

from drapebench.body.lbs import lbs
from methods.base import DrapeResult, DrapingMethod, FitReport


class LBSMethod(DrapingMethod):
    """Nearest-body-vertex skinning of the template (no learning, no collision handling)."""

    name = "lbs"
    generic = True
    needs_reference = False

    def fit(self, data, train_cfg=None) -> FitReport:
        """Nothing to learn: binds the body and material."""
        self.bind(data.body, data.material)
        return FitReport()

    def nearest_vertices(self, garment) -> torch.Tensor:
        """(V,) index of the nearest body vertex of each template vertex on the garment's body shape."""
        with torch.no_grad():
            rest = self.body.shaped(garment.betas[None, : self.body.n_betas])[0][0]
        _, idx = cKDTree(rest.numpy()).query(garment.vertices.numpy())
        return torch.as_tensor(idx, dtype=torch.long)

    def drape(self, garment, seq) -> DrapeResult:
        """(T, V, 3): template + body shape offset (seq betas - garment betas) at the nearest vertex, skinned."""
        self._require_bound()
        t0 = time.perf_counter()
        idx = self.nearest_vertices(garment)
        t1 = time.perf_counter()
        with torch.no_grad():
            dbeta = (seq.betas[: self.body.n_betas] - garment.betas[: self.body.n_betas]).to(self.body.dtype)
            rest = garment.vertices + torch.einsum("vcs,s->vc", self.body.shapedirs[idx][..., : dbeta.shape[0]], dbeta)
            transforms = seq.transforms(self.body)
            t2 = time.perf_counter()
            x = lbs(rest, self.body.weights[idx], transforms)
        t3 = time.perf_counter()
        ms = lambda a, b: (b - a) * 1e3  # noqa: E731
        return DrapeResult(x, {"weights": ms(t0, t1), "body": ms(t1, t2), "skinning": ms(t2, t3)})
