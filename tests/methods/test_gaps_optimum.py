"""gaps_optimum: GAPS's training loss minimised over the vertices (drapebench.optimum) is the training
loss, the solver lowers it, and every term shapes the optimum."""

import numpy as np
import pytest
import torch

import methods
from drapebench.body import make_sequence
from drapebench.data import TrainData
from drapebench.garments import make_garment
from drapebench.optimum import minimise, optimise_sequence, sequence_terms
from drapebench.physics import Material
from drapebench.train.trainer import Step

MEAN_BODY = {"train": {"beta_range": [0.0]}}  # training draws the sequence's (mean) body shape


@pytest.fixture(scope="module")
def scene(body_lowres):
    """The coarse skirt (about 700 vertices) on 6 frames of a walk, moving from frame 3 on."""
    return body_lowres, make_garment("skirt", body_lowres, resolution=0.03), make_sequence("walk", 6, seed=0, transition=3)


@pytest.fixture(autouse=True)
def _data_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("DRAPEBENCH_DATA", str(tmp_path))


def _optimum(body, g, cfg=None):
    """A gaps_optimum bound to ``body`` with its constants for ``g``."""
    m = methods.get("gaps_optimum")(cfg)
    m.bind(body, Material())
    m._setup(g)
    return m


def test_the_loss_at_the_start_is_the_training_loss_of_a_zero_network_output(scene):
    body, g, seq = scene
    gaps = methods.get("gaps")(MEAN_BODY)
    gaps.fit(TrainData(body=body, material=Material(), garment=g, load_train=lambda: [seq]), {"epochs": 0})
    assert torch.count_nonzero(gaps.net.out.weight) == 0 and torch.count_nonzero(gaps.net.out.bias) == 0
    epoch, ramp = 2, gaps.p["train"]["kext_ramp_epochs"]
    first = 2  # the window of frames 2..4 (training window index 1): the body starts to walk, inertia is not zero
    batch = gaps._batch(np.array([first - 1]), Step(0, epoch, np.random.default_rng(0)))
    trained = gaps._loss_terms(batch, Step(0, epoch, np.random.default_rng(0)))
    m = _optimum(body, g, {**MEAN_BODY, "optimum": {"kext_epoch": epoch}})
    assert m.kext_epoch() == epoch and _optimum(body, g, MEAN_BODY).kext_epoch() == ramp  # default: k_ext's final value
    total, terms = m.window_loss(seq, epoch)(first + 2, m.untrained_drape(seq)[first : first + 3])
    assert list(terms) == list(trained) == ["strain", "bending", "gravity", "collision", "inertia", "inext"]
    for k in trained:
        assert torch.allclose(terms[k], trained[k], rtol=1e-4, atol=1e-9), (k, terms[k], trained[k])
    assert trained["inertia"] > 0 and trained["inext"] > 0
    assert torch.allclose(total, sum(trained.values()), rtol=1e-4)


@pytest.mark.parametrize("solver,lr", [("lbfgs", 1.0), ("adam", 1e-3)])
def test_the_solver_lowers_the_loss_from_the_start_and_stays_finite(scene, solver, lr):
    body, g, seq = scene
    m = _optimum(body, g)
    res = optimise_sequence(m.window_loss(seq, m.kext_epoch()), m.untrained_drape(seq)[:5], 3, solver, 15, lr)
    start = np.array([sum(t.values()) for t in res.start_terms])
    final = np.array([sum(t.values()) for t in res.final_terms])
    assert torch.isfinite(res.vertices).all() and np.isfinite(final).all()
    assert (final <= start + 1e-6).all() and (final[3:] < 0.8 * start[3:]).all(), (start, final)  # moving frames: much lower
    loss = m.window_loss(seq, m.kext_epoch())
    scored = sequence_terms(loss, res.vertices, 3)  # from frame 1 on, the windows the optimum's final terms score
    assert len(scored) == 5 and all(scored[t] == pytest.approx(res.final_terms[t], rel=1e-5) for t in range(1, 5))
    assert sequence_terms(loss, m.untrained_drape(seq)[:5], 3)[0] == pytest.approx(res.start_terms[0], rel=1e-5)


def test_the_method_drapes_without_training_and_keeps_no_state(scene):
    body, g, seq = scene
    m = methods.get("gaps_optimum")({"optimum": {"iterations": 3}})
    assert m.fit(TrainData(body=body, material=Material(), garment=g, load_train=lambda: []), {}).n_steps == 0
    res = m.drape(g, seq.slice(0, 2))
    assert res.vertices.shape == (2, g.n_vertices, 3) and torch.isfinite(res.vertices).all()
    assert set(res.timings_ms) == {"setup", "skinning", "optimum"} and res.extras["start"].shape == res.vertices.shape
    assert m.state_dict() == {}
    with pytest.raises(ValueError, match=r"unknown gaps_optimum optimum parameter\(s\) \[.iters.\] \(method.params.optimum\)"):
        methods.get("gaps_optimum")({"optimum": {"iters": 3}})
    with pytest.raises(ValueError, match="solver must be one of"):
        methods.get("gaps_optimum")({"optimum": {"solver": "sgd"}})


def test_every_term_shapes_the_optimum(scene):
    """Dropping any term, or flipping its sign, moves the optimum of a moving frame: no term is inert in it
    (with a 2 cm collision margin, so that the loose skirt is within it). The inextensibility term's
    |det| has a kink at its minimum, so the solver stops short of a stationary point and the weak bending
    term moves the drape by tenths of a micrometre only: the bound is 0.1 um (float32 resolves 0.06 um at 1 m)."""
    body, g, seq = scene
    m = _optimum(body, g, {"collision_eps": 0.02})
    loss, t = m.window_loss(seq, m.kext_epoch()), 5
    start = m.untrained_drape(seq)
    before = start[t - 2 : t]

    def solve(sign: dict):
        def f(x):
            terms = loss(t, torch.cat([before, x[None]]))[1]
            return sum(sign.get(k, 1.0) * v for k, v in terms.items())

        return minimise(f, start[t], "lbfgs", 10)[0]

    full = solve({})
    assert torch.equal(solve({}), full)  # deterministic: any change below is the term's
    for k in loss(t, torch.cat([before, full[None]]))[1]:
        for sign in (0.0, -1.0):
            moved = (solve({k: sign}) - full).norm(dim=-1).max()
            assert not moved < 1e-7, (k, sign, moved)  # NaN (a flipped term can diverge) counts as moved


def test_a_run_scores_its_own_loss_below_its_start_at_the_optimum_and_level_with_it_untrained(scene):
    """``gaps_loss`` (the drape's own loss) and ``gaps_loss@untrained``, the report's loss gap: the optimum below its
    start, a network still at its zero output level with it."""
    body, g, seq = scene
    m = methods.get("gaps_optimum")({"optimum": {"iterations": 5}})
    m.fit(TrainData(body=body, material=Material(), garment=g, load_train=lambda: []), {})
    scores = m.diagnostics(g, seq, m.drape(g, seq))
    assert scores["gaps_loss"] < 0.9 * scores["gaps_loss@untrained"], scores
    loss = m.window_loss(seq, m.kext_epoch())
    by_hand = np.mean([sum(t.values()) for t in sequence_terms(loss, m.untrained_drape(seq), 3)[seq.n_transition :]])
    assert scores["gaps_loss@untrained"] == pytest.approx(by_hand, rel=1e-6)
    gaps = methods.get("gaps")(MEAN_BODY)
    gaps.fit(TrainData(body=body, material=Material(), garment=g, load_train=lambda: [seq]), {"epochs": 0})
    untrained = gaps.diagnostics(g, seq, gaps.drape(g, seq))
    assert untrained["gaps_loss"] == pytest.approx(untrained["gaps_loss@untrained"], rel=1e-6)


def test_a_training_window_feeds_the_network_what_a_drape_of_its_sequence_does(scene):
    """The training batch's network input (betas, poses, root velocity of a window) is the input a drape of the same
    sequence gives at those frames; its last three columns are the root velocity (m/s)."""
    from methods.gaps.method import root_velocity

    body, g, seq = scene
    gaps = methods.get("gaps")(MEAN_BODY)
    gaps.fit(TrainData(body=body, material=Material(), garment=g, load_train=lambda: [seq]), {"epochs": 0})
    W, (_, t) = gaps.p["train"]["window"], gaps._windows[1]
    betas, pose, vel, *_ = gaps._batch(np.array([1]), Step(0, 0, np.random.default_rng(0)))
    drape_inputs = gaps.sequence_inputs(seq)  # (1, T, S + 3J + 3)
    torch.testing.assert_close(gaps._inputs(betas, pose, vel), drape_inputs[:, t : t + W])
    velocity = root_velocity(seq).to(drape_inputs.dtype)
    assert not torch.equal(velocity[t : t + W], velocity[t - 1 : t + W - 1])  # the window sees the body start to move
    raw = drape_inputs * gaps.input_std + gaps.input_mean if gaps.p["normalize_inputs"] else drape_inputs
    torch.testing.assert_close(raw[0, :, -3:], velocity, atol=1e-5, rtol=1e-5)
