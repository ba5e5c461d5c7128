"""GAPS's Laplacian output basis (output_basis: laplacian, beyond the paper): the basis, the network's span, the keys."""

import pytest
import torch

import methods
from drapebench.body import make_sequence
from drapebench.garments import make_garment
from drapebench.geometry.topology import get_topology
from drapebench.physics import Material
from methods.gaps.basis import BASES, laplacian_basis
from methods.gaps.config import gaps_params

K = 16


@pytest.fixture(scope="module")
def skirt(body_lowres):
    """The skirt at a coarse resolution (about 700 vertices)."""
    return make_garment("skirt", body_lowres, resolution=0.03)


@pytest.fixture(autouse=True)
def _data_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("DRAPEBENCH_DATA", str(tmp_path))  # the basis cache


def _set_up(body, g, cfg):
    """An untrained GAPS bound to ``body`` with its constants for garment ``g``."""
    m = methods.get("gaps")(cfg)
    m.bind(body, Material())
    m._setup(g)
    return m


def _rayleigh(d: torch.Tensor, g) -> torch.Tensor:
    """d^T L d / d^T M d per field of displacements d (..., V, 3) (1/m^2): the cotangent Laplacian's Dirichlet
    energy over the mass-weighted norm, at most the basis's largest eigenvalue for a field in its span."""
    topo = get_topology(g.vertices, g.faces, dtype=torch.float64)
    d = d.double().reshape(-1, g.n_vertices, 3)
    Ld = torch.stack([torch.sparse.mm(topo.laplacian, x) for x in d])
    return (d * Ld).sum((-1, -2)) / (d.square() * topo.vertex_areas[:, None]).sum((-1, -2))


def test_the_basis_is_orthonormal_the_lowest_modes_and_cached(skirt, tmp_path):
    b = laplacian_basis(skirt.vertices, skirt.faces, K)
    P, mass = b.vectors, b.mass
    assert P.shape == (skirt.n_vertices, K) and P.dtype == torch.float64
    torch.testing.assert_close(P.T @ (mass[:, None] * P), torch.eye(K, dtype=torch.float64), atol=1e-10, rtol=0)
    topo = get_topology(skirt.vertices, skirt.faces, dtype=torch.float64)
    LP = torch.sparse.mm(topo.laplacian, P)
    torch.testing.assert_close(LP, b.values * topo.vertex_areas[:, None] * P, atol=1e-9 * float(LP.abs().max()), rtol=0)
    assert abs(float(b.values[0])) < 1e-8 and bool((b.values[1:] > 0).all()) and bool((b.values[1:] >= b.values[:-1]).all())
    # the lowest modes: the 2K-mode basis starts with the same eigenvalues, and a field of the next modes is rougher
    wider = laplacian_basis(skirt.vertices, skirt.faces, 2 * K)
    torch.testing.assert_close(wider.values[:K], b.values, rtol=1e-8, atol=1e-8)
    assert float(_rayleigh(wider.vectors[:, K:].sum(1, keepdim=True).expand(-1, 3), skirt)) > float(b.values[-1])
    # a displacement in the span is reproduced exactly by its coefficients Phi^T (M / mean M) d
    c = torch.randn(K, 3, dtype=torch.float64, generator=torch.Generator().manual_seed(0))
    d = P @ c
    torch.testing.assert_close(P @ (P.T @ (mass[:, None] * d)), d, atol=1e-12, rtol=0)
    assert len(list((tmp_path / "cache" / BASES.kind).glob("laplacian_*.npz"))) == 2  # K and 2K, one file each
    again = laplacian_basis(skirt.vertices, skirt.faces, K)
    assert torch.equal(again.vectors, P)


def test_the_network_outputs_lie_in_the_span_and_a_coefficient_moves_them_smoothly(body_lowres, skirt):
    g, seq = skirt, make_sequence("walk", 8, seed=0, transition=2)
    m = _set_up(body_lowres, g, {"output_basis": "laplacian", "basis_modes": K})
    dense = _set_up(body_lowres, g, {})
    assert m.net.out.out_features == 3 * K and m.net.n_out == 3 * g.n_vertices and m.net.basis.dtype == body_lowres.dtype
    torch.manual_seed(0)
    with torch.no_grad():
        for net in (m.net, dense.net):
            net.out.weight.normal_(0.0, 1e-3)
            net.out.bias.normal_(0.0, 1e-3)
    d = m.displacements(seq).reshape(seq.n_frames, g.n_vertices, 3)
    assert float(d.abs().max()) > 1e-5  # it moves the garment
    b = laplacian_basis(g.vertices, g.faces, K)
    P, mass = b.vectors.to(d.dtype), b.mass.to(d.dtype)
    in_span = torch.einsum("vk,tkc->tvc", P, torch.einsum("vk,tvc->tkc", P, mass[:, None] * d))
    torch.testing.assert_close(in_span, d, atol=1e-5 * float(d.abs().max()), rtol=0)
    assert bool((_rayleigh(d, g) <= b.values[-1] * (1 + 1e-4)).all())  # no rougher than the basis's highest mode
    assert bool((_rayleigh(dense.displacements(seq).reshape(seq.n_frames, g.n_vertices, 3), g) > 10 * b.values[-1]).all())
    # one coefficient (the bias of mode k, coordinate x) moves every vertex by that mode's shape
    k, step = 3, 1e-3
    with torch.no_grad():
        m.net.out.bias[3 * k] += step
    moved = m.displacements(seq).reshape(seq.n_frames, g.n_vertices, 3) - d
    expected = torch.zeros_like(moved)
    expected[..., 0] = step * P[:, k]
    torch.testing.assert_close(moved, expected.expand_as(moved), atol=1e-6 * step, rtol=1e-4)
    assert torch.isfinite(m.drape(g, seq).vertices).all()


def test_the_basis_runs_in_float64(skirt):
    from drapebench.body import load_body

    body = load_body("anny_lowres", dtype=torch.float64)
    m = _set_up(body, skirt, {"output_basis": "laplacian", "basis_modes": K})
    seq = make_sequence("walk", 4, seed=0, transition=1)
    assert m.net.basis.dtype == torch.float64 and m.displacements(seq).dtype == torch.float64


def test_a_checkpoint_carries_its_basis_and_dense_keys_stay_out_of_the_key(body_lowres, skirt):
    g, seq = skirt, make_sequence("walk", 6, seed=1, transition=2)
    cfg = {"output_basis": "laplacian", "basis_modes": K}
    m = _set_up(body_lowres, g, cfg)
    with torch.no_grad():
        m.net.out.bias.normal_(0.0, 1e-3)
    m2 = methods.get("gaps")(cfg)
    m2.bind(body_lowres, Material())
    m2.load_state_dict(m.state_dict())
    torch.testing.assert_close(m2.drape(g, seq).vertices, m.drape(g, seq).vertices)
    with pytest.raises(ValueError, match="trained with"):
        methods.get("gaps")({}).load_state_dict(m.state_dict())
    # the dense output reads neither key: its checkpoints keep the key they had before the keys existed
    assert methods.get("gaps")({"basis_modes": 64}).settings_key() == methods.get("gaps")({}).settings_key()
    assert "output_basis" not in methods.get("gaps")({}).settings_key()
    assert methods.get("gaps")({**cfg, "basis_modes": 64}).settings_key() != methods.get("gaps")(cfg).settings_key()


def test_bad_basis_settings_are_named(body_lowres, skirt):
    with pytest.raises(ValueError, match="output_basis must be one of dense, laplacian, not 'fourier'"):
        gaps_params({"output_basis": "fourier"})
    with pytest.raises(ValueError, match="basis_modes"):
        _set_up(body_lowres, skirt, {"output_basis": "laplacian", "basis_modes": skirt.n_vertices})
    m = methods.get("gaps")({"output_basis": "laplacian", "basis_modes": K, "train": {"output_smoothing": 2}})
    from drapebench.data import TrainData

    data = TrainData(body=body_lowres, material=Material(), garment=skirt, load_train=lambda: [make_sequence("walk", 6, seed=0, transition=2)])
    with pytest.raises(ValueError, match="output_smoothing"):
        m.fit(data, {"epochs": 1, "batch_size": 2, "seed": 0})
