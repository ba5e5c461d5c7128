"""Material mapping to Newton's parameters and solver settings (no simulation, no warp import)."""

import numpy as np
import pytest

from drapebench.physics import Material
from drapebench.reference import SimSettings
from drapebench.reference.materials import (
    membrane_moduli,
    panel_coordinates,
    style3d_parameters,
    vbd_edge_stiffness,
    vbd_parameters,
)
from tests.meshes import grid_mesh


def test_vbd_membrane_is_the_materials_lame_times_thickness():
    m = Material()
    p = vbd_parameters(m, damping=1e-3)
    assert p["tri_ke"] == pytest.approx(m.lame_mu * m.thickness)
    assert p["tri_ka"] == pytest.approx(m.lame_lambda * m.thickness)
    assert p["tri_kd"] == pytest.approx(1e-3 * p["tri_ke"])
    assert p["density"] == pytest.approx(m.bulk_density * m.thickness)
    assert p["particle_radius"] == m.collision_thickness
    # the linearised Neo-Hookean membrane has the material's 2D Poisson ratio (plane stress: nu)
    assert p["tri_ka"] / (p["tri_ka"] + 2 * p["tri_ke"]) == pytest.approx(m.poisson)


def test_uniaxial_modulus_matches_plane_stress_young():
    m = Material(young=1.0e5, poisson=0.3)
    # E_2D = 4 mu (mu + lambda) / (lambda + 2 mu) equals E for plane-stress Lame parameters
    assert membrane_moduli(m)["e2d_t"] == pytest.approx(m.young * m.thickness, rel=1e-9)
    ku, kv, ks = style3d_parameters(m)["tri_aniso_ke"]
    assert ku == kv == pytest.approx(m.young * m.thickness) and ks == pytest.approx(m.lame_mu * m.thickness)


def test_vbd_bending_per_edge_scales_with_resolution():
    D = Material().bending
    for n, size in ((6, 0.5), (11, 0.5)):
        V, F = grid_mesh(n, size)
        h = size / (n - 1)
        # interior axis-aligned edge (0-based vertex n+1 -> n+2) with opposite vertices on both sides
        k, l = n + 1, n + 2
        tris = [f for f in F if k in f and l in f]
        opp = [int(next(v for v in f if v not in (k, l))) for f in tris]
        ke = vbd_edge_stiffness(V, np.array([[opp[0], opp[1], k, l]]), D)
        assert ke[0] == pytest.approx(D / h)  # D_eff = h k_e on a grid (newton_anny.md calibration)
    ke_boundary = vbd_edge_stiffness(V, np.array([[opp[0], -1, k, l]]), D)
    assert np.isfinite(ke_boundary).all() and ke_boundary[0] > 0


def test_panel_coordinates_are_isometric_and_counter_clockwise():
    V, F = grid_mesh(5, 0.4, noise=0.05)
    V = V @ np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]], dtype=float).T  # stand the sheet up (warp along z)
    panel, pf = panel_coordinates(V, F)
    assert panel.shape == (3 * len(F), 2) and pf.shape == F.shape
    for e0, e1 in ((0, 1), (1, 2), (2, 0)):
        l3 = np.linalg.norm(V[F[:, e1]] - V[F[:, e0]], axis=1)
        l2 = np.linalg.norm(panel[pf[:, e1]] - panel[pf[:, e0]], axis=1)
        np.testing.assert_allclose(l2, l3, rtol=1e-9)
    p0, p1, p2 = panel[pf[:, 0]], panel[pf[:, 1]], panel[pf[:, 2]]
    signed = 0.5 * ((p1 - p0)[:, 0] * (p2 - p0)[:, 1] - (p1 - p0)[:, 1] * (p2 - p0)[:, 0])
    area3 = 0.5 * np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1)
    np.testing.assert_allclose(signed, area3, rtol=1e-9)


def test_settings_defaults_come_from_the_configs_and_bad_values_fail():
    vbd, s3d = SimSettings.for_solver("vbd"), SimSettings.for_solver("style3d")
    assert vbd.solver == "vbd" and s3d.solver == "style3d" and vbd.substeps >= 1
    assert SimSettings.for_solver("vbd", substeps=3, iterations=None).substeps == 3
    with pytest.raises(ValueError, match="available: vbd, style3d"):
        SimSettings.for_solver("xpbd")
    with pytest.raises(ValueError, match="substeps must be >= 1"):
        SimSettings.for_solver("vbd", substeps=0)
    with pytest.raises(ValueError, match="unknown reference setting"):
        SimSettings.for_solver("vbd", substep=4)
