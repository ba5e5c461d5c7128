"""Pin vertices for GenSim: the garment's own pins, or a ring found where it rests on the body.

GenSim needs pins (paper Eq. 5-6: without them gravity pulls the garment off). A garment without pins
(e.g. a user's OBJ) gets the vertices of its top band (the highest ``band`` metres) that lie closest to
the canonical body: the waistband of a skirt or pants, the shoulders of a top.
"""

from __future__ import annotations

import logging

import torch
from scipy.spatial import cKDTree

MIN_PINS = 3


def auto_pins(template: torch.Tensor, canonical_body: torch.Tensor, band: float = 0.25, share: float = 0.2) -> torch.Tensor:
    """(P,) long: among the template vertices (V, 3) m within ``band`` m of the garment's top, the ``share``
    closest to the canonical body vertices (Vb, 3)."""
    z = template[:, 2]
    top = torch.nonzero(z >= z.max() - band).squeeze(1)
    d, _ = cKDTree(canonical_body.detach().double().numpy()).query(template[top].detach().double().numpy(), workers=1)
    d = torch.as_tensor(d)
    keep = d <= torch.quantile(d, share)
    return top[keep]


def garment_pins(garment, body) -> torch.Tensor:
    """The garment's pins, or :func:`auto_pins` (logged) when it has none; raises ValueError naming the fix
    when fewer than :data:`MIN_PINS` are found."""
    if garment.pins.numel() >= MIN_PINS:
        return garment.pins.long()
    with torch.no_grad():
        canonical = body.shaped(garment.betas[None, : body.n_betas].to(body.dtype))[0][0]
    pins = auto_pins(garment.vertices.to(body.dtype), canonical)
    if len(pins) < MIN_PINS:
        raise ValueError(f"gensim needs pin vertices and found {len(pins)} on garment {garment.name!r}: give them with "
                         "load_garment(..., pins=[vertex indices]) (the waistband or the shoulders)")  # fmt: skip
    logging.getLogger("drapebench").info("gensim: garment %r has no pins; using %d vertices of its top band closest to the body",
                                         garment.name, len(pins))  # fmt: skip
    return pins
