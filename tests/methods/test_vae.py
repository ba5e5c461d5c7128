"""The VAE collision model: the motion descriptor, the garment model and its projection (Eq. 7-12), the VAE
and regressor losses (Eq. 13-18), and a tiny end-to-end fit whose state round-trips through a checkpoint.

The diffused body and the canonical SDF are stand-ins here (nearest-vertex values, a sphere), so these
tests check the method's own code; tests/body holds those of the fitted fields."""

import math

import pytest
import torch

from drapebench.body import load_body, make_sequence
from drapebench.body.lbs import axis_angle_to_matrix
from drapebench.geometry.proximity import nearest_indices
from drapebench.geometry.topology import get_topology
from methods.vae import losses
from methods.vae.config import vae_params
from methods.vae.descriptor import derivative, euler_zxy, generated_poses, motion_descriptor, unwrap
from methods.vae.garment_model import garment_model, pose_garments
from methods.vae.network import GarmentVAE
from methods.vae.projection import project_sequences, projection_terms
from tests.meshes import grid_mesh


class NearestDiffused:
    """Stand-in diffused body: the values of the nearest canonical body vertex."""

    def __init__(self, body):
        self.body = body
        self.rest = body.shaped()[0][0]

    def _nn(self, p):
        flat = p.reshape(-1, 3)
        return nearest_indices(flat[None].detach(), self.rest[None])[0].reshape(p.shape[:-1])

    def weights(self, p):
        return self.body.weights[self._nn(p)]

    def shape_offsets(self, p, betas):
        dirs = self.body.shapedirs[self._nn(p)][..., : betas.shape[-1]]
        return torch.einsum("...cs,...s->...c", dirs, betas)

    def weights_and_shape_offsets(self, p, betas):
        return self.weights(p), self.shape_offsets(p, betas.expand(*p.shape[:-1], -1))


class SphereSDF:
    """Signed distance (m) to a sphere of radius r at c."""

    def __init__(self, c=(0.0, 0.0, 1.0), r=0.2):
        self.c, self.r = torch.tensor(c), r

    def __call__(self, p):
        return (p - self.c).norm(dim=-1) - self.r


@pytest.fixture(scope="module")
def body():
    return load_body("anny_lowres")


def _rot(axis, angle):
    aa = torch.zeros(3)
    aa["xyz".index(axis)] = angle
    return axis_angle_to_matrix(aa)


def test_euler_zxy_recovers_the_angles_and_unwrap_removes_the_2pi_jumps():
    a, b, c = 0.7, -0.4, 1.1
    R = _rot("z", a) @ _rot("x", b) @ _rot("y", c)
    assert torch.allclose(euler_zxy(R), torch.tensor([a, b, c]), atol=1e-5)
    angles = torch.tensor([3.0, 3.1, -3.1, -3.0])[:, None]  # crossing pi
    steps = torch.diff(unwrap(angles), dim=0)
    assert torch.allclose(steps, torch.tensor([[0.1], [2 * math.pi - 6.2], [0.1]]), atol=1e-5)


def test_the_descriptor_holds_velocities_and_accelerations_at_the_frame_rate():
    x = torch.arange(5.0)[:, None] * 0.1  # 0.1 m per frame
    assert torch.allclose(derivative(x, 30.0)[1:], torch.full((4, 1), 3.0))  # m/s
    seq = make_sequence("walk", 20, fps=30.0, seed=1)
    d = motion_descriptor(seq, seq.betas)
    P = 3 * (seq.poses.shape[1] - 1)
    assert d.shape == (seq.n_frames, 3 * P + 12 + len(seq.betas))
    v_H = d[:, 3 * P : 3 * P + 3]
    assert torch.allclose(v_H[1:], torch.diff(seq.trans, dim=0) * 30.0, atol=1e-5)
    code = lambda R: R.flatten(-3)[..., :4]  # noqa: E731 - any pose code of 4 values
    assert motion_descriptor(seq, seq.betas, code).shape[1] == 3 * 4 + 12 + len(seq.betas)
    vertical = motion_descriptor(seq, seq.betas[:0], code, root="vertical")  # heading-invariant, no shape
    assert vertical.shape[1] == 3 * 4 + 2 + 6
    torch.testing.assert_close(vertical[:, 12], motion_descriptor(seq, seq.betas, code)[:, 14])  # the vertical velocity


def _posed_frames(body, X, seq, diffused):
    betas = seq.betas[None, : body.n_betas].expand(seq.n_frames, -1)
    with torch.no_grad():
        return garment_model(diffused, X[None].expand(seq.n_frames, -1, -1), betas, seq.transforms(body))


def _garment_near(body, n=6):
    """A small sheet in front of the chest of the canonical body: vertices (V, 3), Topology."""
    V, F = grid_mesh(n, 0.2)
    rest = body.shaped()[0][0]
    front = rest[:, 1].min() - 0.03  # the body faces -Y
    chest = rest[:, 2].max() * 0.72
    V = torch.as_tensor(V, dtype=torch.float32)
    X = torch.stack([V[:, 0], torch.full_like(V[:, 0], float(front)), V[:, 1] + float(chest)], -1)
    return X, get_topology(X.numpy(), F)


def test_projection_then_unprojection_returns_the_simulated_frames(body):
    diffused = NearestDiffused(body)
    X, topo = _garment_near(body)
    seq = make_sequence("walk", 6, seed=2, betas=[0.5, -0.5, 0, 0], transition=2)
    frames = _posed_frames(body, X + torch.tensor([0.003, -0.004, 0.002]), seq, diffused)  # moved off the template, unstrained
    cfg = vae_params(None)["projection"]  # the defaults: warm start from the previous frame, 40 steps per frame
    far = SphereSDF(c=(5.0, 5.0, 5.0), r=0.1)  # no collisions: the data term alone decides
    p = project_sequences(diffused, far, topo, X, frames[None], seq.betas[None, : body.n_betas], seq.transforms(body)[None], cfg)
    assert p.X.shape == (1, seq.n_frames, len(X), 3)
    assert p.residual_mm.max() < 0.5  # unprojected projection within 0.5 mm of the simulated frame
    again = _posed_frames(body, p.X[0, -1], seq, diffused)[-1]
    assert (again - frames[-1]).norm(dim=-1).max() < 2e-3


def test_the_projection_collision_term_pushes_vertices_out_of_the_canonical_body(body):
    diffused = NearestDiffused(body)
    X, topo = _garment_near(body)
    seq = make_sequence("static", 2, seed=0, transition=0)
    frames = _posed_frames(body, X, seq, diffused)
    sdf = SphereSDF(c=tuple((X.mean(0) + torch.tensor([0.0, 0.025, 0.0])).tolist()), r=0.04)  # a bump of the body through the sheet
    cfg = {**vae_params(None)["projection"], "steps": 30, "lr": 1e-3, "collision_weight": 50.0}
    args = (diffused, sdf, topo, X, frames[None], seq.betas[None, : body.n_betas], seq.transforms(body)[None])
    with_c = project_sequences(*args, cfg)
    without = project_sequences(*args, {**cfg, "collision_weight": 0.0})
    assert with_c.colliding[0, -1] < 0.5 * without.colliding[0, -1]
    assert without.colliding[0, -1] > 0


def test_the_collision_term_is_zero_outside_and_positive_inside():
    sdf = SphereSDF(c=(0.0, 0.0, 0.0), r=0.1)
    outside = torch.tensor([[[0.2, 0.0, 0.0], [0.0, 0.15, 0.0]]])
    inside = torch.tensor([[[0.05, 0.0, 0.0], [0.0, 0.2, 0.0]]])
    assert losses.collision(sdf, outside, 0.002) == 0
    assert losses.collision(sdf, inside, 0.002) == pytest.approx(1e3 * (0.002 + 0.05) / 2, rel=1e-4)  # mm, mean over vertices


def _vae_terms(p_overrides, X, topo, sdf):
    p = {**vae_params(None)["vae"], **p_overrides}
    torch.manual_seed(0)
    vae = GarmentVAE(len(X[0]), p["latent"], (16, 8))
    with torch.no_grad():
        vae.mean.copy_(X.mean(0))
        vae.scale.fill_(0.01)
    return losses.vae_terms(vae, sdf, topo, X, p, 0.002, torch.Generator().manual_seed(0)), vae


def test_vae_terms_follow_eq13_to_16(body):
    X0, topo = _garment_near(body, 4)
    X = X0[None] + 0.01 * torch.randn(3, *X0.shape, generator=torch.Generator().manual_seed(0))
    inside_all = SphereSDF(c=tuple(X0.mean(0).tolist()), r=1.0)  # every vertex inside: both collision terms positive
    terms, vae = _vae_terms({}, X, topo, inside_all)
    assert set(terms) == {"reconstruction", "laplacian", "kl", "collision", "collision_sampled"}
    assert all(v > 0 for v in terms.values())
    no_self, _ = _vae_terms({"selfsup": False}, X, topo, inside_all)
    assert "collision_sampled" not in no_self and "collision" in no_self
    no_coll, _ = _vae_terms({"collision": 0.0}, X, topo, inside_all)
    assert "collision" not in no_coll
    with torch.no_grad():
        mu, logvar = vae.encode(X)
    with torch.no_grad():
        kl = -0.5 * (1 + logvar - mu**2 - logvar.exp()).sum(-1)
    assert float(terms["kl"].detach()) == pytest.approx(vae_params(None)["vae"]["kl"] * float(kl.mean()), rel=1e-5)


def test_the_reparameterisation_draws_codes_with_the_posteriors_std():
    """z = mu + eps exp(logvar / 2): a posterior of variance 4 gives codes of std 2 around its mean."""
    import math

    class Posterior:  # encodes every garment to N(1, 4 I); decode records the codes it is given
        def encode(self, X):
            return torch.ones(len(X), 8), torch.full((len(X), 8), math.log(4.0))

        def decode(self, z):
            self.z = z
            return torch.zeros(len(z), 1, 3)

    vae = Posterior()
    losses.vae_terms(vae, None, None, torch.zeros(20000, 1, 3), {"laplacian": 0, "kl": 0, "collision": 0}, 0.0,
                     torch.Generator().manual_seed(0))  # fmt: skip
    assert vae.z.mean().item() == pytest.approx(1.0, abs=0.02) and vae.z.std().item() == pytest.approx(2.0, abs=0.02)


def test_regressor_terms_penalise_positions_velocities_and_accelerations():
    target = torch.arange(6.0)[None, :, None].expand(2, 6, 3) ** 2  # a moving target: a velocity and an acceleration
    offset = target + 1.0  # right velocity and acceleration, wrong position
    terms = losses.regressor_terms(offset, target, {"velocity": 1.0, "acceleration": 1.0})
    assert terms["position"] == pytest.approx(1.0) and terms["velocity"] == 0 and terms["acceleration"] == 0
    ramp = target + torch.arange(6.0)[None, :, None]  # a velocity error of 1 per frame
    terms = losses.regressor_terms(ramp, target, {"velocity": 2.0, "acceleration": 1.0})
    assert terms["velocity"] == pytest.approx(2.0) and terms["acceleration"] == 0


def test_unknown_and_invalid_parameters_are_named():
    with pytest.raises(ValueError, match="unknown vae parameter"):
        vae_params({"latnet": 3})
    with pytest.raises(ValueError, match="regressor.pose must be one of learned, rotations"):
        vae_params({"regressor": {"pose": "quaternions"}})
    with pytest.raises(ValueError, match="regressor.select must be one of validation, last"):
        vae_params({"regressor": {"select": "best"}})
    with pytest.raises(ValueError, match="regressor.window_stride must be >= 1"):
        vae_params({"regressor": {"window_stride": 0}})


def test_generated_poses_cover_each_motion_kind_once_per_sequence():
    poses = generated_poses(["walk", "dance", "walk"], 2, n_frames=5, transition=3, fps=30.0)
    assert poses.shape == (2 * 2 * 8, 22, 3) and torch.isfinite(poses).all()
    assert torch.equal(poses, generated_poses(["dance", "walk"], 2, 5, 3, 30.0))  # fixed seeds, kinds in order
    assert not torch.equal(poses[:8], poses[8:16])  # two sequences of a kind differ
    assert generated_poses([], 2, 5, 3, 30.0).shape == (0, 22, 3)


def _tiny_scene(body):
    """A small sheet garment, three short sequences and 'reference' drapes: the template posed by the
    stand-in diffused body with a time-varying ripple."""
    from types import SimpleNamespace

    from drapebench.data import References, TrainData
    from drapebench.physics import Material

    X, topo = _garment_near(body, 5)
    garment = SimpleNamespace(name="sheet", vertices=X, faces=topo.faces, topology=topo, betas=torch.zeros(10), n_vertices=len(X))
    diffused = NearestDiffused(body)
    seqs = [make_sequence(m, 8, seed=i, betas=[0.3 * i, 0, 0, 0], transition=2) for i, m in enumerate(["walk", "squat", "run"])]
    drapes = {}
    for s in seqs:
        t = torch.arange(s.n_frames, dtype=torch.float32)[:, None, None]
        wiggle = 0.003 * torch.sin(0.5 * t + 20 * X[None, :, :1])
        drapes[s.name] = _posed_frames(body, X, s, diffused) + wiggle
    refs = References(lambda g, s: drapes.get(s.name))
    data = TrainData(body, Material(), garment, load_train=lambda: seqs, references=refs)
    return garment, data, diffused, seqs


TINY = {"val_sequences": 1, "projection": {"steps": 3}, "vae": {"hidden": [16], "latent": 4, "steps": 12, "samples": 2},
        "regressor": {"hidden": 8, "layers": 1, "window": 4, "pose_steps": 5,
                      "schedule": {"epochs": 2, "batch_size": 4, "lr_switch_epoch": None}}}  # fmt: skip


def _tiny_model(body, diffused, sdf, cfg=TINY):
    from methods.vae import VAEModel

    m = VAEModel(cfg)
    m.diffused, m.sdf = diffused, sdf  # stand-ins: _body_fields keeps fields that are set
    return m


def test_a_tiny_fit_drapes_and_its_state_round_trips(body, tmp_path):
    garment, data, diffused, seqs = _tiny_scene(body)
    sdf = SphereSDF(c=(5.0, 5.0, 5.0), r=0.1)
    m = _tiny_model(body, diffused, sdf)
    report = m.fit(data, {"seed": 0, "log_dir": str(tmp_path)})
    assert {h["stage"] for h in report.history} == {"vae", "pose", "regressor"}
    assert all((tmp_path / stage / f).exists() for stage in ("vae", "regressor") for f in ("losses.csv", "evaluations.csv"))
    assert [e["epoch"] for e in m.evaluations][:2] == [0, 1]
    assert m.projection_stats["residual_mm"] < 5.0
    test = make_sequence("kick", 6, seed=9, transition=2)
    out = m.drape(garment, test)
    assert out.vertices.shape == (test.n_frames, garment.n_vertices, 3) and torch.isfinite(out.vertices).all()
    assert {"regressor", "decoder", "projection"} <= set(out.timings_ms)
    canonical = out.extras["canonical"]  # posed in chunks of frames: the same as all frames at once
    betas = body.full_betas(test.betas)[None].expand(len(canonical), -1)
    torch.testing.assert_close(out.vertices, garment_model(diffused, canonical, betas, test.transforms(body)))
    assert report.evaluations == m.evaluations  # what the run writes to evaluations.csv
    assert {"posterior_sigma", "code_std", "code_norm", "kl_per_sample", "sampled_codes_colliding_pct"} <= set(m.evaluations[-1])
    state = m.state_dict()
    again = _tiny_model(body, diffused, sdf)
    again.bind(body, data.material)
    again.load_state_dict(state)
    assert torch.equal(again.drape(garment, test).vertices, out.vertices)
    rotations = _tiny_model(body, diffused, sdf, {**TINY, "regressor": {**TINY["regressor"], "pose": "rotations"}})
    rotations.fit(data, {"seed": 0})
    assert rotations.pose is None and rotations.drape(garment, test).vertices.shape == out.vertices.shape
    clear = m.diagnostics(garment, test, out)  # the sheet and the samples stay far from the body
    assert set(clear) == {"eps_c_canonical", "eps_c_canonical_std", "sampled_prior_pct", "sampled_prior3_pct", "sampled_codes_pct"}
    assert all(v == 0 for v in clear.values())
    inside = body.shaped()[0][0].mean(0) + 0.01 * torch.randn(garment.n_vertices, 3, generator=torch.Generator().manual_seed(0))
    with torch.no_grad():  # a decoder that puts every garment inside the torso
        m.vae.mean.copy_(inside)
        m.vae.scale.fill_(1e-6)
    hit = m.diagnostics(garment, test, m.drape(garment, test))
    assert hit["eps_c_canonical"] == 100 and hit["sampled_prior_pct"] == 100 and hit["sampled_codes_pct"] == 100


def test_the_mean_code_control_decodes_the_training_codes_mean_at_every_frame(body, tmp_path):
    garment, data, diffused, seqs = _tiny_scene(body)
    m = _tiny_model(body, diffused, SphereSDF(c=(5.0, 5.0, 5.0), r=0.1), {**TINY, "regressor": {**TINY["regressor"], "predict": "mean_code"}})
    report = m.fit(data, {"seed": 0})
    assert m.regressor is None and {h["stage"] for h in report.history} == {"vae"}
    trained = _tiny_model(body, diffused, m.sdf)  # the variant with a regressor: the same VAE, loaded, not trained again
    trained.fit(data, {"seed": 0, "log_dir": str(tmp_path)})
    assert all(torch.equal(a, b) for a, b in zip(trained.vae.state_dict().values(), m.vae.state_dict().values()))
    assert (tmp_path / "vae" / "losses.csv").exists() and trained.evaluations == m.evaluations
    other_seed = _tiny_model(body, diffused, m.sdf)
    other_seed.fit(data, {"seed": 1})
    assert not torch.equal(other_seed.vae.state_dict()["mu.weight"], m.vae.state_dict()["mu.weight"])
    test = make_sequence("kick", 6, seed=9, transition=2)
    out = m.drape(garment, test)
    with torch.no_grad():
        X = m.vae.decode(m.vae.code_mean[None])[0]
    torch.testing.assert_close(out.extras["canonical"], X.expand(test.n_frames, -1, -1))
    again = _tiny_model(body, diffused, m.sdf, m.cfg)
    again.bind(body, data.material)
    again.load_state_dict(m.state_dict())
    assert torch.equal(again.drape(garment, test).vertices, out.vertices)


def test_validation_sequences_are_spread_over_the_motion_kinds():
    from types import SimpleNamespace

    from methods.vae import VAEModel

    seqs = [SimpleNamespace(motion=k) for k in ["random"] * 3 + ["walk"] * 3 + ["dance"] * 3]
    m = VAEModel({"val_sequences": 4})
    train, val = m.validation_split(seqs)
    assert val == [1, 2, 5, 8] and sorted(train + val) == list(range(9))  # the last of each kind, then random's second last
    for bad in (0, 9):
        with pytest.raises(ValueError, match="val_sequences must be in"):
            VAEModel({"val_sequences": bad}).validation_split(seqs)


def test_dropout_acts_in_training_only_and_weight_decay_shrinks_the_regressor(body):
    from methods.vae.network import Regressor

    r = Regressor(5, 3, hidden=16, layers=2, dropout=0.5)
    x = torch.randn(2, 7, 5, generator=torch.Generator().manual_seed(0))
    r.eval()
    assert torch.equal(r(x)[0], r(x)[0])
    r.train()
    assert not torch.equal(r(x)[0], r(x)[0])
    garment, data, diffused, seqs = _tiny_scene(body)
    norms = {}
    for decay in (0.0, 10.0):
        schedule = {**TINY["regressor"]["schedule"], "epochs": 10, "lr": 5e-2}
        m = _tiny_model(body, diffused, SphereSDF(c=(5.0, 5.0, 5.0), r=0.1),
                        {**TINY, "regressor": {**TINY["regressor"], "weight_decay": decay, "schedule": schedule}})  # fmt: skip
        m.fit(data, {"seed": 0})
        with torch.no_grad():
            norms[decay] = float(sum(p.square().sum() for n, p in m.regressor.named_parameters() if "weight" in n))
    assert norms[10.0] < 0.9 * norms[0.0]


def test_the_regressor_keeps_the_epoch_of_lowest_validation_error(body):
    garment, data, diffused, seqs = _tiny_scene(body)
    cfg = {**TINY, "regressor": {**TINY["regressor"], "schedule": {**TINY["regressor"]["schedule"], "epochs": 20, "lr": 5e-2}}}
    m = _tiny_model(body, diffused, SphereSDF(c=(5.0, 5.0, 5.0), r=0.1), cfg)
    m.fit(data, {"seed": 0})
    T = seqs[0].n_frames
    codes = 3 + torch.randn(2, T, 4, generator=torch.Generator().manual_seed(0))  # training targets far from the code 0 ...
    with torch.no_grad():  # ... and validation garments decoded at the code 0: the validation error grows with training
        val_garments = m.vae.decode(torch.zeros(T, 4))[None]
    for select in ("validation", "last"):
        m.p["regressor"]["select"] = select
        res = m._train_regressor(seqs[:2], codes, {"seed": 0}, None, (seqs[2:], val_garments))
        errors = [e["val_error_mm"] for e in res.evaluations]
        with torch.no_grad():
            decoded = m.vae.decode(m.regressor(m._descriptor(seqs[2])[None])[0][0])
        final = 1e3 * float((decoded - val_garments[0]).norm(dim=-1).mean())
        assert final == pytest.approx(min(errors) if select == "validation" else errors[-1], rel=1e-5)
    assert len(errors) == 20 and min(errors) < 0.5 * errors[-1]  # the two choices keep different weights


class ShiftVAE(torch.nn.Module):
    """Stand-in VAE: every garment encodes to the code 0 (sigma ~ 0), and a code z decodes to ``X`` moved by
    ``shift`` (m per unit |z|) along -x: reconstructions are ``X``, latent samples away from 0 move."""

    def __init__(self, X, shift):
        super().__init__()
        self.X, self.shift, self.latent = X, shift, 3
        self.w = torch.nn.Parameter(torch.ones(()))  # something to take a gradient of

    def encode(self, X):
        return torch.zeros(len(X), self.latent), torch.full((len(X), self.latent), -30.0)

    def decode(self, z):
        move = torch.tensor([-1.0, 0.0, 0.0]) * self.shift * z.norm(dim=-1)[:, None, None]
        return self.w * (self.X[None] + move)


def _sphere_shell(r_out):
    """Points (20, 3) on the sphere of radius r_out around the origin (the SphereSDF below has radius 0.1)."""
    d = torch.nn.functional.normalize(torch.randn(20, 3, generator=torch.Generator().manual_seed(3)), dim=-1)
    return d * r_out


def test_both_collision_terms_are_zero_outside_the_body_and_positive_inside(body):
    sdf = SphereSDF(c=(0.0, 0.0, 0.0), r=0.1)
    p = {**vae_params(None)["vae"], "laplacian": 0.0, "kl": 0.0, "sample_scale": "prior"}
    topo = None  # no Laplacian term
    for r_out, positive in ((0.15, False), (0.05, True)):
        X = _sphere_shell(r_out)
        vae = ShiftVAE(X, 0.0)  # samples decode to X too
        terms = losses.vae_terms(vae, sdf, topo, X[None], p, 0.002, torch.Generator().manual_seed(0))
        assert (terms["collision"] > 0) == positive and (terms["collision_sampled"] > 0) == positive


def test_the_sampled_term_sees_the_decoded_samples():
    sdf = SphereSDF(c=(0.0, 0.0, 0.0), r=0.1)
    X = torch.tensor([[0.11, 0.0, 0.0], [0.0, 0.13, 0.0]])  # outside the sphere and its 2 mm margin
    p = {**vae_params(None)["vae"], "laplacian": 0.0, "kl": 0.0, "sample_scale": "prior"}  # samples away from the code 0
    calm = losses.vae_terms(ShiftVAE(X, 0.0), sdf, None, X[None], p, 0.002, torch.Generator().manual_seed(0))
    colliding = losses.vae_terms(ShiftVAE(X, 0.05), sdf, None, X[None], p, 0.002, torch.Generator().manual_seed(0))
    assert calm["collision"] == 0 and colliding["collision"] == 0  # the reconstructions (z = 0) stay outside
    assert calm["collision_sampled"] == 0 and colliding["collision_sampled"] > 0  # samples moved into the sphere


def test_latent_samples_are_drawn_where_the_codes_live():
    mu = torch.tensor([[4.0, -1.0], [6.0, -1.2], [5.0, -0.8]])
    z = losses.latent_samples(20000, mu, "codes", torch.Generator().manual_seed(0))
    torch.testing.assert_close(z.mean(0), mu.mean(0), atol=0.03, rtol=0)
    torch.testing.assert_close(z.std(0), mu.std(0), atol=0.03, rtol=0.02)
    assert losses.latent_samples(20000, mu, 3.0, torch.Generator().manual_seed(0)).std(0).min() > 2.9
    prior = losses.latent_samples(20000, mu, "prior", torch.Generator().manual_seed(0))  # N(0, I) whatever the codes
    assert prior.std(0).max() < 1.05 and prior.std(0).min() > 0.95 and prior.mean(0).abs().max() < 0.03
    with pytest.raises(ValueError, match="sample_scale"):
        vae_params({"vae": {"sample_scale": "wide"}})


def test_dropping_either_collision_term_changes_the_trained_decoder():
    sdf = SphereSDF(c=(0.0, 0.0, 0.0), r=0.1)
    X = _sphere_shell(0.105)[None] + 0.004 * torch.randn(16, 20, 3, generator=torch.Generator().manual_seed(1))
    topo = get_topology(X[0].numpy(), torch.tensor([[0, 1, 2]]).numpy())

    def trained(overrides):
        p = {**vae_params(None)["vae"], "sample_scale": "prior", **overrides}
        torch.manual_seed(0)
        vae = GarmentVAE(20, 4, (32,), p["logvar_init"])
        with torch.no_grad():
            vae.mean.copy_(X.mean(0))
            vae.scale.fill_(0.01)
        opt = torch.optim.Adam(vae.parameters(), lr=3e-3)
        gen = torch.Generator().manual_seed(0)
        for _ in range(60):
            loss = sum(losses.vae_terms(vae, sdf, topo, X, p, 0.002, gen).values())
            opt.zero_grad()
            loss.backward()
            opt.step()
        with torch.no_grad():
            recon = losses.collision(sdf, vae.decode(vae.encode(X)[0]), 0.002)
            sampled = losses.collision(sdf, vae.decode(3 * torch.randn(256, 4, generator=torch.Generator().manual_seed(5))), 0.002)
        return float(recon), float(sampled)

    full, no_selfsup, no_collision = trained({}), trained({"selfsup": False}), trained({"collision": 0.0})
    assert full[0] < no_collision[0]  # the reconstruction term pulls reconstructions out of the body
    assert full[1] < no_selfsup[1]  # the sampled term pulls decoded samples out of the body


def test_the_vertical_root_descriptor_ignores_the_heading():
    from dataclasses import replace

    from drapebench.body.lbs import matrix_to_axis_angle

    seq = make_sequence("walk", 20, fps=30.0, seed=1)
    turn = _rot("z", 1.2)
    poses = seq.poses.clone()
    poses[:, 0] = matrix_to_axis_angle(turn @ axis_angle_to_matrix(seq.poses[:, 0]))
    turned = replace(seq, poses=poses, trans=seq.trans @ turn.T)  # the same motion, walked in another direction
    same = lambda s, root: motion_descriptor(s, s.betas, root=root)  # noqa: E731
    torch.testing.assert_close(same(turned, "vertical"), same(seq, "vertical"), atol=2e-3, rtol=1e-3)
    assert not torch.allclose(same(turned, "world"), same(seq, "world"), atol=1e-2)


def test_the_descriptor_is_computed_on_the_device_of_the_body_shape():
    seq = make_sequence("walk", 10, seed=1)  # a sequence's poses stay on the CPU; the body (here "meta") may not
    assert motion_descriptor(seq, seq.betas.to("meta")).device.type == "meta"


def test_the_fig3_table_is_one_the_scoreboard_reads(tmp_path, monkeypatch):
    """methods.vae.projection_table writes a row per projection and a group per garment (its rows stubbed here)."""
    from drapebench.claims import read_table
    from methods.vae import projection_table

    def rows(garment, data):
        return [{"garment": garment, "projection": label, "sequences": 2, "frames": 120, "eps_c_canonical": 0.1 * k,
                 "eps_c_canonical_max": 0.2 * k, "reprojection_error_mm": 1.0 + k} for k, label in enumerate(projection_table.PROJECTIONS)]  # fmt: skip

    monkeypatch.setattr(projection_table, "projection_rows", rows)
    projection_table.main(["--garments", "tshirt,dress", "--out", str(tmp_path / "fig3")])
    table = read_table(tmp_path / "fig3.csv")
    assert table.rows() == list(projection_table.PROJECTIONS) and table.groups == ["tshirt", "dress"]
    assert table.get("inverse skinning", "dress", "ε_c canon. (%)").mean == 0.1
    assert table.get("optimised", "tshirt", "reproj. err. (mm)").mean == 1.0


def test_the_garment_model_poses_the_canonical_body_onto_the_shaped_posed_body(body):
    """Eq. 7-11 with betas != 0: the canonical body itself, shaped by its diffused offsets and skinned by its
    weights, is the posed body of that shape, by the projection's model and by the drape's alike."""
    diffused = NearestDiffused(body)
    seq = make_sequence("walk", 4, seed=2, betas=[1.5, -1.5, 0.5, 0.0], transition=0)
    X, betas = diffused.rest[None].expand(seq.n_frames, -1, -1), body.full_betas(seq.betas)
    with torch.no_grad():
        x = garment_model(diffused, X, betas[None].expand(seq.n_frames, -1), seq.transforms(body))
        y = pose_garments(diffused, X, betas, seq.transforms(body))
    torch.testing.assert_close(x, seq.vertices(body).to(x.dtype), atol=1e-4, rtol=0)
    torch.testing.assert_close(y, x, atol=1e-4, rtol=0)


def test_the_projection_strain_is_that_of_the_shaped_garment(body):
    """The projection's strain term measures T_G(X), the canonical garment moved to the frame's body shape."""
    diffused, (X, topo) = NearestDiffused(body), _garment_near(body)  # X unstrained: the topology's rest shape
    A = make_sequence("static", 1, seed=0, transition=0).transforms(body)
    cfg = {**vae_params(None)["projection"], "strain_weight": 1.0}
    strain = {k: float(projection_terms(diffused, SphereSDF(c=(5.0, 5.0, 5.0)), topo, X[None], X[None],
                                        body.full_betas(torch.tensor(b))[None], A, cfg)["strain"])
              for k, b in (("mean", [0.0]), ("shaped", [2.0, -2.0]))}  # fmt: skip
    assert strain["mean"] < 1e-6 and strain["shaped"] > 1e-3, strain


def test_the_descriptor_s_accelerations_are_the_derivatives_of_its_velocities():
    seq = make_sequence("walk", 20, fps=30.0, seed=1)
    d, P = motion_descriptor(seq, seq.betas[:0]), 3 * (seq.poses.shape[1] - 1)  # [phi, dphi, d2phi, dH, d2H, dK, d2K]
    torch.testing.assert_close(d[:, 2 * P : 3 * P], derivative(d[:, P : 2 * P], 30.0))
    torch.testing.assert_close(d[:, 3 * P + 3 : 3 * P + 6], derivative(d[:, 3 * P : 3 * P + 3], 30.0))
    assert d[2:, 2 * P : 3 * P].abs().max() > 0


def test_the_descriptor_s_heading_rate_has_no_2pi_jumps():
    """A body turning at a constant rate: the heading passes pi at frame 16, its rate stays constant."""
    from types import SimpleNamespace

    T, fps, rate = 40, 30.0, 0.2  # rad per frame about the vertical
    poses = torch.zeros(T, 22, 3)
    poses[:, 0, 2] = rate * torch.arange(T)
    d = motion_descriptor(SimpleNamespace(poses=poses, trans=torch.zeros(T, 3), fps=fps), torch.zeros(0))
    heading_rate = 3 * 3 * 21 + 6  # after phi, dphi, d2phi (3 x 21 joints x 3) and dH, d2H: dK's first angle, the heading
    torch.testing.assert_close(d[1:, heading_rate], torch.full((T - 1,), rate * fps), atol=1e-3, rtol=0)
