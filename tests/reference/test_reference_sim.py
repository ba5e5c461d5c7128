"""Reference simulations on Newton against the animated low-resolution body (slow: the first run compiles
warp kernels for minutes; each scene simulates 55 frames)."""

import json
import time

import pytest
import torch

from drapebench.body import make_sequence
from drapebench.garments import make_garment
from drapebench.geometry.sdf import signed_distance
from drapebench.metrics import evaluate
from drapebench.physics import Material
from drapebench.reference import SimulationDiverged, simulate, simulate_record

pytestmark = pytest.mark.slow
RES = 0.025  # coarser than the default garments (1.1-1.3k vertices) to keep CPU runs in minutes
SETTLE = 15


def scene(body, kind, motion, n_frames=30, transition=10):
    return make_garment(kind, body, resolution=RES), make_sequence(motion, n_frames, transition=transition, seed=1000)


def stays_on_body(garment, seq, body, x):
    """How far the garment came off: the largest fraction of vertices (over frames) that are more than
    10 cm farther from the body surface than they were on the template (a flared hem is far from the
    legs at rest already), and the largest drop (m) of the garment's mean height relative to the
    pelvis below its first-frame value (falling off is downward; a hem flipping up in a jump is not)."""
    sd = signed_distance(x, seq.vertices(body), body.faces)
    sd_rest = signed_distance(garment.vertices[None], body.shaped(garment.betas[None, : body.n_betas])[0], body.faces)
    far = ((sd - sd_rest) > 0.10).float().mean(1)
    rel_z = x[..., 2].mean(1) - seq.joints(body)[:, 0, 2]
    return float(far.max()), float((rel_z[0] - rel_z).max())


@pytest.mark.parametrize("solver", ["vbd", "style3d"])
@pytest.mark.parametrize("kind", ["tshirt", "skirt"])
def test_walk_quality(body_lowres, kind, solver):
    g, seq = scene(body_lowres, kind, "walk")
    x = simulate(g, seq, body_lowres, Material(), solver=solver, settle_frames=SETTLE, progress=False)
    assert x.shape == (seq.n_frames, g.n_vertices, 3) and torch.isfinite(x).all()
    summary, _ = evaluate(g, seq, body_lowres, x, energies=False)
    assert summary["eps_c"] < 1.0, summary
    assert summary["eps_e"] < 5.0, summary
    far, drop = stays_on_body(g, seq, body_lowres, x)
    assert far < 0.05 and drop < 0.05, (far, drop)
    t = time.perf_counter()
    again = simulate(g, seq, body_lowres, Material(), solver=solver, settle_frames=SETTLE, progress=False)
    assert time.perf_counter() - t < 1.0 and torch.equal(again, x)


@pytest.mark.parametrize("kind, motion", [("tshirt", "jump"), ("skirt", "jump"), ("tshirt", "twist"), ("skirt", "twist")])
def test_garment_stays_on_through_jump_and_twist(body_lowres, kind, motion):
    g, seq = scene(body_lowres, kind, motion)
    x = simulate(g, seq, body_lowres, Material(), settle_frames=SETTLE, progress=False)
    assert torch.isfinite(x).all()
    far, drop = stays_on_body(g, seq, body_lowres, x)
    assert far < 0.05 and drop < 0.05, (far, drop)


def test_stress_finishes_or_reports_the_frame(body_lowres):
    g, seq = scene(body_lowres, "skirt", "stress")
    try:
        rec = simulate_record(g, seq, body_lowres, Material(), settle_frames=SETTLE, progress=False)
    except SimulationDiverged as err:
        assert err.garment == "skirt" and 0 <= err.frame < seq.n_frames and "substeps=" in str(err)
    else:
        assert torch.isfinite(rec.vertices).all() and rec.stats["max_speed"] < 50.0


def test_blow_up_names_garment_and_frame_and_caches_only_the_failure(body_lowres, monkeypatch, tmp_path):
    monkeypatch.setenv("DRAPEBENCH_DATA", str(tmp_path))
    g, seq = scene(body_lowres, "tshirt", "walk", n_frames=4, transition=2)
    with pytest.raises(SimulationDiverged, match=r"garment 'tshirt' on sequence 'walk_s1000' diverged at settling frame 0 of 2") as err:
        simulate(g, seq, body_lowres, Material(), settle_frames=2, substeps=1, iterations=1, max_speed=1e-6, progress=False)
    (record,) = (tmp_path / "cache" / "reference").glob("*")  # no drape: only the record of the failure
    assert record.name.endswith(".failed.json") and json.loads(record.read_text())["frame"] == err.value.frame


def test_pinned_vertices_follow_the_skinned_body(body_lowres):
    from methods.lbs import LBSMethod

    g, seq = scene(body_lowres, "skirt", "walk", n_frames=6, transition=3)
    x = simulate(g, seq, body_lowres, Material(), settle_frames=2, progress=False)
    lbs = LBSMethod()
    lbs.bind(body_lowres, Material())
    skinned = lbs.drape(g, seq).vertices
    err = (x[:, g.pins] - skinned[:, g.pins]).norm(dim=-1)
    assert float(err.max()) < 1e-4
    free = torch.ones(g.n_vertices, dtype=torch.bool)
    free[g.pins] = False
    assert float((x[:, free] - skinned[:, free]).norm(dim=-1).max()) > 1e-3
