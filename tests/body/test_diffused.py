"""The diffused body model: Eq. 4-6 targets (exact on the surface, a partition of unity off it, mixing
across medial axes) and the fitted MLPs (reproduce the body's weights, partition of unity, cached)."""

import pytest
import torch

from drapebench.body import diffused as diffused_mod
from drapebench.body import BodyModel, fit_diffused_body
from drapebench.body.diffused import diffused_targets
from drapebench.body.fields import interpolate, sample_surface

TINY = dict(n_surface=3000, n_shell=2000, n_heldout=300, n_samples=8, steps=300, width=64, depth=2, n_frequencies=4)


def _leg_shares(body, weights):
    """Total weight (N,) of the left and of the right leg joints."""
    left = [body.joint_index(n) for n in ("left_hip", "left_knee", "left_ankle", "left_foot")]
    right = [body.joint_index(n) for n in ("right_hip", "right_knee", "right_ankle", "right_foot")]
    return weights[:, left].sum(-1), weights[:, right].sum(-1)


def test_body_vertices_with_one_sample_get_exactly_their_own_values(body_lowres):
    out = diffused_targets(body_lowres.v_template, body_lowres, n_samples=1, generator=torch.Generator().manual_seed(0))
    torch.testing.assert_close(out["weights"], body_lowres.weights, atol=1e-5, rtol=0)
    torch.testing.assert_close(out["shapedirs"], body_lowres.shapedirs, atol=1e-6, rtol=0)
    assert "posedirs" not in out  # the Anny bakes have no pose correctives


def test_surface_points_get_the_interpolated_surface_values(body_lowres):
    gen = torch.Generator().manual_seed(1)
    v, f = body_lowres.v_template, body_lowres.faces
    points, face, bary, _ = sample_surface(v, f, 500, gen)
    out = diffused_targets(points, body_lowres, n_samples=16, generator=gen)
    expect_w = interpolate(body_lowres.weights, f, face, bary)
    expect_s = interpolate(body_lowres.shapedirs.reshape(len(v), -1), f, face, bary).reshape(-1, 3, body_lowres.n_betas)
    torch.testing.assert_close(out["weights"], expect_w, atol=1e-4, rtol=0)
    torch.testing.assert_close(out["shapedirs"], expect_s, atol=1e-5, rtol=0)


def test_off_the_surface_the_weights_stay_a_partition_of_unity(body_lowres):
    gen = torch.Generator().manual_seed(2)
    points, _, _, normals = sample_surface(body_lowres.v_template, body_lowres.faces, 300, gen)
    points = torch.cat([points + 0.05 * normals, points - 0.01 * normals, 2 * torch.randn(20, 3, generator=gen)])
    w = diffused_targets(points, body_lowres, n_samples=16, generator=gen)["weights"]
    assert (w >= 0).all()
    torch.testing.assert_close(w.sum(-1), torch.ones(len(points)), atol=1e-5, rtol=0)


def test_a_point_between_the_knees_mixes_both_legs(body_lowres):
    knees = body_lowres().rest_joints[0, [body_lowres.joint_index("left_knee"), body_lowres.joint_index("right_knee")]]
    mid = knees.mean(0, keepdim=True)
    w = diffused_targets(mid, body_lowres, n_samples=256, generator=torch.Generator().manual_seed(3))["weights"]
    left, right = _leg_shares(body_lowres, w)
    assert left > 0.25 and right > 0.25, (float(left), float(right))
    torch.testing.assert_close(left + right, torch.ones(1), atol=0.05, rtol=0)


def test_the_sqrt_spread_reaches_farther_than_the_distance_spread(body_lowres):
    # 2 cm outside the left knee: sigma = 2 cm keeps the samples on the left leg; sigma = sqrt(0.02) = 14 cm
    # reaches the right leg
    knee = body_lowres().rest_joints[0, body_lowres.joint_index("left_knee")]
    v = body_lowres.v_template
    outer = v[torch.argmax(v[:, 0] - 10 * (v[:, 2] - knee[2]).abs())]
    point = (outer + torch.tensor([0.02, 0.0, 0.0]))[None]
    shares = {}
    for spread in ("distance", "sqrt_distance"):
        w = diffused_targets(point, body_lowres, n_samples=256, spread=spread, generator=torch.Generator().manual_seed(4))
        shares[spread] = float(_leg_shares(body_lowres, w["weights"])[1])
    assert shares["distance"] < 0.01 < shares["sqrt_distance"], shares
    with pytest.raises(ValueError, match="spread"):
        diffused_targets(point, body_lowres, spread="gauss")


@pytest.fixture(scope="module")
def fitted(body_lowres):
    return fit_diffused_body(body_lowres, TINY)


def test_the_fitted_model_reproduces_the_body_weights_on_the_surface(body_lowres, fitted):
    w = fitted.weights(body_lowres.v_template)
    error = (w - body_lowres.weights).abs().sum(-1).mean()  # sum_j |error| per vertex
    ignoring_position = (body_lowres.weights.mean(0) - body_lowres.weights).abs().sum(-1).mean()
    assert error < 0.3 < ignoring_position, (float(error), float(ignoring_position))
    offsets = fitted.shape_offsets(body_lowres.v_template, torch.ones(5))
    expect = body_lowres.shaped(torch.ones(1, 5))[0][0] - body_lowres.v_template
    assert (offsets - expect).norm(dim=-1).mean() < 0.25 * expect.norm(dim=-1).mean()
    assert fitted.report["surface_weight_error"] < 0.3 and fitted.matches(body_lowres)
    assert fitted.pose_offsets(body_lowres.v_template, torch.zeros(189)) is None and not fitted.has_posedirs


def test_the_fitted_weights_are_a_partition_of_unity_everywhere(fitted):
    p = torch.cat([torch.randn(2000, 3), 20 * torch.randn(200, 3)])
    w = fitted.weights(p)
    assert (w >= 0).all()
    torch.testing.assert_close(w.sum(-1), torch.ones(len(p)), atol=1e-5, rtol=0)


def test_the_model_is_frozen_but_differentiable_in_its_points(fitted):
    assert not fitted.training and not any(p.requires_grad for p in fitted.parameters())
    x = torch.randn(10, 3, requires_grad=True)
    fitted.shape_offsets(x, torch.ones(10, 3)).sum().backward()
    assert x.grad is not None and torch.isfinite(x.grad).all() and x.grad.abs().sum() > 0


def test_weights_and_shape_offsets_in_one_pass_equal_the_two_fields(fitted):
    p = torch.randn(2, 50, 3, generator=torch.Generator().manual_seed(0)) * 0.3 + torch.tensor([0.0, 0.0, 1.0])
    betas = torch.tensor([1.0, -0.5, 0.3, 2.0])
    weights, offsets = fitted.weights_and_shape_offsets(p, betas)
    torch.testing.assert_close(weights, fitted.weights(p), atol=1e-6, rtol=1e-5)
    torch.testing.assert_close(offsets, fitted.shape_offsets(p, betas.expand(2, 50, -1)), atol=1e-6, rtol=1e-5)
    assert offsets.abs().max() > 1e-4  # the shape field does move the points


def test_a_second_fit_loads_the_cached_model(body_lowres, fitted, monkeypatch):
    monkeypatch.setattr(diffused_mod, "_fit", lambda *a: pytest.fail("refitted instead of loading the cache"))
    again = fit_diffused_body(body_lowres, TINY)
    p = torch.randn(50, 3)
    torch.testing.assert_close(again.weights(p), fitted.weights(p), atol=0, rtol=0)
    assert again.report == fitted.report and again.matches(body_lowres)


def test_unknown_settings_are_named():
    with pytest.raises(ValueError, match="n_sample"):
        fit_diffused_body(None, dict(n_sample=3))


def test_a_body_with_pose_correctives_gets_a_diffused_pose_field(body_lowres):
    b = body_lowres
    posedirs = 0.01 * torch.randn(b.n_vertices, 3, 9 * (b.n_joints - 1), generator=torch.Generator().manual_seed(7))
    posed_body = BodyModel(b.v_template, b.shapedirs, b.J_regressor, b.weights, b.parents, b.faces, posedirs=posedirs)
    out = diffused_targets(b.v_template, posed_body, n_samples=1)
    torch.testing.assert_close(out["posedirs"], posedirs, atol=1e-6, rtol=0)
    model = fit_diffused_body(posed_body, {**TINY, "steps": 20, "n_shell": 200})
    feature = torch.randn(4, 1, posedirs.shape[-1])
    offsets = model.pose_offsets(b.v_template[:5], feature)
    assert model.has_posedirs and offsets.shape == (4, 5, 3) and torch.isfinite(offsets).all()
    assert model.pose_offsets(b.v_template[:5], torch.zeros_like(feature)).abs().max() == 0
