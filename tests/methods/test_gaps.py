"""GAPS on tiny data: learning, finiteness, recurrence, skinning weights, ablations."""

from dataclasses import fields

import numpy as np
import pandas as pd
import pytest
import torch

import methods
from drapebench.body import make_sequence
from drapebench.garments import make_garment
from drapebench.geometry.sdf import signed_distance
from drapebench.physics import Material
from drapebench.data import TrainData
from methods.gaps.config import ADDED_KEYS, GapsTrain
from methods.gaps.skinning import rbf_weights, smoothed_weights

QUICK = {"epochs": 1, "batch_size": 4, "log_every": 1, "checkpoint_every": 1000}


def walks():
    """Two 12-frame walks (seeds 0 and 1)."""
    return [make_sequence("walk", 12, seed=s, transition=3) for s in range(2)]


@pytest.fixture(scope="module")
def scene(body_lowres):
    """The skirt at a coarse resolution (about 700 vertices): these tests check the training's mechanics."""
    return body_lowres, make_garment("skirt", body_lowres, resolution=0.03), walks()


@pytest.fixture(autouse=True)
def _data_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("DRAPEBENCH_DATA", str(tmp_path))  # training checkpoints


def _fit(scene, cfg=None, steps_epochs=1, seed=0, **train):
    """Train GAPS ``cfg`` on the scene; ``train`` holds budget keys (conf/train) and GAPS's own training keys."""
    body, g, seqs = scene
    cfg = dict(cfg or {})
    own = {f.name for f in fields(GapsTrain)}
    cfg["train"] = {k: v for k, v in train.items() if k in own}
    m = methods.get("gaps")(cfg)
    data = TrainData(body=body, material=Material(), garment=g, load_train=lambda: seqs)
    budget = {k: v for k, v in train.items() if k not in own}
    rep = m.fit(data, {**QUICK, "seed": seed, "epochs": steps_epochs, **budget})
    return m, rep


def test_overfit_drives_the_loss_down(scene):
    # the walks' own (mean) shape; at 3e-3 the loss (collision and inertia at the code's weight) oscillates
    m, rep = _fit(scene, steps_epochs=8, lr_switch_epoch=100, lr=1e-3, beta_range=[0.0])
    first = np.mean([h["loss"] for h in rep.history[:3]])
    last = np.mean([h["loss"] for h in rep.history[-3:]])
    assert last < 0.4 * first, (first, last)
    body, g, seqs = scene
    x = m.drape(g, seqs[0]).vertices
    assert x.shape == (seqs[0].n_frames, g.n_vertices, 3) and torch.isfinite(x).all()
    # the skinning weights are frozen: after training still GAPS's normalize(P W), a partition of unity
    assert not m.weights.requires_grad
    assert torch.equal(m.weights.detach(), rbf_weights(g.vertices, body.shaped(g.betas[None, : body.n_betas])[0][0], body.weights, 0.25))
    assert torch.allclose(m.weights.sum(1), torch.ones(g.n_vertices, dtype=m.weights.dtype), atol=1e-5)


def test_training_is_deterministic_for_a_seed(scene):
    _, a = _fit(scene, seed=3)
    _, b = _fit(scene, seed=3)
    assert [h["loss"] for h in a.history] == [h["loss"] for h in b.history]


def test_weight_averaging_and_lr_decay(scene):
    plain, a = _fit(scene, seed=1)
    avg, b = _fit(scene, seed=1, ema_decay=0.9)
    assert [h["loss"] for h in a.history] == [h["loss"] for h in b.history]  # averaging does not change training
    assert not torch.equal(plain.net.out.weight, avg.net.out.weight)
    assert (avg.net.out.weight.abs().sum() < plain.net.out.weight.abs().sum())  # an average of a walk from zero is smaller
    _, c = _fit(scene, steps_epochs=2, seed=1, lr_decay_fraction=0.5, lr_switch_epoch=100)
    lrs = [h["lr"] for h in c.history]
    n = len(lrs)
    assert all(lr == pytest.approx(1e-3) for lr in lrs[: n // 2]) and lrs[-1] < lrs[n // 2] * 0.2
    assert all(x >= y for x, y in zip(lrs, lrs[1:]))


def test_output_smoothing_gives_a_smoother_output(scene):
    from drapebench.geometry.ops import ring_mean

    body, g, seqs = scene

    def roughness(m):  # mean |D - ring mean of D| of the output layer's bias field, per vertex (m)
        d = m.net.out.bias.detach().reshape(1, g.n_vertices, 3)
        return float((d - ring_mean(d, g.topology)).norm(dim=-1).mean()), float(d.norm(dim=-1).mean())

    plain, _ = _fit(scene, seed=4, lr=1e-3, output_adam_eps=1.0)
    smooth, _ = _fit(scene, seed=4, lr=1e-3, output_adam_eps=1.0, output_smoothing=10)
    (r0, size0), (r1, size1) = roughness(plain), roughness(smooth)
    assert size1 > 0.2 * size0  # it still learns a displacement
    assert r1 / size1 < 0.5 * (r0 / size0), (r0, size0, r1, size1)
    assert not smooth.net.out.bias._backward_hooks  # the hooks are removed after training


def test_gradient_clipping(scene):
    _, a = _fit(scene, seed=2)
    _, b = _fit(scene, seed=2, grad_clip=1e-3)
    assert all(h["grad_norm"] > 1e-3 for h in a.history)  # so the clip acts on every step
    assert [h["grad_norm"] for h in a.history[:1]] == [h["grad_norm"] for h in b.history[:1]]  # the norm before clipping
    assert a.history[0]["loss"] == b.history[0]["loss"] and a.history[-1]["loss"] != b.history[-1]["loss"]


def test_a_non_finite_gradient_stops_training_before_the_step(scene, monkeypatch):
    from drapebench.errors import TrainingDiverged

    body, g, seqs = scene
    m = methods.get("gaps")({})
    data = TrainData(body=body, material=Material(), garment=g, load_train=lambda: seqs)
    monkeypatch.setattr(torch.nn.utils, "clip_grad_norm_", lambda params, max_norm: torch.tensor(float("nan")))
    with pytest.raises(TrainingDiverged, match="non-finite gradient"):
        m.fit(data, {"seed": 0, **QUICK})
    assert torch.count_nonzero(m.net.out.weight) == 0  # the zero-initialised output layer never stepped


def test_gradients_finite_through_300_frames(scene):
    body, g, _ = scene
    m, _ = _fit(scene)
    seq = make_sequence("dance", 285, seed=1)
    x, _ = m.forward_sequence(g, seq)
    x.square().mean().backward()
    grads = [p.grad for p in m.net.parameters()]
    assert all(gr is not None and torch.isfinite(gr).all() for gr in grads)


def test_hidden_state_is_carried(scene):
    body, g, _ = scene
    m, _ = _fit(scene)
    seq = make_sequence("arm_raise", 20, seed=5, transition=0)  # no root travel: slicing keeps the inputs
    full = m.drape(g, seq).vertices
    with torch.no_grad():
        first, h = m.forward_sequence(g, seq.slice(0, 10))
        carried, _ = m.forward_sequence(g, seq.slice(10, 20), h)
        reset, _ = m.forward_sequence(g, seq.slice(10, 20))
    assert torch.allclose(torch.cat([first, carried]), full, atol=1e-5)
    assert not torch.allclose(reset, full[10:], atol=1e-5)


def test_a_sequence_with_fewer_betas_drapes_as_with_zero_padding(scene):
    body, g, _ = scene
    m, _ = _fit(scene)
    short = make_sequence("walk", 6, seed=2, betas=[0.0, -2.0])
    padded = make_sequence("walk", 6, seed=2, betas=[0.0, -2.0] + [0.0] * (body.n_betas - 2))
    assert len(short.betas) == 2 < body.n_betas
    assert torch.allclose(m.drape(g, short).vertices, m.drape(g, padded).vertices, atol=1e-6)


def test_rbf_weights_match_brute_force_and_sum_to_one(scene):
    body_lowres, g, _ = scene
    rest = body_lowres.v_template
    w = rbf_weights(g.vertices, rest, body_lowres.weights, k=0.25)
    assert torch.allclose(w.sum(1), torch.ones(len(w)), atol=1e-5)
    for i in (0, 100, g.n_vertices - 1):
        d = (rest.double() - g.vertices[i].double()).norm(dim=1)
        m = d.min()
        p = torch.exp(-((d - m) ** 2) / (0.25 * m * m))
        ref = p @ body_lowres.weights.double()
        assert torch.allclose(w[i].double(), ref / ref.sum(), atol=1e-6)
    s = smoothed_weights(w, g.topology, 10)
    assert torch.allclose(s.sum(1), torch.ones(len(s)), atol=1e-5)


def _untrained_inside_share(scene, shape_transfer, betas):
    """% of the garment's vertices inside a body of shape ``betas`` at the rest pose, GAPS's output zero."""
    body, g, _ = scene
    m, _ = _fit(scene, {"shape_transfer": shape_transfer}, steps_epochs=0)
    seq = make_sequence("static", 2, seed=0, betas=betas)
    x = m.drape(g, seq).vertices
    d = signed_distance(x, seq.vertices(body).to(x.dtype), body.faces, outer_faces=body.outer_faces)
    return 100.0 * (d < 0).double().mean().item()


def test_shape_transfer_carries_the_body_s_shape_to_the_garment(scene):
    body, g, _ = scene
    heavy = [1.0, 2.0, 1.0, 0.0]  # taller and heavier: the mean-body garment cuts into it
    inside = {mode: _untrained_inside_share(scene, mode, heavy) for mode in ("none", "nearest", "rbf")}
    assert inside["none"] > 5.0 and inside["rbf"] < 0.2 * inside["none"] and inside["nearest"] < 0.2 * inside["none"], inside
    m, _ = _fit(scene, {"shape_transfer": "rbf"}, steps_epochs=0)
    zero = torch.zeros(1, 1, 3 * g.n_vertices, dtype=m.body.dtype)
    assert torch.equal(m._canonical(zero, m.garment_betas[None])[0, 0], m.template)  # the garment's own shape: the template
    i = int(torch.argmin((g.vertices[:, None] - body.v_template[None]).norm(dim=-1).min(1).values))  # the vertex nearest the body
    assert torch.allclose(m.shape_dirs[i], body.shapedirs[m.nn_rest[i]], atol=0.3 * body.shapedirs[m.nn_rest[i]].abs().max())


def test_training_motions_can_be_left_out_and_a_wrong_name_is_an_error(scene):
    body, g, seqs = scene
    mixed = seqs + [make_sequence("jump", 12, seed=0, transition=3)]
    m = methods.get("gaps")({"train": {"exclude_motions": ["jump"]}})
    assert [s.motion for s in m._training_sequences(mixed)] == ["walk", "walk"]
    with pytest.raises(ValueError, match=r"exclude_motions names \['twist'\].*dataset does not hold"):
        methods.get("gaps")({"train": {"exclude_motions": ["twist"]}})._training_sequences(mixed)
    with pytest.raises(ValueError, match="leaves none"):
        methods.get("gaps")({"train": {"exclude_motions": ["walk"]}})._training_sequences(seqs)


def test_each_epoch_can_train_on_a_new_draw_of_the_dataset_and_the_schedule_overrides_the_budget(scene, monkeypatch):
    """train.redraw_motions: epoch 1 trains on new sequences of the same dataset spec (other seeds, the same motions and
    window count), epoch 0 on the dataset itself; train.schedule replaces budget keys (here the rate) for GAPS."""
    from drapebench.body import dataset

    body, g, _ = scene
    tiny = dataset.DatasetSpec(("walk", "random"), per_motion=1, n_frames=8, split="train", seed=7, transition=2)
    monkeypatch.setitem(dataset.DATASETS, "tiny", tiny)
    first = dataset.spec_sequences(tiny)
    m = methods.get("gaps")({"train": {"redraw_motions": True, "schedule": {"lr": 3e-4}}})
    data = TrainData(body=body, material=Material(), garment=g, load_train=lambda: first)
    rep = m.fit(data, {**QUICK, "epochs": 2, "dataset": "tiny"})
    assert {h["lr"] for h in rep.history} == {3e-4}
    assert m._draw == 1 and [s.motion for s in dataset.spec_sequences(dataset.redrawn("tiny", 1))] == ["walk", "random"]
    assert not any(torch.equal(p, s.poses.to(p.dtype)) for p, s in zip(m._poses, first))  # new motions in epoch 1
    assert len(m._windows) == sum(s.n_frames - 3 for s in first)  # windows of 3 frames from frame 1 on
    with pytest.raises(ValueError, match="only training datasets"):
        dataset.redrawn("test_heldout", 1)


def test_ablations_change_what_they_claim(scene):
    body, g, _ = scene
    kext1, _ = _fit(scene, {"kext": "one"}, kext_ramp_epochs=1, steps_epochs=2)
    assert kext1.last_kext_max == 1.0  # never raised, even after the ramp
    full, _ = _fit(scene, {}, kext_ramp_epochs=1, steps_epochs=2)
    assert full.last_kext_max >= 1.0
    _, rep = _fit(scene, {"inextensibility_weight": 0.0})
    assert "inext" not in rep.history[-1]
    snug, _ = _fit(scene, {"skinning": "nearest", "trainable_weights": False, "shape_transfer": "nearest"})
    nn_w = body.weights[snug.nn_rest]
    assert torch.equal(snug.weights.detach(), nn_w) and not snug.weights.requires_grad
    ncs, rep = _fit(scene, {"skinning": "smoothed", "single_shape": True, "trainable_weights": False})
    assert not torch.equal(ncs.weights.detach(), nn_w) and torch.allclose(ncs.weights.sum(1), torch.ones(g.n_vertices), atol=1e-5)
    with pytest.raises(ValueError, match="unknown gaps parameter"):
        methods.get("gaps")({"kextt": "one"})
    with pytest.raises(ValueError, match="bending must be one of"):
        methods.get("gaps")({"bending": "flatt"})


def test_collision_postprocess_only_when_asked(scene):
    body, g, seqs = scene
    m, _ = _fit(scene)
    seq = seqs[0]
    raw = m.drape(g, seq)
    m.p["collision_postprocess"] = True
    fixed = m.drape(g, seq)
    assert "postprocess" in fixed.timings_ms and "postprocess" not in raw.timings_ms
    bv, bn = seq.vertices(body), seq.vertex_normals(body)
    d_raw = m._body_contact(raw.vertices, bv, bn).distance
    d_fix = m._body_contact(fixed.vertices, bv, bn).distance
    moved = (fixed.vertices - raw.vertices).norm(dim=-1) > 0
    assert moved.any() and not moved[d_raw > 2e-3 + 1e-6].any()  # only vertices within eps of the body move
    assert (d_fix < 0).sum() <= (d_raw < 0).sum()
    # each drape is scored beside the other: the push-out's result for the paper's drape, and back
    assert torch.equal(m.scored_variants(seq, fixed)["raw"], raw.vertices)
    m.p["collision_postprocess"] = False
    assert torch.equal(m.scored_variants(seq, raw)["postprocessed"], fixed.vertices)
    assert torch.equal(m.scored_variants(seq, raw)["untrained"], m.untrained_drape(seq))  # training's start, scored too


def _set_up(body, g, cfg):
    """An untrained GAPS bound to ``body`` with its constants for garment ``g``."""
    m = methods.get("gaps")(cfg)
    m.bind(body, Material())
    m._setup(g)
    return m


def test_collision_distance_is_the_exact_body_surface_unless_vertex_is_asked(scene):
    """The training's collision term, k_ext and the push-out read the exact signed distance to the body
    mesh by default; "vertex" (the GAPS/SNUG code) reads the nearest body vertex, which on the coarse
    body counts cloth lying just off the surface as inside."""
    body, g, seqs = scene
    seq = seqs[0]
    bv, bn = seq.vertices(body)[:4], seq.vertex_normals(body)[:4]
    lbs = methods.get("lbs")({})
    lbs.bind(body, Material())
    x = lbs.drape(g, seq).vertices[:4]
    surface = _set_up(body, g, {})._body_contact(x, bv, bn)
    exact = signed_distance(x, bv, body.faces, exact=True)
    assert torch.allclose(surface.distance, exact, atol=1e-5)
    assert torch.allclose(((x - surface.point) * surface.normal).sum(-1), surface.distance, atol=1e-5)
    vertex = _set_up(body, g, {"collision_distance": "vertex"})._body_contact(x, bv, bn)
    assert not torch.allclose(vertex.distance, exact, atol=1e-3)
    assert _set_up(body, g, {}).settings_key()["collision_distance"] == "surface"  # in the checkpoint key
    with pytest.raises(ValueError, match="collision_distance must be one of"):
        methods.get("gaps")({"collision_distance": "mesh"})


@pytest.mark.parametrize("before_added_keys", [False, True])
def test_checkpoint_round_trip(scene, before_added_keys):
    """A checkpoint loads into a model of the same parameters; one written before a key existed (methods.gaps.config
    ADDED_KEYS) loads as that key's default; one of other parameters is refused."""
    body, g, seqs = scene
    m, _ = _fit(scene)
    state = m.state_dict()
    if before_added_keys:
        state["params"] = {k: v for k, v in state["params"].items() if k not in ADDED_KEYS}
    m2 = methods.get("gaps")(dict(ADDED_KEYS) if before_added_keys else {})  # the behaviour it was trained with
    m2.bind(body, Material())
    m2.load_state_dict(state)
    assert torch.allclose(m2.drape(g, seqs[0]).vertices, m.drape(g, seqs[0]).vertices)
    for other in ({"kext": "one"}, {"canonical": "relaxed"}):
        with pytest.raises(ValueError, match="trained with"):
            methods.get("gaps")(other).load_state_dict(state)


def test_the_diagnostic_takes_the_network_output_apart(scene):
    """methods.gaps.diagnose.output_parts: an output that does not vary with the motion is all static part, a
    uniform shift has no roughness, a per-vertex random field has; the parts are drapes of those outputs."""
    from methods.gaps.diagnose import output_parts

    body, g, seqs = scene
    m = _set_up(body, g, {})
    seq = seqs[0]
    shift = torch.tensor([0.0, 0.0, 0.004]).repeat(g.n_vertices)  # 4 mm up, every vertex
    with torch.no_grad():
        m.net.out.bias.copy_(shift)
    stats, parts = output_parts(m, seq)
    assert stats["mean |D| (mm)"] == pytest.approx(4.0, rel=1e-4) and stats["static |S| (mm)"] == pytest.approx(4.0, rel=1e-4)
    assert stats["varying |D - S| (mm)"] < 1e-3 and stats["roughness (mm)"] < 1e-3
    torch.testing.assert_close(parts["static part"], m.drape(g, seq).vertices)
    torch.testing.assert_close(parts["varying part"], m.untrained_drape(seq), atol=1e-6, rtol=0)
    with torch.no_grad():
        m.net.out.bias.copy_(0.004 * torch.randn(3 * g.n_vertices, generator=torch.Generator().manual_seed(0)))
    rough, parts = output_parts(m, seq)
    assert rough["roughness (mm)"] > 3.0
    smooth = (parts["smoothed x3"] - m.untrained_drape(seq)).norm(dim=-1).mean()
    assert 1e3 * smooth < 0.5 * rough["mean |D| (mm)"]  # averaging over the 1-rings shrinks a random field


def test_the_diagnostic_maps_a_drape_back_to_canonical_space_and_splits_it(scene):
    """methods.gaps.diagnose.canonical_offsets inverts the skinning of canonical displacements; static_and_varying
    gives a time-constant displacement all to the static part and a frame-to-frame one to the varying part."""
    from methods.gaps.diagnose import canonical_offsets, static_and_varying

    body, g, seqs = scene
    m = _set_up(body, g, {})
    seq = seqs[0]
    T, V = seq.n_frames, g.n_vertices
    rng = torch.Generator().manual_seed(0)
    fixed = 0.01 * torch.randn(1, V, 3, generator=rng).expand(T, V, 3)
    moving = 0.01 * torch.randn(T, V, 3, generator=rng)
    moving = moving - moving[seq.n_transition :].mean(0)  # zero time mean over the frames after the transition
    drape = m.skinned((fixed + moving).reshape(1, T, -1), m._sequence_betas(seq), seq)
    torch.testing.assert_close(canonical_offsets(m, seq, drape), fixed + moving, atol=1e-5, rtol=0)
    parts = static_and_varying(m, seq, drape)
    torch.testing.assert_close(parts["static part"], m.skinned(fixed.reshape(1, T, -1), m._sequence_betas(seq), seq), atol=1e-5, rtol=0)
    torch.testing.assert_close(parts["varying part"], m.skinned(moving.reshape(1, T, -1), m._sequence_betas(seq), seq), atol=1e-5, rtol=0)


def test_the_diagnostic_sees_a_saturated_trunk(scene):
    """methods.gaps.diagnose.trunk_state: a fresh GRU is not saturated and follows the motion; one whose
    candidate biases are pushed far out outputs +-1 whatever the frame, and its output layer sees a constant."""
    from methods.gaps.diagnose import trunk_state

    body, g, seqs = scene
    m = _set_up(body, g, {})
    with torch.no_grad():
        m.net.out.weight.normal_(0.0, 1e-3)
    fresh = trunk_state(m, seqs[0])
    assert fresh["saturated"] == 0.0 and fresh["std over frames of y"] > 1e-4 and fresh["std over frames of W y (mm)"] > 1e-4
    H = m.p["hidden"]
    with torch.no_grad():
        for layer in range(m.p["layers"]):
            getattr(m.net.gru, f"bias_ih_l{layer}")[2 * H :] = 50.0  # the candidate state n = tanh(50 + ...)
            getattr(m.net.gru, f"bias_ih_l{layer}")[H : 2 * H] = -50.0  # update gate z = 0: h = n
    saturated = trunk_state(m, seqs[0])
    assert saturated["saturated"] == 1.0 and saturated["mean |y|"] > 0.99
    assert saturated["std over frames of W y (mm)"] < 1e-3 * fresh["std over frames of W y (mm)"]


def test_the_diagnostic_scores_a_loss_optimum_drape_beside_the_run(scene, tmp_path, monkeypatch):
    """methods.gaps.diagnose.run_terms with an optimum run: its drape gets a row of the same terms (here the
    untrained drape written as the optimum's prediction scores as the untrained row); a drape of another
    scene, or a training motion with it, is refused."""
    import types

    import drapebench.trained_run
    from drapebench.results import write_prediction
    from methods.gaps.diagnose import run_terms

    body, g, seqs = scene
    m = _set_up(body, g, {})
    seq = seqs[0]
    reference = m.untrained_drape(seq) + torch.tensor([0.0, 0.0, 0.01])  # 10 mm above the untrained drape
    run = types.SimpleNamespace(method=m, seq=seq, garment=g, reference=lambda: reference)
    monkeypatch.setattr(drapebench.trained_run, "load_run", lambda run_dir: run)
    write_prediction(tmp_path / "prediction.h5", m.untrained_drape(seq), g.faces)
    table, _, _ = run_terms("run", optimum_run=tmp_path)
    rows = table.set_index("drape")
    assert rows.loc["loss optimum", "total"] == pytest.approx(rows.loc["untrained", "total"], rel=1e-4)
    assert rows.loc["untrained", "error (mm)"] == pytest.approx(10.0, rel=1e-4)
    assert rows.loc["loss optimum, static part", "error (mm)"] == pytest.approx(10.0, rel=1e-4)  # no move: both parts are the start
    assert rows.loc["loss optimum, varying part", "total"] == pytest.approx(rows.loc["untrained", "total"], rel=1e-4)
    write_prediction(tmp_path / "prediction.h5", m.untrained_drape(seq)[:5], g.faces)
    with pytest.raises(ValueError, match="is not of"):
        run_terms("run", optimum_run=tmp_path)
    with pytest.raises(ValueError, match="training-motion"):
        run_terms("run", training_motion="walk", optimum_run=tmp_path)


def test_a_relaxed_canonical_garment_lowers_the_loss_at_rest_and_is_multilinear_in_the_shape(scene, monkeypatch):
    """canonical: relaxed (methods.gaps.canonical): each grid solve lowers GAPS's loss on the rest-pose body; the
    relaxation is exact at every grid point, a corner included (two components' relaxations do not add), multilinear
    between them and clamped outside; the canonical garment is template + transfer + relaxation; a second set-up
    reads the cache instead of solving again."""
    import methods.gaps.canonical as canonical

    body, g, _ = scene
    cfg = {"canonical": "relaxed", "relax_iterations": 10, "relax_grid": [-2.0, 0.0, 2.0], "relax_components": 2}
    m = _set_up(body, g, cfg)
    rel = m.relaxed
    assert rel.d.shape == (9, g.n_vertices, 3) and np.all(rel.loss_end <= rel.loss_start)
    corner = 8  # (2, 2): the last grid point
    assert rel.loss_end[corner] < 0.9 * rel.loss_start[corner]  # the shape transfer's stretch is relaxed
    b = torch.zeros(4, body.n_betas)
    b[0, :2] = torch.tensor([2.0, 2.0])
    b[1, :2] = torch.tensor([1.0, 2.0])  # halfway between (0, 2) and (2, 2)
    b[2, :2] = torch.tensor([5.0, 2.0])  # outside: clamped to (2, 2)
    b[3, :3] = torch.tensor([2.0, 2.0, 1.0])  # a component beyond relax_components does not enter
    d = rel.at(b)
    solved, _, _ = canonical.relax_at(m, b[0], 10)
    torch.testing.assert_close(d[0], solved, atol=1e-6, rtol=0)
    torch.testing.assert_close(d[1], 0.5 * (rel.d[5] + rel.d[8]), atol=1e-6, rtol=0)
    torch.testing.assert_close(d[2], d[0])
    torch.testing.assert_close(d[3], d[0])
    assert (rel.d[2] + rel.d[6] - rel.d[4] - rel.d[8]).norm(dim=-1).mean() > 1e-4  # not additive: a grid is needed
    zero = torch.zeros(1, 1, 3 * g.n_vertices)
    torch.testing.assert_close(m._canonical(zero, b[:1])[0, 0] - m._canonical(zero, b[:1], relaxed=False)[0, 0], solved.float(), atol=1e-6, rtol=0)
    monkeypatch.setattr(canonical, "relax_at", lambda *a: pytest.fail("solved again instead of reading the cache"))
    again = _set_up(body, g, cfg)
    torch.testing.assert_close(again.relaxed.d, rel.d)
    with pytest.raises(ValueError, match="relax_grid"):
        _set_up(body, g, {**cfg, "relax_grid": [0.0]})


def test_the_relaxation_keeps_its_clearance_and_an_ablation_of_inext_can_share_gaps_s_canonical_garment(scene):
    """relax_clearance is the collision margin of the rest solves: a larger one leaves the relaxed garment farther
    from the rest-pose body. relax_inextensibility_weight puts L_inext back into the solves of a model trained
    without it: its canonical garment is then GAPS's; without it the garment relaxes under its own loss."""
    body, g, _ = scene
    base = {"canonical": "relaxed", "relax_iterations": 10, "relax_grid": [0.0, 2.0], "relax_components": 1}
    b = torch.zeros(1, body.n_betas)
    b[0, 0] = 2.0
    zero = torch.zeros(1, 1, 3 * g.n_vertices)

    def clearance_mm(m):  # mean signed distance (mm) to the rest-pose body of the 10 % closest vertices
        rest = body.shaped(m.garment_betas[None] + b)[0][0]
        d = signed_distance(m._canonical(zero, m.garment_betas[None] + b)[0, 0], rest, body.faces, exact=True, outer_faces=body.outer_faces).flatten()
        return 1e3 * float(d.sort().values[: len(d) // 10].mean())

    near, far = (_set_up(body, g, {**base, "relax_clearance": c}) for c in (2e-3, 1.5e-2))
    assert clearance_mm(far) > clearance_mm(near) + 1.0
    gaps = _set_up(body, g, base)
    no_inext = {**base, "inextensibility_weight": 0.0}
    shared = _set_up(body, g, {**no_inext, "relax_inextensibility_weight": 2e8})
    torch.testing.assert_close(shared.relaxed.d, gaps.relaxed.d)
    own = _set_up(body, g, no_inext)
    assert (own.relaxed.d - gaps.relaxed.d).norm(dim=-1).mean() > 1e-4


def test_clip_table_reads_the_steps_gradient_norms_and_the_clips_binding_rate(tmp_path):
    """methods.gaps.diagnose.clip_table: quantiles of the logged norms; the share of steps whose global norm is above
    the clip (those the clip scales down)."""
    from methods.gaps.diagnose import clip_table

    norms = np.arange(1.0, 11.0)
    pd.DataFrame({"step": np.arange(10), "grad_norm": norms, "grad_norm_output": norms / 2}).to_csv(tmp_path / "losses.csv", index=False)
    t = clip_table(tmp_path / "losses.csv", 8.5).set_index("norm")
    assert t.loc["grad_norm", "clipped share"] == pytest.approx(0.2) and t.loc["grad_norm", "max"] == 10.0
    assert t.loc["grad_norm_output", "p50"] == pytest.approx(np.median(norms / 2)) and np.isnan(t.loc["grad_norm_output", "clipped share"])
