"""``energy_terms``: every energy a scene has the inputs for, by name."""

from __future__ import annotations

import torch

from drapebench.geometry.proximity import nearest_body_vertex
from drapebench.geometry.sdf import closest_body_point
from drapebench.geometry.topology import Topology
from drapebench.physics.energies import (
    bending_energy,
    collision_energy,
    gravity_energy,
    inertia_energy,
    stvk_energy,
)
from drapebench.physics.material import Material


def energy_terms(
    x: torch.Tensor,
    topology: Topology,
    material: Material,
    body_vertices: torch.Tensor | None = None,
    body_normals: torch.Tensor | None = None,
    x_prev: torch.Tensor | None = None,
    v_prev: torch.Tensor | None = None,
    rest_angle: str | torch.Tensor = "flat",
    blend: torch.Tensor | None = None,
    collision_eps: float | None = None,
    candidates: torch.Tensor | None = None,
    body_faces: torch.Tensor | None = None,
    body_outer_faces: torch.Tensor | None = None,
    near=None,
) -> dict[str, torch.Tensor]:
    """Named (B,) energies of garment positions x (B, V, 3) in joules (collision in m^3, unweighted).

    Always ``stvk``, ``bending``, ``gravity``; ``inertia`` when ``x_prev`` and ``v_prev`` (B, V, 3) are
    given (x_hat = x_prev + dt v_prev, Material.dt); ``collision`` (cubic SNUG penalty against
    the nearest body vertex, margin ``collision_eps`` or Material.collision_thickness) when
    ``body_vertices`` and ``body_normals`` (B, Vb, 3) are given (``candidates`` restricts the body
    vertices searched, see ``proximity.culled_body_vertices``). With ``body_faces`` (F, 3) the
    collision term uses the exact signed distance of :mod:`drapebench.geometry.sdf` instead (the
    eps_c rule; body_normals may then be omitted): d_v = n . (x_v - p_v) to the closest body surface
    point p_v with the detached closest point and normal, differentiable w.r.t. x (``body_outer_faces``
    (F,) bool: searched on the body's outer surface, ``BodyModel.outer_faces``). ``near``: that body
    query (``nearest_body_vertex`` or ``closest_body_point`` of x, with ``point`` and ``normal``)
    already computed by the caller; the collision term then uses it. ``rest_angle`` and ``blend`` are passed
    to :func:`bending_energy`. Terms whose inputs are missing are skipped, never computed on placeholders.
    """
    if x.dim() == 2:
        x = x[None]
    terms = {
        "stvk": stvk_energy(x, topology, material),
        "bending": bending_energy(x, topology, material, rest_angle=rest_angle, blend=blend),
        "gravity": gravity_energy(x, topology, material),
    }
    if (x_prev is None) != (v_prev is None):
        raise ValueError("inertia needs both x_prev and v_prev (or neither)")
    if x_prev is not None:
        terms["inertia"] = inertia_energy(x, x_prev, v_prev, topology, material)
    if body_vertices is None and (body_normals is not None or body_faces is not None):
        raise ValueError("collision needs body_vertices with body_normals (nearest vertex) or body_faces (signed distance)")
    if body_vertices is not None and body_normals is None and body_faces is None:
        raise ValueError("collision needs body_normals (nearest vertex) or body_faces (signed distance) with body_vertices")
    if near is None and body_vertices is not None:
        if body_faces is None:
            near = nearest_body_vertex(x, body_vertices, body_normals, candidates)
        else:  # closest point and normal carry no gradient: d is differentiable w.r.t. x only
            near = closest_body_point(x, body_vertices, body_faces, outer_faces=body_outer_faces)
    if near is not None:
        eps = material.collision_thickness if collision_eps is None else collision_eps
        terms["collision"] = collision_energy(x, near.point, near.normal, eps)
    return terms
