"""Pin vertices: the band of a garment that rests on the body (a skirt's waistband, a top's shoulders).

Methods that hold a garment to the body (Tiwari et al. 2023, Eq. 5-6; the reference simulators) read
``Garment.pins``. A garment that comes without them (a user's OBJ) gets the vertices of its top band
(the highest ``band`` metres) that lie closest to the canonical body.
"""

from __future__ import annotations

import logging

import torch
from scipy.spatial import cKDTree

MIN_PINS = 3
log = logging.getLogger("drapebench")


def auto_pins(template: torch.Tensor, canonical_body: torch.Tensor, band: float = 0.25, share: float = 0.2) -> torch.Tensor:
    """(P,) long: among the template vertices (V, 3) m within ``band`` m of the garment's top, the ``share``
    closest to the canonical body vertices (Vb, 3) m."""
    z = template[:, 2]
    top = torch.nonzero(z >= z.max() - band).squeeze(1)
    # scipy's k-d tree runs on the CPU: the vertices go there once, the distances come back to the template's device
    d, _ = cKDTree(canonical_body.detach().cpu().double().numpy()).query(template[top].detach().cpu().double().numpy(), workers=1)
    d = torch.as_tensor(d, device=template.device)
    keep = d <= torch.quantile(d, share)
    return top[keep]


def find_pins(template: torch.Tensor, canonical_body: torch.Tensor, name: str) -> torch.Tensor:
    """:func:`auto_pins` of garment ``name`` (logged); raises ValueError naming the fix when fewer than
    :data:`MIN_PINS` are found."""
    pins = auto_pins(template, canonical_body)
    if len(pins) < MIN_PINS:
        raise ValueError(f"found only {len(pins)} pin vertices on garment {name!r} (at least {MIN_PINS} hold it to the body): "
                         "give them as garment.pins=[vertex indices] (run.py) or load_garment(..., pins=[...]), "
                         "e.g. the waistband or the shoulders")  # fmt: skip
    log.info("garment %r has no pins; using the %d vertices of its top band closest to the body (garment.pins=[...] to choose)",
             name, len(pins))  # fmt: skip
    return pins


def check_pins(pins, n_vertices: int, name: str) -> torch.Tensor:
    """(P,) long pins given by a user, checked: at least :data:`MIN_PINS`, unique, each in [0, n_vertices)."""
    pins = torch.as_tensor(pins, dtype=torch.long).reshape(-1)
    bad = pins[(pins < 0) | (pins >= n_vertices)]
    if len(bad):
        raise ValueError(f"garment {name!r}: pin indices {bad[:10].tolist()} are outside [0, {n_vertices}) (0-based vertex indices); "
                         f"give garment.pins (load_garment's pins) indices below {n_vertices}, or none to have them found")  # fmt: skip
    if len(pins.unique()) < MIN_PINS:
        raise ValueError(f"garment {name!r}: {len(pins.unique())} distinct pins given, at least {MIN_PINS} needed; give garment.pins "
                         f"(load_garment's pins) {MIN_PINS} or more distinct vertex indices, or none to have them found")  # fmt: skip
    return pins


def garment_pins(garment, body) -> torch.Tensor:
    """The garment's pins, or :func:`find_pins` on its canonical body when it has fewer than :data:`MIN_PINS`."""
    if garment.pins.numel() >= MIN_PINS:
        return garment.pins.long()
    with torch.no_grad():
        canonical = body.shaped(body.full_betas(garment.betas)[None])[0][0]
    return find_pins(garment.vertices.to(body.dtype), canonical, garment.name)
