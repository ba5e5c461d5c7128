"""motion=random: seeded, inside the joint limits, with capped angular velocity/acceleration, random root travel.

Determinism, seed variation, joint-position accelerations, the transition from rest and the feet on the
floor are checked for every motion (random included) in test_motions.py.
"""

import numpy as np
import pytest

from drapebench.body import make_sequence
from drapebench.body.limits import JOINT_LIMITS
from drapebench.body.motions import GRAVITY, SOFT_MARGIN, motion_defaults
from drapebench.body.random_motion import random_motion

FPS = 30.0


def _angular(seq):
    """Finite-difference angular velocity (rad/s) and acceleration (rad/s^2) of every joint axis after the transition."""
    p = seq.poses[seq.n_transition :].double().numpy()
    return np.diff(p, axis=0) * seq.fps, np.diff(p, 2, axis=0) * seq.fps**2


@pytest.mark.parametrize("caps", [{}, {"max_vel": 1.0, "max_acc": 4.0}])
def test_angular_velocity_and_acceleration_are_capped(caps):
    p = {**motion_defaults("random"), **caps}
    tightest = []
    for seed in range(4):
        vel, acc = _angular(make_sequence("random", 300, FPS, seed, **caps))
        assert np.abs(vel).max() <= p["max_vel"] and np.abs(acc).max() <= p["max_acc"], seed
        tightest.append(np.abs(vel).max() / p["max_vel"])
    if caps:  # the tight caps bind: some joint moves at more than half the velocity cap
        assert max(tightest) > 0.5


def test_every_frame_is_inside_the_band_where_the_soft_limit_is_the_identity():
    lo, hi = JOINT_LIMITS[..., 0], JOINT_LIMITS[..., 1]
    d = SOFT_MARGIN * (hi - lo)
    knee_max = 0.0
    for seed in range(6):
        poses = make_sequence("random", 600, FPS, seed, transition=0).poses.double().numpy()
        assert np.isfinite(poses).all()
        assert (poses >= lo + d - 1e-6).all() and (poses <= hi - d + 1e-6).all(), seed
        knee_max = max(knee_max, poses[:, 7, 0].max())
    assert knee_max > 0.8  # the knee does bend (not a motion stuck at rest)


@pytest.mark.parametrize("n_frames, transition", [(1, 0), (2, 0), (1, 15), (2, 15), (3000, 15)])
def test_any_length(n_frames, transition):
    seq = make_sequence("random", n_frames, FPS, 7, transition=transition)
    assert seq.poses.shape == (transition + n_frames, 22, 3) and seq.trans.shape == (transition + n_frames, 3)
    assert seq.poses.isfinite().all() and seq.trans.isfinite().all()
    longer = make_sequence("random", n_frames + 10, FPS, 7, transition=transition)
    assert np.allclose(longer.poses[: seq.n_frames], seq.poses, atol=1e-6)  # a length is a prefix of a longer one


def test_too_short_or_bad_parameters_are_rejected():
    with pytest.raises(ValueError, match="n_frames must be >= 1"):
        make_sequence("random", 0)
    with pytest.raises(ValueError, match="turn must be in"):
        make_sequence("random", 10, turn=3.0)  # past the pelvis limits
    with pytest.raises(ValueError, match="speed >= 0"):
        make_sequence("random", 10, speed=-1.0)


def test_the_root_turns_and_travels_along_its_heading_at_walking_speed():
    seq = make_sequence("random", 600, FPS, 3, transition=0)
    heading = seq.poses[:, 0, 2].double().numpy()
    step = np.diff(seq.trans[:, :2].double().numpy(), axis=0) * FPS  # horizontal velocity, m/s
    speed = np.linalg.norm(step, axis=1)
    assert np.ptp(heading) > 0.5 and np.abs(heading).max() <= motion_defaults("random")["turn"]
    assert speed.max() <= motion_defaults("random")["speed"] * 1.01 and speed.sum() / FPS > 2.0
    mid = 0.5 * (heading[1:] + heading[:-1])
    facing = np.stack([np.sin(mid), -np.cos(mid)], -1)  # the body faces -Y at heading 0
    moving = speed > 0.1
    assert (np.einsum("tc,tc->t", step, facing)[moving] / speed[moving]).min() > 0.99
    still = make_sequence("random", 100, FPS, 3, speed=0.0, transition=0)
    assert still.trans[:, :2].abs().max() < 1e-6


def test_the_root_never_drops_faster_than_cloth_can_follow():
    """Grounding makes the root follow the lower foot; it must not fall at more than 2 g (like the jump's crouches)."""
    for seed in range(4):
        z = make_sequence("random", 300, FPS, seed).trans[:, 2].double().numpy()
        assert (np.diff(z, 2) * FPS**2).min() > -2.0 * GRAVITY, seed


def test_random_motion_builder_is_seeded_and_bounded_without_the_pipeline():
    t = np.arange(50) / FPS
    a, va = random_motion(t, np.random.default_rng(0))
    b, vb = random_motion(t, np.random.default_rng(0))
    c, _ = random_motion(t, np.random.default_rng(1))
    assert np.array_equal(a, b) and np.array_equal(va, vb) and not np.allclose(a, c)
    assert a.shape == (50, 22, 3) and va.shape == (50, 3) and np.isfinite(a).all() and np.isfinite(va).all()
    with pytest.raises(ValueError, match="amplitude, cadence"):
        random_motion(t, np.random.default_rng(0), cadence=0.0)
