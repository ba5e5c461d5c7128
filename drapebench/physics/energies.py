"""Cloth energies, batched over (B, V, 3), differentiable, float32 or float64.

Each function returns a (B,) total, or per-element values with ``per_element=True``. Formulas
follow the public code of SNUG (Santesteban et al. 2022) and of Chen et al. 2024 (3DV: R. Chen, L. Chen,
S. Parashar; ``docs/references.md``) and the paper of Tiwari et al. 2023 (CVPR-W); the source of each is in its
docstring. Loss *weights* are never applied here: the caller (method) owns them (e.g. Chen et al.'s collision
weight 250, the SNUG pitfall).
"""

from __future__ import annotations

import torch

from drapebench.geometry.ops import corners, dihedral_angles, edge_lengths, face_areas
from drapebench.geometry.topology import Topology
from drapebench.physics.material import Material


def _tiny(x: torch.Tensor) -> float:
    return torch.finfo(x.dtype).tiny


def _total(e: torch.Tensor, per_element: bool) -> torch.Tensor:
    return e if per_element else e.sum(-1)


def _batch(x: torch.Tensor) -> torch.Tensor:
    if x.dim() == 2:
        x = x[None]
    if x.dim() != 3 or x.shape[-1] != 3:
        raise ValueError(f"positions must be (B, V, 3), got {tuple(x.shape)}")
    return x


def deformation_gradient(x: torch.Tensor, topo: Topology) -> torch.Tensor:
    """Per-face deformation gradient F = Ds Dm^-1, (B, F, 3, 2); Ds = [x1 - x0, x2 - x0]."""
    v0, v1, v2 = corners(x, topo.faces)
    ds = torch.stack((v1 - v0, v2 - v0), -1).movedim(0, -2)  # (..., F, 3, 2)
    return ds @ topo.rest_inv


def _green_strain_entries(x: torch.Tensor, topo: Topology) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """G00, G01 (= G10), G11 of the Green strain per face, each (..., F): F^T F = R^T (Ds^T Ds) R with
    R = Dm^-1, from the three dot products of the face's edge vectors."""
    v0, v1, v2 = corners(x, topo.faces)
    d1, d2 = v1 - v0, v2 - v0
    a, b, c = (d1 * d1).sum(0), (d1 * d2).sum(0), (d2 * d2).sum(0)
    r00, r01, r10, r11 = topo.rest_inv[:, 0, 0], topo.rest_inv[:, 0, 1], topo.rest_inv[:, 1, 0], topo.rest_inv[:, 1, 1]
    g00 = 0.5 * (r00 * r00 * a + 2.0 * r00 * r10 * b + r10 * r10 * c - 1.0)
    g01 = 0.5 * (r00 * r01 * a + (r00 * r11 + r10 * r01) * b + r10 * r11 * c)
    g11 = 0.5 * (r01 * r01 * a + 2.0 * r01 * r11 * b + r11 * r11 * c - 1.0)
    return g00, g01, g11


def green_strain(x: torch.Tensor, topo: Topology) -> torch.Tensor:
    """Green-Lagrange strain G = (F^T F - I) / 2 per face, (B, F, 2, 2)."""
    g00, g01, g11 = _green_strain_entries(x, topo)
    return torch.stack((torch.stack((g00, g01), -1), torch.stack((g01, g11), -1)), -2)


def stvk_energy(x: torch.Tensor, topo: Topology, material: Material, per_element: bool = False) -> torch.Tensor:
    """StVK membrane energy (J): sum_f A_f t (mu |G|_F^2 + lambda/2 tr(G)^2).

    as the SNUG code and that of Chen et al. 2024 compute it: S = mu G + lambda/2 tr(G) I, energy density tr(S^T G); A_f is the rest area,
    mu and lambda per thickness (Material), so the product with thickness t gives N/m.
    """
    x = _batch(x)
    g00, g01, g11 = _green_strain_entries(x, topo)
    tr = g00 + g11
    psi = material.lame_mu * (g00 * g00 + 2.0 * g01 * g01 + g11 * g11) + 0.5 * material.lame_lambda * tr * tr
    return _total(topo.face_areas * material.thickness * psi, per_element)


def bending_energy(
    x: torch.Tensor,
    topo: Topology,
    material: Material,
    rest_angle: str | torch.Tensor = "flat",
    blend: torch.Tensor | None = None,
    scale: str = "rest",
    per_element: bool = False,
) -> torch.Tensor:
    """Discrete hinge bending (J): sum_e k s_e / 2 [(1 - w_e) theta_e^2 + w_e (theta_e - theta_bar_e)^2].

    theta is the signed dihedral angle (``ops.dihedral_angles``), s_e = l_e^2 / (4 (a0 + a1)) with the
    hinge edge's length l_e and its two face areas a0, a1 (Chen et al. 2024's Eq. 12 writes l^2/(8a) with
    no 1/2 in front, the same number), k = Material.bending (N m).
    ``rest_angle``: "flat" (theta_bar = 0, SNUG), "template" (theta_bar = rest dihedral), or an (H,)
    tensor (rad). ``blend`` (H,) or (B, H) in [0, 1] gives Chen et al. 2024's per-edge mix between the flat and
    the template angle (Eq. 12); with ``blend`` theta_bar is the template angle and ``rest_angle`` is ignored.
    ``scale`` says where l_e and a0, a1 are measured: "rest" (both on the rest mesh; ArcSim's
    constant stiffness), "edge" (l_e on the deformed mesh, the areas at rest: what the SNUG and Chen et al.
    code compute, ``losses/physics.py`` / ``script/losses/losses.py``, so a stretched hinge bends
    stiffer by its stretch squared) or "current" (both deformed, as Tiwari et al. 2023's Eq. 4 prints ||E_ij^pred||^2).
    """
    x = _batch(x)
    theta = dihedral_angles(x, topo)
    rest_area = topo.face_areas[topo.hinge_faces].sum(-1)
    if scale == "rest":
        s = topo.hinge_rest_lengths**2 / (4.0 * rest_area)
    elif scale == "edge":
        s = edge_lengths(x, topo.hinge_edges) ** 2 / (4.0 * rest_area)
    elif scale == "current":
        l2 = edge_lengths(x, topo.hinge_edges) ** 2
        area = face_areas(x, topo.faces)[..., topo.hinge_faces].sum(-1)
        s = l2 / (4.0 * torch.maximum(area, 1e-6 * rest_area))  # floor: collapsed faces stay finite
    else:
        raise ValueError(f"scale must be 'rest', 'edge' or 'current', not {scale!r}")
    if blend is not None:
        w = blend.to(x.dtype)
        e = (1.0 - w) * theta**2 + w * (theta - topo.rest_dihedral) ** 2
    else:
        if isinstance(rest_angle, str):
            if rest_angle not in ("flat", "template"):
                raise ValueError(f"rest_angle must be 'flat', 'template' or a tensor, not {rest_angle!r}")
            ref = topo.rest_dihedral if rest_angle == "template" else torch.zeros_like(topo.rest_dihedral)
        else:
            ref = rest_angle.to(x.dtype)
        e = (theta - ref) ** 2
    return _total(0.5 * material.bending * s * e, per_element)


def gravity_energy(x: torch.Tensor, topo: Topology, material: Material, per_element: bool = False) -> torch.Tensor:
    """Gravitational potential energy (J): -sum_v m_v g . x_v (Chen et al. 2024, Eq. 10; g = Material.gravity)."""
    x = _batch(x)
    g = torch.tensor(material.gravity, dtype=x.dtype, device=x.device)
    return _total(-topo.vertex_masses(material) * (x * g).sum(-1), per_element)


def inertia_energy(
    x: torch.Tensor,
    x_prev: torch.Tensor,
    v_prev: torch.Tensor,
    topo: Topology,
    material: Material,
    dt: float | None = None,
    per_element: bool = False,
) -> torch.Tensor:
    """Inertia (J): sum_v m_v |x - x_hat|^2 / (2 dt^2), x_hat = x_prev + dt v_prev (SNUG; Chen et al. 2024, Eq. 13).

    Callers detach ``x_prev``/``v_prev`` when gradients must not flow into earlier frames (Chen et al.'s
    and NCS's code use stop_gradient on 2 x1 - x0).
    """
    x = _batch(x)
    dt = material.dt if dt is None else dt
    x_hat = x_prev + dt * v_prev
    d = x - x_hat
    return _total(topo.vertex_masses(material) * (d * d).sum(-1) / (2.0 * dt * dt), per_element)


def collision_energy(
    x: torch.Tensor, nn_point: torch.Tensor, nn_normal: torch.Tensor, eps: float = 2e-3, per_element: bool = False
) -> torch.Tensor:
    """Cubic body-collision penalty (m^3): sum_v max(eps - d_v, 0)^3, d_v = n . (x_v - p_v) to the nearest
    body vertex p_v with normal n (SNUG and Chen et al. 2024 code; the weight, 250 there, is the caller's)."""
    x = _batch(x)
    d = ((x - nn_point) * nn_normal).sum(-1)
    return _total(torch.relu(eps - d) ** 3, per_element)


def hinge_collision_energy(
    x: torch.Tensor, nn_point: torch.Tensor, nn_normal: torch.Tensor, eps: float = 2e-3, per_element: bool = False
) -> torch.Tensor:
    """Tiwari et al. 2023's linear hinge collision penalty (m): sum_v max(eps - d_v, 0), d_v = n . (x_v - p_v).

    Their Eq. 8 prints max(-n (B - G), eps) = max(d, eps), which read literally is minimised by
    pulling every vertex onto the body; its text asks for a penetration penalty with a threshold
    eps "for robustness". This is the hinge on the margin: eps > 0 keeps vertices eps outside the
    body (as the cubic SNUG term); a negative eps tolerates penetrations up to |eps| (the other
    reading of the threshold). The weight is the caller's.
    """
    x = _batch(x)
    d = ((x - nn_point) * nn_normal).sum(-1)
    return _total(torch.relu(eps - d), per_element)


_SYM_FULL = (0, 3, 4, 3, 1, 5, 4, 5, 2)  # the row-major 3x3 from the six entries xx, yy, zz, xy, xz, yz


def _outer6(v: torch.Tensor) -> torch.Tensor:
    """The six entries (xx, yy, zz, xy, xz, yz) of v v^T per vector v, component-major: v (3, ...) -> (6, ...)."""
    a, b, c = v.unbind(0)
    return torch.stack((a * a, b * b, c * c, a * b, a * c, b * c))


def _ring_moments(x: torch.Tensor, topo: Topology) -> torch.Tensor:
    """The six entries (xx, yy, zz, xy, xz, yz) of each vertex's 1-ring covariance, component-major (6, V, B) m^2,
    of positions x (B, V, 3): the neighbours' offsets from the vertex (small numbers: no cancellation against
    positions of about 1 m), their mean outer product less the outer product of their mean (the covariance does not
    depend on the origin). Component-major, so that the gathers and sums over the rings (and their gradients) move
    contiguous rows of the B frames and each entry is a contiguous (V, B) block (on a CPU several times faster than
    (B, V, 6)); callers work on that layout and transpose their (V, B) result."""
    owner, ring = topo.ring_owner, topo.ring_idx
    cnt = topo.ring_sizes.clamp_min(1).to(x.dtype)[:, None]
    B, V = x.shape[:2]
    xc = x.permute(2, 1, 0).contiguous()  # (3, V, B)
    e = xc.index_select(1, ring) - xc.index_select(1, owner)  # (3, P, B)
    mean = xc.new_zeros(3, V, B).index_add_(1, owner, e) / cnt
    second = xc.new_zeros(6, V, B).index_add_(1, owner, _outer6(e)) / cnt
    return second - _outer6(mean)


def ring_covariance(x: torch.Tensor, topo: Topology) -> torch.Tensor:
    """Covariance of each vertex's 1-ring neighbours (centre excluded, mean-centred, / count): (B, V, 3, 3)."""
    x = _batch(x)
    m = _ring_moments(x, topo).permute(2, 1, 0)  # (B, V, 6)
    return m.index_select(2, torch.tensor(_SYM_FULL, device=x.device)).reshape(*x.shape[:2], 3, 3)


def inextensibility_energy(
    x: torch.Tensor, topo: Topology, k_ext: float | torch.Tensor = 1.0, per_element: bool = False
) -> torch.Tensor:
    """Collision-aware inextensibility (m^6): sum_v sum_j |det(C_v - k_ext,v sigma_j,v I)| (Chen et al. 2024, Eq. 15).

    C_v is the current 1-ring covariance, sigma_j the template's eigenvalues
    (``Topology.rest_ring_eigvals``); ``k_ext`` is a scalar or (B, V) per-vertex factor (1 = inextensible;
    their Eq. 16 raises it where the garment collides). The weight (2e8) is the caller's. Each determinant is
    C_v's characteristic polynomial at s = k_ext sigma_j: det C - s c_2 + s^2 tr C - s^3 (c_2 the sum of the
    principal 2x2 minors).
    """
    x = _batch(x)
    xx, yy, zz, xy, xz, yz = _ring_moments(x, topo).unbind(0)  # each (V, B), as the moments
    trace = (xx + yy + zz)[..., None]
    minors = (xx * yy - xy * xy + xx * zz - xz * xz + yy * zz - yz * yz)[..., None]
    det = (xx * (yy * zz - yz * yz) - xy * (xy * zz - yz * xz) + xz * (xy * yz - yy * xz))[..., None]
    k = torch.as_tensor(k_ext, dtype=x.dtype, device=x.device)
    k = k.transpose(0, 1)[..., None] if k.dim() == 2 else k[:, None, None] if k.dim() == 1 else k  # (V|1, B|1, 1) or a scalar
    s = k * topo.rest_ring_eigvals[:, None]  # (V, B|1, 3)
    dets = det - s * (minors - s * (trace - s))  # (V, B, 3)
    return _total(dets.abs().sum(-1).transpose(0, 1), per_element)


def collision_aware_kext(
    distance: torch.Tensor, epoch: float, eps: float = 2e-3, rate: float = 10.0, cap: float = 0.03, ramp_epochs: int = 100
) -> torch.Tensor:
    """Chen et al. 2024's Eq. 16 extension factor per vertex: k_ext = 1 + min(rate d_c, cap) min(epoch, ramp_epochs), d_c = max(eps - d, 0).

    ``distance`` (B, V) signed normal distance to the nearest body vertex (m); returns (B, V) in
    [1, 1 + cap ramp_epochs] (theirs: [1, 4], reached for d <= eps - cap/rate = -1 mm after 100 epochs).
    Differentiable in ``distance`` where 0 < rate d_c < cap, as in their code (whose distance n_b . (x - v_b)
    carries the garment's gradient); pass a detached distance for a factor held constant.
    """
    d_c = torch.relu(eps - distance)
    return 1.0 + torch.clamp(rate * d_c, max=cap) * min(epoch, ramp_epochs)


def restrain_energy(
    x: torch.Tensor, topo: Topology, fabric_mean: float, fabric_std: float, per_element: bool = False
) -> torch.Tensor:
    """Restrain energy (dimensionless): sum_e ((|l_e - l0_e| - mu_fabric) / sigma_fabric)^2 (Tiwari et al. 2023, Eq. 2-3).

    ``fabric_mean``/``fabric_std`` (m) are the mean and std of absolute edge-length changes of the
    fabric, estimated from reference simulations.
    """
    x = _batch(x)
    if not fabric_std > 0:
        raise ValueError(f"fabric_std must be positive, got {fabric_std}")
    phi = (edge_lengths(x, topo.edges) - topo.rest_edge_lengths).abs()
    return _total(((phi - fabric_mean) / fabric_std) ** 2, per_element)


def pin_energy(x: torch.Tensor, target: torch.Tensor, pins: torch.Tensor, per_element: bool = False) -> torch.Tensor:
    """Pin energy (m^2): sum_{i in pins} |x_i - target_i|^2 (Tiwari et al. 2023, Eq. 5); target (P,3) or (B,P,3)."""
    x = _batch(x)
    d = x[:, pins] - target
    return _total((d * d).sum(-1), per_element)


def laplacian(x: torch.Tensor, topo: Topology) -> torch.Tensor:
    """Cotangent Laplacian applied to positions, L x: (B, V, 3)."""
    x = _batch(x)
    B, V, _ = x.shape
    flat = x.permute(1, 0, 2).reshape(V, B * 3)
    L = topo.laplacian if topo.laplacian.dtype == x.dtype else topo.laplacian.to(x.dtype)
    return torch.sparse.mm(L, flat).reshape(V, B, 3).permute(1, 0, 2)


def laplacian_smoothness(x: torch.Tensor, topo: Topology, squared: bool = False, per_element: bool = False) -> torch.Tensor:
    """Mesh smoothness: sum_v |(L x)_v| (m) with the cotangent Laplacian L (Tiwari et al. 2023's Eq. 7 prints only
    "Delta(G)"; its Table 2 reports a mean magnitude), or sum_v |(L x)_v|^2 (m^2) with ``squared``.
    L's off-diagonal weights are (cot a + cot b) / 2, not area-normalised (``Topology.laplacian``)."""
    lx = laplacian(x, topo)
    sq = (lx * lx).sum(-1)
    return _total(sq if squared else torch.sqrt(sq + _tiny(lx)), per_element)
