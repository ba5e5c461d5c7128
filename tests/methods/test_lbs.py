import torch

import methods
from drapebench.body import make_sequence
from drapebench.garments import make_garment
from drapebench.physics import Material
from drapebench.data import TrainData


def test_registry_lists_and_rejects():
    assert "lbs" in methods.available()
    try:
        methods.get("nope")
    except KeyError as e:
        assert "available methods: " in str(e) and "lbs" in str(e)
    else:
        raise AssertionError("unknown method accepted")


def test_lbs_follows_the_body_rigidly(body_lowres):
    g = make_garment("skirt", body_lowres)
    m = methods.get("lbs")({})
    m.fit(TrainData(body=body_lowres, material=Material(), garment=g))
    seq = make_sequence("walk", 12, seed=0, transition=0)
    x = m.drape(g, seq).vertices
    assert x.shape == (seq.n_frames, g.n_vertices, 3)
    # pose 0 / trans 0 gives the template back
    rest = make_sequence("static", 1, transition=1)
    assert torch.allclose(m.drape(g, rest).vertices[0], g.vertices, atol=1e-5)
    # a pure translation moves every vertex by it
    shifted = make_sequence("static", 1, transition=1)
    shifted.trans[:] = torch.tensor([0.1, -0.2, 0.3])
    assert torch.allclose(m.drape(g, shifted).vertices[0], g.vertices + shifted.trans[0], atol=1e-5)


def test_lbs_drapes_a_chunk_at_a_time_what_it_drapes_whole(body_lowres):
    g = make_garment("tshirt", body_lowres)
    m = methods.get("lbs")({})
    m.fit(TrainData(body=body_lowres, material=Material(), garment=g))
    seq = make_sequence("walk", 20, seed=0, transition=3)
    whole = m.drape(g, seq)
    chunks = list(m.drape_chunks(g, seq, 5))
    assert [len(c.vertices) for c in chunks] == [5, 5, 5, 5, 3]
    assert torch.equal(torch.cat([c.vertices for c in chunks]), whole.vertices)
    assert whole.timings_ms.keys() == chunks[0].timings_ms.keys() == {"weights", "body", "skinning"}
    assert sum(c.timings_ms["weights"] for c in chunks) == chunks[0].timings_ms["weights"] > 0  # counted once
