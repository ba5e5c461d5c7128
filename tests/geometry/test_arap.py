"""The sparse ARAP solver against libigl's and its closed-form rotations against the SVD."""

import numpy as np
import pytest
import torch

from drapebench.geometry.arap import ArapSolver, SparseArapSolver, arap_solver, best_rotations


def _svd_rotations(M: np.ndarray) -> np.ndarray:
    u, _, vt = np.linalg.svd(M)
    u[:, :, 2] *= np.sign(np.linalg.det(u @ vt))[:, None]
    return u @ vt


def _warp_rotations(M: np.ndarray, max_newton: int = 50) -> np.ndarray:
    from drapebench.geometry import rotation_kernels

    return rotation_kernels.best_rotations(M, max_newton)


@pytest.mark.parametrize("rotations", [best_rotations, _warp_rotations], ids=["numpy", "warp"])
def test_best_rotations_are_the_svds_polar_factor_with_positive_determinant(rotations):
    rng = np.random.default_rng(0)
    M = np.concatenate([rng.standard_normal((500, 3, 3)), np.eye(3) + 0.2 * rng.standard_normal((500, 3, 3))])
    M[:10, :, 2] = (M[:10, :, :2] @ rng.standard_normal((10, 2, 1)))[..., 0]  # rank 2, as a flat 1-ring's covariance
    s = np.linalg.svd(M, compute_uv=False)
    well_posed = (s[:, 1] - s[:, 2] > 1e-3) | (np.linalg.det(M) > 0)  # a reflection with sigma_2 = sigma_3 has no unique answer
    R = rotations(M)
    assert np.allclose(np.linalg.det(R), 1.0, atol=1e-12)
    assert np.abs(R - _svd_rotations(M))[well_posed].max() < 1e-8
    assert (np.linalg.det(M) < 0).sum() > 100  # the reflections were tested


@pytest.mark.parametrize("rotations", [best_rotations, _warp_rotations], ids=["numpy", "warp"])
def test_newtons_start_is_the_top_eigenvalue_of_a_flat_one_ring_and_of_a_scaled_rotation(rotations):
    """The start of Newton's method is exact for the covariances ARAP meets most (a flat 1-ring: rank 2; a scaled
    rotation: an isotropic 1-ring), so one step already gives the rotation there."""
    rng = np.random.default_rng(1)
    Q = _svd_rotations(rng.standard_normal((200, 3, 3)))
    flat = Q @ (np.array([1.0, 0.6, 0.0])[:, None] * _svd_rotations(rng.standard_normal((200, 3, 3))))
    scaled = 0.3 * Q
    for M in (flat, scaled):
        assert np.abs(rotations(M, max_newton=1) - _svd_rotations(M)).max() < 1e-9


@pytest.fixture(scope="module")
def skirt_frame(body_lowres):
    """A skirt with its pins and the vertices of its lowest 5 cm as handles (in shuffled order), moved as a kick would."""
    from drapebench.garments import make_garment

    g = make_garment("skirt", body_lowres)
    V, F = g.vertices.double().numpy(), g.faces.numpy()
    b = np.unique(np.concatenate([g.pins.numpy(), np.nonzero(V[:, 2] < V[:, 2].min() + 0.05)[0][::3]]))
    b = b[np.random.default_rng(0).permutation(len(b))]
    bc = V[b] + np.array([0.02, 0.01, 0.03]) * (V[b, 2:3] - V[:, 2].min()) * 5
    return V, F, b, bc


@pytest.mark.parametrize("iterations", [2, 5])  # one iteration after a 7 cm jump of the handles: 25 um (libigl's float SVD)
def test_sparse_arap_gives_libigls_frame_within_ten_micrometres(skirt_frame, iterations):
    V, F, b, bc = skirt_frame
    ours = SparseArapSolver(V, F, b, iterations).solve(bc, V)
    theirs = ArapSolver(V, F, b, iterations).solve(bc, V)
    assert np.abs(theirs - V).max() > 0.02  # the handles moved the skirt by centimetres
    assert np.abs(ours - theirs).max() < 1e-5
    assert np.allclose(ours[b], bc)


def test_gensims_arap_stage_is_the_same_with_either_solver(body_lowres):
    import methods
    from drapebench.body import make_sequence
    from drapebench.garments import make_garment
    from drapebench.physics import Material
    from methods.gensim.method import garment_graph

    g = make_garment("skirt", body_lowres, resolution=0.025)
    seq = make_sequence("kick", 30, seed=0)
    poses = seq.poses[[seq.n_transition + 12]]
    stages = []
    for solver in ("sparse", "libigl"):
        m = methods.get("gensim")({"arap_solver": solver, "stage": "arap"})
        m.bind(body_lowres, Material())
        graph = garment_graph(g, body_lowres, m.material)
        stages.append(m.arap_stage(graph, torch.zeros(body_lowres.n_betas), poses)[0].double())
    assert (stages[1] - g.vertices).norm(dim=-1).max() > 0.02  # a moving frame
    apart = (stages[0] - stages[1]).norm(dim=-1)
    # libigl's rotations come from a float32 SVD: on 10 steps of 2 iterations it drifts from the exact local step
    # (below) by a few micrometres on average, up to 40 um at a few vertices of near-planar 1-rings
    assert apart.mean() < 5e-6 and apart.max() < 1e-4


def _reference_arap(V, F, b, bc, U, iterations):
    """ARAP written out from the energy: per-face covariances scattered with np.add.at, the local step by
    float64 SVD, the global step by a fresh sparse solve of the free block."""
    import igl
    from scipy.sparse.linalg import spsolve

    w = igl.cotmatrix_entries(V, F)
    e0, e1 = F[:, [1, 2, 0]], F[:, [2, 0, 1]]
    dv = V[e0] - V[e1]
    A = (-igl.cotmatrix(V, F)).tocsr()
    free = np.setdiff1d(np.arange(len(V)), b)
    U = U.copy()
    U[b] = bc
    for _ in range(iterations):
        du = U[e0] - U[e1]
        per_face = np.einsum("fe,fei,fej->fij", w, du, dv)
        M = np.zeros((len(V), 3, 3))
        for k in range(3):
            np.add.at(M, F[:, k], per_face)
        R = _svd_rotations(M)
        r = np.einsum("fij,fej->fei", R[F].mean(1), dv) * w[..., None]
        B = np.zeros((len(V), 3))
        np.add.at(B, e0.ravel(), r.reshape(-1, 3))
        np.add.at(B, e1.ravel(), -r.reshape(-1, 3))
        U[free] = spsolve(A[free][:, free].tocsc(), B[free] - A[free][:, b] @ bc)
    return U


@pytest.mark.parametrize("warp", [True, False], ids=["warp rotations", "numpy rotations (no sim extra)"])
def test_sparse_arap_is_the_exact_arap_step(skirt_frame, warp, monkeypatch):
    from drapebench.geometry import arap

    if not warp:
        monkeypatch.setattr(arap, "_rotation_kernels", lambda: None)
    V, F, b, bc = skirt_frame
    assert np.abs(SparseArapSolver(V, F, b, 2).solve(bc, V) - _reference_arap(V, F, b, bc, V, 2)).max() < 1e-9


def test_arap_solver_rejects_bad_handles_and_backends(skirt_frame):
    V, F, b, _ = skirt_frame
    with pytest.raises(ValueError, match="at least one handle"):
        SparseArapSolver(V, F, b[:0])
    with pytest.raises(ValueError, match="distinct"):
        SparseArapSolver(V, F, np.concatenate([b, b[:1]]))
    with pytest.raises(ValueError, match="backend must be one of"):
        arap_solver(V, F, b, backend="eigen")
    assert arap_solver(V, F, b) is arap_solver(V, F, b)  # factorized once per handle set
