"""From :class:`drapebench.physics.Material` to Newton's cloth parameters (VBD and Style3D).

Notation: t thickness (m); mu, lambda the Material's per-thickness plane-stress Lame parameters (Pa),
so mu t and lambda t are 2D membrane moduli (N/m); D = ``material.bending`` (N m); rho_A =
``material.area_density`` (kg/m^2); eps = ``material.collision_thickness`` (m).

Common to both solvers
- Mass: rho_A x (area of the template's triangles) / 3 per vertex (Newton lumps exactly like
  :meth:`Topology.vertex_masses`).
- Rest shape: the garment template (the 3D mesh as built, curved).
- Body contact: particle radius eps, so a vertex is pushed out once it is closer than eps to the
  body mesh (penalty stiffness ``contact_ke`` N/m, damping ``contact_kd``); Coulomb friction with
  mu_f = ``material.friction`` on both the cloth and the body side (Newton combines them as
  sqrt(mu_cloth mu_body) = mu_f). Contacts are vertex-vs-body-triangle only: body edges may cut
  through cloth triangles between vertices (the suite's ``eps_c`` also counts vertices).

SolverVBD (Chen et al. 2024, Vertex Block Descent)
- Membrane: a stable Neo-Hookean membrane, psi = mu/2 (I_C - 2) + lambda'/2 (J - alpha)^2 per rest
  area with ``tri_ke`` = mu t, ``tri_ka`` = lambda t (lambda' = tri_ke + tri_ka, alpha = 1 + mu/lambda').
  It linearises exactly to the suite's StVK (same 2D mu, lambda); the two differ only at large strain
  (StVK stiffens with Green strain and has no resistance to inversion, Neo-Hookean resists
  compression/inversion). 2D Poisson ratio lambda/(lambda + 2 mu).
- Bending: a dihedral spring E = 1/2 k_e L_e (theta - theta_0)^2 with theta_0 the template's
  dihedral angle (as the suite's bending energy). Per edge k_e = D L_e / (A_0 + A_1) (A_i the two
  adjacent triangle areas): on a regular grid this gives D_eff = c h k_e = c D with c ~ 0.95-1.0 for
  bending across grid axes and ~0.7 for oblique bending (cylinder calibration in
  ``docs/references.md``); on the remeshed (near-equilateral) garments the effective
  bending stiffness is therefore within ~30% of D and direction-dependent at the element scale.
- Damping: stiffness-proportional (Rayleigh beta = ``damping`` s): ``tri_kd`` = beta tri_ke on the
  rate of C = F^T F (rotation-free), ``edge_kd`` = beta k_e on d theta/dt. The suite's energies
  have no damping; this only removes element-scale ringing.

SolverStyle3D (projective dynamics, Baraff-Witkin membrane)
- Membrane: per area ku/2 (|F_u| - 1)^2 + kv/2 (|F_v| - 1)^2 + ks/2 (F_u^ . F_v^)^2 along a
  per-triangle material frame (v = "warp" along the template's projected vertical, u = v x n).
  ku = kv = E_2D t = 4 mu (mu + lambda) / (lambda + 2 mu) t (matches uniaxial stretch), ks = mu t
  (matches small shear). No Poisson coupling: biaxial stretch is softer than StVK
  (ku vs (lambda + 2 mu) t, about 0.77x for cotton).
- Rest shape: each triangle's 2D rest shape is its own isometric flattening (panel coordinates are
  per face), so the membrane is at rest on the template.
- Bending: Bergou et al.'s quadratic isometric model, whose rest state is FLAT (not the template's
  curvature): a curved garment carries a small bending pre-stress. ke = D / 2.8 (measured
  D_eff = 2.6-3.0 ke on cylinders); resolution-independent.
- Self-contact is always on (thickness 2 x eps); velocities are multiplied by 0.998 every substep.
"""

from __future__ import annotations

import numpy as np

from drapebench.physics.material import Material

STYLE3D_BEND_CALIBRATION = 2.8  # D_eff / ke measured for Style3D's Bergou bending (2.6-3.0)


def membrane_moduli(material: Material) -> dict:
    """2D membrane moduli in N/m: mu_t, lambda_t (Lame x thickness), e2d_t (uniaxial Young's x thickness)."""
    mu, lam = material.lame_mu, material.lame_lambda
    t = material.thickness
    return {"mu_t": mu * t, "lambda_t": lam * t, "e2d_t": 4.0 * mu * (mu + lam) / (lam + 2.0 * mu) * t}


def vbd_edge_stiffness(vertices: np.ndarray, edge_indices: np.ndarray, bending: float) -> np.ndarray:
    """Per-edge VBD bending stiffness k_e = D L_e / (A_0 + A_1) in N.

    vertices (V, 3) rest positions (m); edge_indices (E, 4) Newton's (opposite_0, opposite_1, v_0, v_1)
    with -1 for a missing opposite vertex (boundary edge: A_1 = A_0); bending D (N m).
    """
    x = np.asarray(vertices, dtype=np.float64)
    e = np.asarray(edge_indices, dtype=np.int64)
    k, l = x[e[:, 2]], x[e[:, 3]]
    length = np.linalg.norm(l - k, axis=1)

    def area(opp):
        valid = opp >= 0
        a = np.zeros(len(opp))
        p = x[opp[valid]]
        a[valid] = 0.5 * np.linalg.norm(np.cross(k[valid] - p, l[valid] - p), axis=1)
        return a, valid

    a0, v0 = area(e[:, 0])
    a1, v1 = area(e[:, 1])
    total = np.where(v0 & v1, a0 + a1, 2.0 * np.maximum(a0, a1))
    return bending * length / np.maximum(total, 1e-12)


def vbd_parameters(material: Material, damping: float) -> dict:
    """Keyword arguments of ``ModelBuilder.add_cloth_mesh`` for SolverVBD (per-edge ``edge_ke`` is set
    afterwards with :func:`vbd_edge_stiffness`; ``damping`` is the Rayleigh beta in s)."""
    m = membrane_moduli(material)
    return {
        "density": material.area_density,
        "tri_ke": m["mu_t"],
        "tri_ka": m["lambda_t"],
        "tri_kd": damping * m["mu_t"],
        "particle_radius": material.collision_thickness,
    }


def style3d_parameters(material: Material) -> dict:
    """Style3D stretch (ku, kv, ks) in N/m, bending ke (N m) and cloth keyword arguments."""
    m = membrane_moduli(material)
    return {
        "density": material.area_density,
        "tri_aniso_ke": (m["e2d_t"], m["e2d_t"], m["mu_t"]),
        "bend_ke": material.bending / STYLE3D_BEND_CALIBRATION,
        "particle_radius": material.collision_thickness,
    }


def panel_coordinates(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-face isometric 2D flattening of a 3D mesh for Style3D.

    Each triangle gets its own three panel vertices in a frame whose v axis ("warp") is the world
    Z axis projected onto the triangle (Y for near-horizontal triangles) and u = v x n, so every
    panel triangle is counter-clockwise with its 3D rest area. Returns panel_verts (3F, 2) metres
    and panel_indices (F, 3).
    """
    x = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    a, b, c = x[f[:, 0]], x[f[:, 1]], x[f[:, 2]]
    n = np.cross(b - a, c - a)
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
    up = np.where(np.abs(n[:, 2:3]) > 0.95, np.array([[0.0, 1.0, 0.0]]), np.array([[0.0, 0.0, 1.0]]))
    v = up - (up * n).sum(1, keepdims=True) * n
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    u = np.cross(v, n)
    rel = np.stack([np.zeros_like(a), b - a, c - a], axis=1)  # (F, 3, 3)
    panel = np.stack([(rel * u[:, None]).sum(-1), (rel * v[:, None]).sum(-1)], axis=-1)  # (F, 3, 2)
    return panel.reshape(-1, 2), np.arange(3 * len(f)).reshape(-1, 3)


__all__ = ["membrane_moduli", "panel_coordinates", "style3d_parameters", "vbd_edge_stiffness", "vbd_parameters"]
