"""Detect degenerate cloth states (reported, never silently fixed)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import torch

from drapebench.geometry.ops import dihedral_angles, edge_lengths, face_areas
from drapebench.geometry.topology import Topology


@dataclass
class MeshStateReport:
    """Indices (into the flattened batch x element arrays per frame) of degenerate elements."""

    nonfinite_vertices: list = field(default_factory=list)
    degenerate_faces: list = field(default_factory=list)
    collapsed_edges: list = field(default_factory=list)
    folded_hinges: list = field(default_factory=list)
    flipped_faces: list = field(default_factory=list)
    overstretched_edges: list = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not any(getattr(self, k) for k in self.__dataclass_fields__)

    def __str__(self) -> str:
        if self.ok:
            return "mesh state ok"
        parts = []
        for k in self.__dataclass_fields__:
            v = getattr(self, k)
            if v:
                parts.append(f"{len(v)} {k.replace('_', ' ')} (first: {v[:5]})")
        return "; ".join(parts)


def validate_mesh_state(
    x: torch.Tensor,
    topo: Topology,
    area_ratio: float = 1e-3,
    length_ratio: float = 1e-3,
    max_stretch: float = 10.0,
    fold: float = 0.95 * np.pi,
    flip: float = 0.5 * np.pi,
) -> MeshStateReport:
    """Report degenerate elements of positions x (B, V, 3) or (V, 3); nothing is modified.

    Lists, as (frame, index) pairs: non-finite vertices; faces whose area fell below ``area_ratio`` x
    rest; edges shorter than ``length_ratio`` x rest (collapsed) or longer than ``max_stretch`` x rest;
    hinges whose dihedral angle exceeds ``fold`` rad (folded onto themselves); flipped faces, i.e.
    faces turned over against most of their edge neighbours (dihedral beyond ``flip`` rad on more
    than half of their interior edges, e.g. a vertex pushed through the opposite edge).
    """
    x = x[None] if x.dim() == 2 else x
    x = x.detach()
    rep = MeshStateReport()

    def pairs(mask):
        return [tuple(p) for p in torch.nonzero(mask).tolist()]

    rep.nonfinite_vertices = pairs(~torch.isfinite(x).all(-1))
    xs = torch.nan_to_num(x)
    rep.degenerate_faces = pairs(face_areas(xs, topo.faces) < area_ratio * topo.face_areas)
    ratio = edge_lengths(xs, topo.edges) / topo.rest_edge_lengths
    rep.collapsed_edges = pairs(ratio < length_ratio)
    rep.overstretched_edges = pairs(ratio > max_stretch)
    theta = dihedral_angles(xs, topo).abs()  # (B, H)
    rep.folded_hinges = pairs(theta > fold)
    B, F = x.shape[0], topo.n_faces
    hf = topo.hinge_faces.reshape(-1)
    turned = (theta > flip).long().repeat_interleave(2, dim=1)  # per (hinge, side) -> its face
    n_turned = torch.zeros(B, F, dtype=torch.long, device=x.device).index_add(1, hf, turned)
    n_hinges = torch.zeros(F, dtype=torch.long, device=x.device).index_add(0, hf, torch.ones_like(hf))
    rep.flipped_faces = pairs(2 * n_turned > n_hinges)
    return rep
