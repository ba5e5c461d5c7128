import numpy as np
import pytest
import torch

from drapebench.body import MOTIONS, BodySequence, make_sequence
from drapebench.body.limits import JOINT_LIMITS, limit_violation
from drapebench.body.motions import motion_defaults, soft_limit

# Physical bound on joint accelerations (m/s^2) from finite differences; stress is allowed more.
ACC_BOUND = {"stress": 400.0, "jump": 150.0, "run": 150.0, "kick": 150.0}  # fast limbs: 10-15 g
DEFAULT_ACC_BOUND = 80.0


@pytest.mark.parametrize("motion", MOTIONS)
def test_motion_respects_limits_and_acceleration(motion, body_lowres):
    seq = make_sequence(motion, n_frames=60, seed=3, transition=10)
    assert seq.n_frames == 70 and seq.n_transition == 10
    assert limit_violation(seq.poses.numpy()).max() == 0.0
    joints = seq.joints(body_lowres).double()
    acc = (joints[2:] - 2 * joints[1:-1] + joints[:-2]).norm(dim=-1) * seq.fps**2
    assert torch.isfinite(acc).all()
    assert acc.max() < ACC_BOUND.get(motion, DEFAULT_ACC_BOUND), f"{motion}: {acc.max():.1f} m/s^2"


@pytest.mark.parametrize("motion", MOTIONS)
def test_seed_reproduces_and_varies(motion):
    a, b = make_sequence(motion, 30, seed=1), make_sequence(motion, 30, seed=1)
    c = make_sequence(motion, 30, seed=2)
    assert torch.equal(a.poses, b.poses) and torch.equal(a.trans, b.trans)
    assert not torch.equal(a.poses, c.poses)


def test_transition_starts_at_rest_and_is_smooth():
    seq = make_sequence("run", 30, seed=0, transition=15)
    assert seq.poses[0].abs().max() == 0 and seq.trans[0].abs().max() == 0
    no_trans = make_sequence("run", 30, seed=0, transition=0)
    assert no_trans.poses[0].abs().max() > 0.05  # without the transition the first frame is mid-stride


def test_travelling_motions_move_the_root():
    walk = make_sequence("walk", 90, seed=0)
    assert walk.trans[-1, 1] < -0.5  # walks forward (-Y)
    assert make_sequence("arm_raise", 90, seed=0).trans.abs().max() < 1e-6
    jump = make_sequence("jump", 60, seed=0, transition=0)
    assert jump.trans[:, 2].max() > 0.1


def test_motion_signs_on_the_body(body_lowres):
    """Knees flex backwards, walking arms swing, arm_raise lifts the wrists above the shoulders."""
    b = body_lowres
    raise_ = make_sequence("arm_raise", 75, seed=0, transition=0)
    j = raise_.joints(b)
    top = j[:, b.joint_index("left_wrist"), 2].argmax()
    assert j[top, b.joint_index("left_wrist"), 2] > j[top, b.joint_index("left_shoulder"), 2]
    pose = torch.zeros(1, 22, 3)
    pose[0, b.joint_index("left_knee"), 0] = 1.0
    out = b.forward(None, pose)
    assert out.joints[0, b.joint_index("left_ankle"), 1] > out.joints[0, b.joint_index("left_knee"), 1]


def test_soft_limit_is_identity_inside_and_bounded():
    lo, hi = np.array(-1.0), np.array(1.0)
    x = np.linspace(-5, 5, 1001)
    y = soft_limit(x, lo, hi)
    assert (y >= lo).all() and (y <= hi).all()
    inside = np.abs(x) < 0.85
    assert np.allclose(y[inside], x[inside])
    assert (np.diff(y) >= 0).all()  # monotone: no kinks that reverse motion


def test_bad_motion_input():
    with pytest.raises(ValueError, match="valid motions: walk"):
        make_sequence("moonwalk")
    with pytest.raises(ValueError, match="unknown parameter"):
        make_sequence("walk", speedd=2.0)
    assert "speed" in motion_defaults("walk")
    with pytest.raises(ValueError, match="NaN"):
        BodySequence("x", "walk", torch.zeros(10), torch.full((3, 22, 3), float("nan")), torch.zeros(3, 3))
    with pytest.raises(ValueError, match=r"poses must be \(T, J, 3\)"):
        BodySequence("x", "walk", torch.zeros(10), torch.zeros(3, 22), torch.zeros(3, 3))


def test_limits_table_contains_rest_pose():
    assert (JOINT_LIMITS[..., 0] <= 0).all() and (JOINT_LIMITS[..., 1] >= 0).all()
