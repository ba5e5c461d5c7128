import numpy as np
import pytest
import torch

from drapebench.body import MOTIONS, BodySequence, make_sequence
from drapebench.body.limits import JOINT_LIMITS, limit_violation
from drapebench.body.motions import GRAVITY, UNGROUNDED_MOTIONS, ballistic_height, ground_offset, motion_defaults, soft_limit, split_motions

# Stated physical bounds on joint accelerations (m/s^2, finite second differences of joint positions):
# everyday motions stay under 5 g, athletic ones (a foot in a kick, hands in a jump) under 20 g, and
# stress (fast, near joint limits) under 40 g; random (every joint at once, grounded through whichever foot is
# lower, so the support switches often) under 10 g.
ACC_BOUND = {"run": 200.0, "jump": 200.0, "kick": 200.0, "stress": 400.0, "random": 100.0}
EVERYDAY_ACC_BOUND = 50.0


def _joint_acc(seq, body):
    joints = body.forward(seq.betas[None], seq.poses, seq.trans, skin=False).joints.double()
    return (joints[2:] - 2 * joints[1:-1] + joints[:-2]).norm(dim=-1) * seq.fps**2


@pytest.mark.parametrize("motion", MOTIONS)
def test_motion_respects_limits_and_acceleration(motion, body_lowres):
    for seed in range(3):
        seq = make_sequence(motion, n_frames=90, seed=seed)  # default 15-frame transition
        assert seq.n_frames == 105 and seq.n_transition == 15
        assert limit_violation(seq.poses.numpy()).max() == 0.0
        acc = _joint_acc(seq, body_lowres)
        assert torch.isfinite(acc).all()
        bound = ACC_BOUND.get(motion, EVERYDAY_ACC_BOUND)
        assert acc.max() < bound, f"{motion} seed {seed}: {acc.max():.1f} m/s^2 > {bound}"


def test_jump_flight_is_ballistic():
    """Cloth under gravity can follow the body only if the pelvis never drops faster than free fall:
    the flight falls at exactly g and the crouches keep the root's downward acceleration under 2 g."""
    tau = np.linspace(-0.6, 0.6, 1201)
    z = ballistic_height(tau, 0.3)
    acc = np.gradient(np.gradient(z, tau), tau)
    assert np.allclose(acc[np.abs(tau) < 0.1], -GRAVITY, atol=0.05) and abs(z.max() - 0.3) < 0.01
    assert np.abs(z[np.abs(tau) > 0.5]).max() < 1e-6 and acc.max() < 2.5 * GRAVITY
    for seed in range(5):
        seq = make_sequence("jump", n_frames=120, seed=seed)
        root_z = seq.trans[:, 2].double().numpy()
        assert root_z.max() > 0.15  # it does leave the ground
        assert (np.diff(root_z, 2) * seq.fps**2).min() > -2.0 * GRAVITY


@pytest.mark.parametrize("motion", MOTIONS)
def test_seed_reproduces_and_varies(motion):
    a, b = make_sequence(motion, 30, seed=1), make_sequence(motion, 30, seed=1)
    c = make_sequence(motion, 30, seed=2)
    assert torch.equal(a.poses, b.poses) and torch.equal(a.trans, b.trans)
    assert not torch.equal(a.poses, c.poses)


def test_parameters_change_the_motion():
    slow, fast = make_sequence("walk", 60, seed=0, speed=0.8), make_sequence("walk", 60, seed=0, speed=1.6)
    assert torch.allclose(fast.trans[-1, 1], 2 * slow.trans[-1, 1], rtol=1e-4)
    small, big = make_sequence("arm_raise", 60, seed=0, amplitude=0.5), make_sequence("arm_raise", 60, seed=0)
    assert big.poses.abs().max() > 1.5 * small.poses.abs().max()
    assert make_sequence("kick", 60, seed=0, side="left").poses[:, 6, 0].min() < -0.5  # left hip flexes


def test_transition_starts_at_rest_and_is_smooth(body_lowres):
    seq = make_sequence("run", 30, seed=0, transition=15)
    assert seq.poses[0].abs().max() == 0 and seq.trans[0].abs().max() == 0
    no_trans = make_sequence("run", 30, seed=0, transition=0)
    assert no_trans.poses[0].abs().max() > 0.05  # without the transition the first frame is mid-stride
    rest = body_lowres.forward().vertices[0]
    for motion in MOTIONS:
        first = make_sequence(motion, 10, seed=0, transition=8).vertices(body_lowres)[0]
        assert torch.allclose(first, rest, atol=1e-6), motion
    # velocity ramps up from zero: the first step is much smaller than a step at full motion
    step = (seq.trans[1:] - seq.trans[:-1]).norm(dim=-1)
    assert step[0] < 0.01 * step[-1]


def test_travelling_motions_move_the_root():
    walk = make_sequence("walk", 90, seed=0)
    assert walk.trans[-1, 1] < -0.5 and walk.trans[:, 0].abs().max() < 1e-6  # walks forward (-Y)
    run = make_sequence("run", 90, seed=0)
    assert run.trans[-1, 1] < 2 * walk.trans[-1, 1]
    assert make_sequence("arm_raise", 90, seed=0).trans.abs().max() < 0.005
    jump = make_sequence("jump", 60, seed=0, transition=0)
    assert jump.trans[:, 2].max() > 0.1


@pytest.mark.parametrize("motion", [m for m in MOTIONS if m not in UNGROUNDED_MOTIONS])
def test_grounded_motions_keep_the_feet_on_the_floor(motion, body_lowres):
    floor = body_lowres.v_template[:, 2].min()
    seq = make_sequence(motion, 60, seed=0)
    lowest = seq.vertices(body_lowres)[..., 2].amin(-1) - floor
    assert lowest.abs().max() < 0.03, f"{motion}: lowest vertex {lowest.min():.3f}..{lowest.max():.3f} m from the floor"


def test_ground_offset_is_zero_at_rest_and_follows_a_squat():
    assert np.abs(ground_offset(np.zeros((2, 22, 3)))).max() < 1e-6
    pose = np.zeros((1, 22, 3))
    pose[0, [6, 10], 0], pose[0, [7, 11], 0], pose[0, [8, 12], 0] = -1.0, 2.0, -1.0  # hips, knees, ankles
    assert ground_offset(pose)[0] < -0.2  # a deep squat lowers the pelvis


def test_joint_signs_follow_the_limits(body_lowres):
    """Each joint bends the anatomical way at the larger end of its range (body faces -Y, +X is its left)."""
    b = body_lowres
    rest = b.forward().joints[0]

    def moved(joint, axis, end, probe, frac=1.0):
        pose = torch.zeros(1, 22, 3)
        j = b.joint_index(joint)
        pose[0, j, axis] = frac * float(JOINT_LIMITS[j, axis, end])
        return b.forward(None, pose).joints[0, b.joint_index(probe)] - rest[b.joint_index(probe)]

    lo, hi = 0, 1
    assert moved("left_hip", 0, lo, "left_knee")[1] < -0.3  # hip flexion: thigh swings forward
    assert moved("right_hip", 0, lo, "right_knee")[1] < -0.3
    assert moved("left_knee", 0, hi, "left_ankle")[1] > 0.2  # knee flexion: shin swings backward
    assert moved("right_knee", 0, hi, "right_ankle")[1] > 0.2
    assert moved("left_knee", 0, lo, "left_ankle").norm() < 1e-6  # no hyperextension
    assert moved("spine1", 0, hi, "head")[1] < -0.2  # the spine bends further forward than back
    assert moved("left_shoulder", 1, lo, "left_wrist")[2] > 0.7  # arms raise sideways up to overhead
    assert moved("right_shoulder", 1, hi, "right_wrist")[2] > 0.7
    assert moved("left_shoulder", 0, lo, "left_wrist", frac=0.5)[1] < -0.15  # shoulder flexion: arm forward...
    assert moved("left_shoulder", 0, lo, "left_wrist")[2] > 0.6  # ...and up
    assert moved("left_elbow", 0, lo, "left_wrist")[2] > 0.2  # elbow flexion lifts the forearm
    assert moved("left_hip", 1, lo, "left_knee")[0] > 0.15  # hip abduction: left thigh moves to +X
    assert moved("right_hip", 1, hi, "right_knee")[0] < -0.15


def test_limits_table_is_mirror_symmetric_and_contains_rest_pose():
    assert (JOINT_LIMITS[..., 0] <= 0).all() and (JOINT_LIMITS[..., 1] >= 0).all()
    left, right = JOINT_LIMITS[6:10], JOINT_LIMITS[10:14]  # legs
    assert np.allclose(right[:, 0], left[:, 0]) and np.allclose(right[:, 1:], -left[:, 1:, ::-1])
    left, right = JOINT_LIMITS[14:18], JOINT_LIMITS[18:22]  # arms
    assert np.allclose(right[:, 0], left[:, 0]) and np.allclose(right[:, 1:], -left[:, 1:, ::-1])


def test_soft_limit_is_identity_inside_and_bounded():
    lo, hi = np.array(-1.0), np.array(1.0)
    x = np.linspace(-5, 5, 1001)
    y = soft_limit(x, lo, hi)
    assert (y >= lo).all() and (y <= hi).all()
    inside = np.abs(x) < 0.85
    assert np.allclose(y[inside], x[inside])
    assert (np.diff(y) >= 0).all()  # monotone: no kinks that reverse motion


def test_split_motions():
    train, test = split_motions(held_out=("kick", "stress"))
    assert set(train) | set(test) == set(MOTIONS) and not set(train) & set(test)
    assert test == ("kick", "stress")
    with pytest.raises(ValueError, match="valid motions"):
        split_motions(held_out=("kik",))
    with pytest.raises(ValueError, match="leaves no motion"):
        split_motions(held_out=MOTIONS)


def test_bad_motion_input():
    with pytest.raises(ValueError, match="valid motions: walk"):
        make_sequence("moonwalk")
    with pytest.raises(ValueError, match="unknown parameter"):
        make_sequence("walk", speedd=2.0)
    with pytest.raises(ValueError, match="n_frames"):
        make_sequence("walk", n_frames=0)
    with pytest.raises(ValueError, match="fps"):
        make_sequence("walk", fps=0)
    assert "speed" in motion_defaults("walk")
    with pytest.raises(ValueError, match="NaN"):
        BodySequence("x", "walk", torch.zeros(10), torch.full((3, 22, 3), float("nan")), torch.zeros(3, 3))
    with pytest.raises(ValueError, match=r"poses must be \(T, J, 3\)"):
        BodySequence("x", "walk", torch.zeros(10), torch.zeros(3, 22), torch.zeros(3, 3))
    with pytest.raises(ValueError, match=r"trans must be \(3, 3\)"):
        BodySequence("x", "walk", torch.zeros(10), torch.zeros(3, 22, 3), torch.zeros(4, 3))


def test_hydra_motion_configs_match_the_generators():
    from pathlib import Path

    from omegaconf import OmegaConf

    conf = Path(__file__).resolve().parents[2] / "conf" / "motion"
    assert {p.stem for p in conf.glob("*.yaml")} == {*MOTIONS, "file", "amass"}  # file, amass: a user's poses (motion_file.py, amass.py)
    for p in conf.glob("*.yaml"):
        if p.stem in ("file", "amass"):
            continue
        cfg = OmegaConf.load(p)
        assert cfg.name == p.stem and cfg.n_frames > 0 and cfg.fps > 0 and cfg.transition >= 0
        assert set(cfg.params) <= set(motion_defaults(cfg.name)), p.name


def test_limit_violation_measures_both_ends_of_a_range():
    from drapebench.body.bake import JOINT_NAMES

    knee = JOINT_NAMES.index("left_knee")
    pose = np.zeros((1, 22, 3))
    pose[0, knee, 0] = JOINT_LIMITS[knee, 0, 0] - 0.2  # hyperextended
    pose[0, knee, 1] = JOINT_LIMITS[knee, 1, 1] + 0.1
    v = limit_violation(pose)
    assert np.isclose(v[0, knee, 0], 0.2, atol=1e-5) and np.isclose(v[0, knee, 1], 0.1, atol=1e-5)
    assert np.isclose(v.sum(), 0.3, atol=1e-5)
    assert limit_violation(np.zeros((1, 22, 3))).max() == 0.0


def test_transition_envelope_is_c2_at_both_ends():
    """Velocity and acceleration stay continuous: the smoothstep's second derivative vanishes at 0 and 1."""
    from drapebench.body.motions import smoothstep

    h = 1e-3
    s = smoothstep(np.array([0.0, h, 2 * h, 1 - 2 * h, 1 - h, 1.0]))
    assert abs(s[2] - 2 * s[1] + s[0]) / h**2 < 0.1 and abs(s[5] - 2 * s[4] + s[3]) / h**2 < 0.1
    assert s[0] == 0.0 and s[-1] == 1.0 and abs(s[1] - s[0]) / h < 1e-4
