import json
from types import SimpleNamespace

import numpy as np
import pytest
import torch
import trimesh

from drapebench.body import BodyModel, BodySequence
from drapebench.geometry import get_topology
from drapebench.geometry.ops import edge_lengths
from drapebench.metrics import evaluate


@pytest.fixture(scope="module")
def sphere_scene():
    """A one-joint 'body' that is a sphere of radius 0.5, and a spherical 'garment' of radius 0.8."""
    s = trimesh.creation.icosphere(3, radius=0.5)
    V = len(s.vertices)
    body = BodyModel(s.vertices, np.zeros((V, 3, 1)), np.full((1, V), 1.0 / V), np.ones((V, 1)), [-1], s.faces, name="sphere")
    g = trimesh.creation.icosphere(1, radius=0.8)
    garment = SimpleNamespace(topology=get_topology(g.vertices, g.faces), n_vertices=len(g.vertices),
                              vertices=torch.as_tensor(g.vertices, dtype=torch.float32))  # fmt: skip
    seq = BodySequence("still", "static", torch.zeros(1), torch.zeros(4, 1, 3), torch.zeros(4, 3), n_transition=1)
    return body, garment, seq


def test_eps_c_is_exact_for_points_inside_a_sphere(sphere_scene):
    body, garment, seq = sphere_scene
    pred = garment.vertices[None].repeat(seq.n_frames, 1, 1).clone()
    inside = [[], [0, 1, 2], [3, 4, 5, 6, 7, 8], [0]]  # per frame
    for t, idx in enumerate(inside):
        pred[t, idx] *= 0.3 / 0.8  # radius 0.3: 0.2 m deep inside the 0.5 sphere
    summary, frames = evaluate(garment, seq, body, pred, energies=False)
    n = garment.n_vertices
    expected = [100 * len(i) / n for i in inside[1:]]  # frame 0 is the transition
    assert np.allclose(frames["eps_c"], expected) and np.allclose(frames["eps_c_nn"], expected)
    assert np.isclose(summary["eps_c"], np.mean(expected)) and np.isclose(summary["eps_c_std"], np.std(expected))
    assert np.isclose(summary["eps_e_std"], frames["eps_e"].std(ddof=0)) and summary["eps_e_std"] > 0
    assert np.allclose(frames["penetration_mm"], [200, 200, 200], atol=2.0)  # mesh vs true sphere


def test_depth_is_to_the_outer_surface_past_a_buried_part(sphere_scene):
    """The sphere body with a second closed part buried inside it (radius 0.15): vertices at radius 0.3
    are 0.15 m from the buried part and 0.2 m deep below the outer surface, which is what they report."""
    _, garment, seq = sphere_scene
    outer, buried = trimesh.creation.icosphere(3, radius=0.5), trimesh.creation.icosphere(2, radius=0.15)
    V = np.concatenate([outer.vertices, buried.vertices])
    F = np.concatenate([outer.faces, buried.faces + len(outer.vertices)])
    body = BodyModel(V, np.zeros((len(V), 3, 1)), np.full((1, len(V)), 1.0 / len(V)), np.ones((len(V), 1)), [-1], F, name="two parts")
    assert not body.outer_faces[len(outer.faces) :].any() and body.outer_faces[: len(outer.faces)].all()
    pred = garment.vertices[None].repeat(seq.n_frames, 1, 1) * (0.3 / 0.8)
    for exact in (False, True):
        summary, frames = evaluate(garment, seq, body, pred, energies=False, exact=exact)
        assert np.allclose(frames["eps_c"], 100.0)
        assert np.allclose(frames["penetration_mm"], 200, atol=2.0) and 198 < summary["max_penetration_mm"] < 201


def test_uniform_stretch_and_reference_error(sphere_scene):
    body, garment, seq = sphere_scene
    pred = garment.vertices[None].repeat(seq.n_frames, 1, 1) * 1.1
    summary, _ = evaluate(garment, seq, body, pred, reference=pred * 0 + garment.vertices, energies=True)
    assert np.isclose(summary["eps_e"], 10.0, atol=1e-3) and np.isclose(summary["eps_a"], 21.0, atol=1e-3)
    assert np.isclose(summary["vertex_error_mm"], 80.0, rtol=1e-4)  # every vertex 0.08 m out
    assert summary["eps_e_std"] < 1e-3 and summary["eps_a_std"] < 1e-3  # the same stretch in every frame
    assert summary["jitter"] == 0.0 and summary["eps_c"] == 0.0 and summary["penetration_mm"] == 0.0
    assert summary["energy_stvk"] > 0 and "energy_collision" in summary
    shrunk, _ = evaluate(garment, seq, body, garment.vertices[None].repeat(seq.n_frames, 1, 1) * 0.9, energies=False)
    assert np.isclose(shrunk["eps_e"], 10.0, atol=1e-3) and np.isclose(shrunk["eps_a"], 19.0, atol=1e-3)  # a compression counts as much


def test_jitter_zero_for_linear_motion_positive_for_shaking(sphere_scene):
    body, garment, seq = sphere_scene
    t = torch.arange(seq.n_frames, dtype=torch.float32)[:, None, None]
    linear = garment.vertices[None] + 0.01 * t
    assert evaluate(garment, seq, body, linear, energies=False)[0]["jitter"] < 1e-3
    shaking = garment.vertices[None] + 0.01 * (-1) ** t
    assert evaluate(garment, seq, body, shaking, energies=False)[0]["jitter"] > 10


def test_a_drape_too_short_for_jitter_and_drift_reports_them_as_null_not_nan(sphere_scene, caplog):
    """``motion.n_frames=1`` once wrote ``"jitter": NaN, "drift_mm": NaN`` into metrics.json (JSON has no NaN)."""
    body, garment, _ = sphere_scene
    seq = BodySequence("still", "static", torch.zeros(1), torch.zeros(2, 1, 3), torch.zeros(2, 3), n_transition=1)
    pred = garment.vertices[None].repeat(seq.n_frames, 1, 1)
    with caplog.at_level("WARNING", logger="drapebench"):
        summary, _ = evaluate(garment, seq, body, pred, energies=False)
    assert summary["jitter"] is None and summary["drift_mm"] is None and summary["n_frames_evaluated"] == 1
    assert "jitter and drift_mm not measured on 1 evaluated frame(s)" in caplog.text and "motion.n_frames" in caplog.text
    from drapebench.schema import EvalConf

    assert "eval.skip_transition=false" in caplog.text and EvalConf().skip_transition  # the advice names a real key
    assert json.loads(json.dumps(summary, allow_nan=False)) == summary  # strict JSON: no NaN anywhere
    long_enough = BodySequence("still", "static", torch.zeros(1), torch.zeros(11, 1, 3), torch.zeros(11, 3), n_transition=1)
    summary, _ = evaluate(garment, long_enough, body, garment.vertices[None].repeat(11, 1, 1), energies=False)
    assert summary["jitter"] == 0.0 and summary["drift_mm"] == 0.0  # 10 evaluated frames measure both


def test_bad_prediction_is_reported(sphere_scene):
    body, garment, seq = sphere_scene
    pred = garment.vertices[None].repeat(seq.n_frames, 1, 1).clone()
    pred[2, 5, 0] = float("nan")
    with pytest.raises(ValueError, match=r"NaN/Inf in frames \[2\]"):
        evaluate(garment, seq, body, pred)
    with pytest.raises(ValueError, match="expected"):
        evaluate(garment, seq, body, pred[:2])


def test_lbs_drape_on_a_real_body_matches_unculled_queries(body_lowres):
    """evaluate() culls the body; its eps_c / eps_c_nn equal counts over the whole body."""
    from scipy.spatial import cKDTree

    from drapebench.body import make_sequence
    from drapebench.body.lbs import lbs
    from drapebench.garments import make_garment
    from drapebench.geometry.proximity import nearest_body_vertex
    from drapebench.geometry.sdf import signed_distance

    body = body_lowres
    g = make_garment("tshirt", body)
    seq = make_sequence("dance", 8, seed=4)
    idx = torch.as_tensor(cKDTree(body.v_template.numpy()).query(g.vertices.numpy())[1])
    x = lbs(g.vertices, body.weights[idx], seq.transforms(body))
    summary, frames = evaluate(g, seq, body, x)
    assert len(frames) == seq.n_frames - seq.n_transition == summary["n_frames_evaluated"]
    chunked, chunked_frames = evaluate(g, seq, body, x, chunk_frames=2)  # chunks of 2 frames: the same table
    assert list(chunked_frames.columns) == list(frames.columns) and np.allclose(chunked_frames, frames, equal_nan=True, rtol=1e-6)
    assert summary["drift_mm"] is None and chunked["drift_mm"] is None  # 6 evaluated frames: too few for a drift
    assert np.allclose([chunked[k] for k in summary if k != "drift_mm"], [v for k, v in summary.items() if k != "drift_mm"], rtol=1e-6)
    bv, bn = seq.vertices(body)[seq.n_transition :], seq.vertex_normals(body)[seq.n_transition :]
    xe = x[seq.n_transition :]
    sd = signed_distance(xe, bv, body.faces)
    assert np.allclose(frames["eps_c"], (sd < 0).float().mean(-1) * 100)
    assert np.allclose(frames["eps_c_nn"], (nearest_body_vertex(xe, bv, bn).distance < 0).float().mean(-1) * 100)
    depth = -sd[sd < 0]
    assert np.isclose(summary["penetration_mm"], float(depth.mean()) * 1e3 if len(depth) else 0.0, rtol=1e-5)
    for name in ("stvk", "bending", "gravity", "collision"):
        assert np.isfinite(frames[f"energy_{name}"]).all()
    rel = (edge_lengths(xe, g.topology.edges) - g.topology.rest_edge_lengths).abs() / g.topology.rest_edge_lengths
    assert np.isclose(summary["max_strain"], float(rel.max()) * 100, rtol=1e-5)
    assert np.isclose(summary["max_penetration_mm"], float(depth.max()) * 1e3 if len(depth) else 0.0, rtol=1e-5)
    assert np.allclose(frames["garment_body_mm"], sd.mean(-1) * 1e3, rtol=1e-5)


def test_drift_compares_the_first_and_last_tenth_of_the_frames(sphere_scene):
    from drapebench.metrics import drift

    assert drift(np.arange(20.0)) == 18.0  # last two (18, 19) against first two (0, 1)
    assert drift(np.r_[np.zeros(10), -np.ones(10)]) == 1.0 and np.isnan(drift(np.ones(9)))
    body, garment, _ = sphere_scene
    seq = BodySequence("still", "static", torch.zeros(1), torch.zeros(20, 1, 3), torch.zeros(20, 3))
    rising = garment.vertices[None] + torch.linspace(0, 0.1, seq.n_frames)[:, None, None] * torch.tensor([0.0, 0.0, 1.0])
    summary, frames = evaluate(garment, seq, body, rising, skip_transition=False)
    n = len(frames) // 10
    expected = abs(frames["garment_body_mm"][-n:].mean() - frames["garment_body_mm"][:n].mean())
    assert summary["drift_mm"] == pytest.approx(expected) and summary["drift_mm"] > 1.0


@pytest.mark.parametrize("shift", [(0.0, 0.0, 0.0), (0.0, -2.0, 0.0), (0.08, 0.0, 0.0), (0.3, 0.0, 0.0)])
def test_collision_metrics_equal_whole_body_queries_when_the_garment_moves_or_the_shape_differs(body_lowres, shift):
    """A mean-shape tshirt skinned to a walk of a far body shape, in place, 2 m below the feet and
    moved sideways into the arm (8 cm, 30 cm): eps_c and penetration_mm equal an exact inside test (libigl's
    winding number) and distance (libigl's closest point) over the whole body, eps_c_nn the nearest
    vertex of the whole body."""
    import igl
    from scipy.spatial import cKDTree

    from drapebench.body import make_sequence
    from drapebench.body.lbs import lbs
    from drapebench.garments import make_garment

    body = body_lowres
    g = make_garment("tshirt", body)
    betas = torch.zeros(body.n_betas)
    betas[:2] = torch.tensor([2.5, -2.0])
    seq = make_sequence("walk", 4, seed=1, betas=betas, transition=0)
    idx = torch.as_tensor(cKDTree(body.v_template.numpy()).query(g.vertices.numpy())[1])
    x = lbs(g.vertices, body.weights[idx], seq.transforms(body)) + torch.tensor(shift)
    summary, frames = evaluate(g, seq, body, x, energies=False)
    F = body.faces.numpy().astype(np.int64)
    depths, eps_c, eps_c_nn = [], [], []
    for t, (bv, bn) in enumerate(zip(seq.vertices(body).double().numpy(), seq.vertex_normals(body).double().numpy())):
        p = x[t].double().numpy()
        inside = igl.winding_number(bv, F, p) > 0.5
        eps_c.append(inside.mean() * 100)
        depths.append(np.sqrt(igl.point_mesh_squared_distance(p, bv, F)[0])[inside])
        near = cKDTree(bv).query(p)[1]
        eps_c_nn.append((((p - bv[near]) * bn[near]).sum(-1) < 0).mean() * 100)
    assert np.allclose(frames["eps_c"], eps_c)
    assert np.allclose(frames["eps_c_nn"], eps_c_nn)
    depth = np.concatenate(depths)
    assert np.isclose(summary["penetration_mm"], depth.mean() * 1e3 if len(depth) else 0.0, rtol=1e-4)
    if shift[1] == -2.0:
        assert summary["eps_c"] == 0.0
    if shift[0] > 0:
        assert summary["eps_c"] > 1.0  # part of the garment is moved into the body


@pytest.mark.parametrize("offset", [(1.0e4, 0.0, 0.0), (0.0, -1.0e4, 1.0e4)])
def test_every_metric_is_translation_invariant_ten_kilometres_from_the_origin(body_lowres, offset):
    """A drape and its body moved 10 km (float64 positions, a root translation float32 holds exactly) give
    every metric of the drape at the origin to float32's resolution at the body's scale; energy_gravity keeps
    the world's datum, so it moves by exactly -M g . offset."""
    from drapebench.body import make_sequence
    from drapebench.body.lbs import lbs
    from drapebench.garments import make_garment
    from drapebench.physics import Material

    g = make_garment("tshirt", body_lowres)
    dance = make_sequence("dance", 8, seed=4, transition=2)
    seq = BodySequence("here", "dance", dance.betas, dance.poses, torch.zeros_like(dance.trans), n_transition=2)
    far = BodySequence("far", "dance", dance.betas, dance.poses, torch.tensor(offset).expand(seq.n_frames, 3), n_transition=2)
    idx = torch.cdist(g.vertices, body_lowres.v_template).argmin(1)
    x = lbs(g.vertices.double(), body_lowres.weights[idx].double(), seq.transforms(body_lowres).double())
    x = x + torch.tensor([0.08, 0.0, 0.0], dtype=torch.float64)  # 8 cm sideways: part of it inside the arm
    ref = x + 0.002
    here, frames = evaluate(g, seq, body_lowres, x, reference=ref)
    moved = torch.tensor(offset, dtype=torch.float64)
    there, far_frames = evaluate(g, far, body_lowres, x + moved, reference=ref + moved)
    assert here["eps_e"] > 1.0 and here["eps_c"] > 0.0 and here["penetration_mm"] > 0.0  # something to measure
    lift = -float(g.topology.vertex_masses(Material()).double().sum()) * float(torch.tensor(Material().gravity).double() @ moved)
    for key, value in here.items():
        expected = value + lift if key == "energy_gravity" else value  # None: too few frames (drift_mm)
        assert (there[key] is None) if value is None else there[key] == pytest.approx(expected, rel=1e-5, abs=1e-9), key
    assert np.allclose(far_frames["eps_e"], frames["eps_e"], rtol=1e-5)


def test_float32_positions_too_far_from_the_origin_to_measure_are_refused(sphere_scene):
    from drapebench.metrics import MAX_FLOAT32_DISTANCE, FarFromOrigin

    body, garment, seq = sphere_scene
    pred = garment.vertices[None].repeat(seq.n_frames, 1, 1) + 2 * MAX_FLOAT32_DISTANCE
    with pytest.raises(FarFromOrigin, match=r"float32 positions are .* mm apart.*dtype=float64"):
        evaluate(garment, seq, body, pred)
    evaluate(garment, seq, body, pred.double() - 2 * MAX_FLOAT32_DISTANCE, energies=False)  # float64 is measured anywhere
