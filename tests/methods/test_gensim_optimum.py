"""gensim_optimum: GenSim's Eq. 9 minimised over the vertices of each frame from the ARAP stage (drapebench.optimum)."""

from types import SimpleNamespace

import pytest
import torch

import methods
from methods.gensim.method import garment_graph
from drapebench.body import make_sequence
from drapebench.garments import make_garment
from drapebench.physics import Material

FABRIC = {"fabric_mean": 4.442e-4, "fabric_std": 8.059e-4}


@pytest.fixture(autouse=True)
def _data_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("DRAPEBENCH_DATA", str(tmp_path))


def test_the_optimum_lowers_gensims_loss_from_its_arap_stage(body_lowres):
    g = make_garment("skirt", body_lowres, resolution=0.03)
    seq = make_sequence("walk", 3, seed=0, transition=1)
    m = methods.get("gensim_optimum")({**FABRIC, "optimum": {"iterations": 15}})
    m.bind(body_lowres, Material())
    with pytest.raises(RuntimeError, match="call fit"):  # mu_fabric / sigma_fabric are read by fit
        m.drape(g, seq)
    m.fit(SimpleNamespace(body=body_lowres, material=Material()))
    r = m.drape(g, seq)
    assert r.vertices.shape == (seq.n_frames, g.n_vertices, 3) and torch.isfinite(r.vertices).all()
    assert set(r.extras) == {"arap", "handles"} and (r.vertices - r.extras["arap"]).norm(dim=-1).max() > 1e-4
    stats = m.diagnostics(g, seq, r)  # GenSim's PEN statistics measure the optimum's move from the ARAP stage
    assert stats["pen_mm"] > 0 and "hem_drop_mm" in stats
    graph = garment_graph(g, body_lowres, Material())  # Eq. 9 in the front-aligned frame: lower at the optimum
    G, _, _, verts, normals, _ = m.arap_stage(graph, torch.zeros(body_lowres.n_betas), seq.poses)
    root = seq.transforms(body_lowres)[:, 0]
    aligned = (r.vertices - root[:, None, :3, 3]) @ root[:, :3, :3]
    loss = lambda x: sum(m.terms(graph, x, G, verts, normals).values())  # noqa: E731
    assert torch.allclose(r.extras["arap"], G @ root[:, :3, :3].transpose(1, 2) + root[:, None, :3, 3], atol=1e-5)
    assert loss(aligned) < 0.9 * loss(G)
    with pytest.raises(ValueError, match="unknown gensim_optimum parameter"):
        methods.get("gensim_optimum")({"optimum": {"steps": 3}})


def test_the_half_space_optimum_keeps_every_move_in_eq1s_half_space_and_lowers_the_loss(body_lowres):
    g = make_garment("skirt", body_lowres, resolution=0.03)
    seq = make_sequence("walk", 3, seed=0, transition=1)
    free, half = (methods.get("gensim_optimum")({**FABRIC, "optimum": {"iterations": 15, "space": space}}) for space in ("vertices", "half_space"))
    for m in (free, half):
        m.fit(SimpleNamespace(body=body_lowres, material=Material()))
    graph = garment_graph(g, body_lowres, Material())
    G, _, _, verts, normals, _ = half.arap_stage(graph, torch.zeros(body_lowres.n_betas), seq.poses)
    _, body_normal = half.body_query(G, verts, normals)
    root = seq.transforms(body_lowres)[:, 0]
    loss = lambda x: sum(half.terms(graph, x, G, verts, normals).values())  # noqa: E731
    aligned = {}
    for name, m in (("free", free), ("half", half)):
        aligned[name] = (m.drape(g, seq).vertices - root[:, None, :3, 3]) @ root[:, :3, :3]
    along = lambda x: ((x - G) * body_normal).sum(-1)  # noqa: E731
    assert along(aligned["half"]).min() > -1e-5  # Eq. 1: nothing moves against the body normal
    assert along(aligned["free"]).min() < -1e-4  # the free optimum does move some vertices inward
    assert loss(aligned["half"]) < 0.9 * loss(G)
    with pytest.raises(ValueError, match="space"):
        methods.get("gensim_optimum")({"optimum": {"space": "tangent"}})
