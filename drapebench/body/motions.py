"""Procedural, seeded body motions for the 22-joint skeleton.

Every motion is a smooth function of time (sums of sinusoids and Gaussian bumps), so poses and the
root translation have bounded finite-difference acceleration. Motions are designed inside
:data:`drapebench.body.limits.JOINT_LIMITS`; a smooth soft limit (identity inside the range,
exponential approach within 5 % of either end) guarantees they never leave it. Random motions
(``dance``, ``stress``) cap each joint axis's angular acceleration (``max_acc``, rad/s^2) by slowing
their sinusoids. ``random`` (:mod:`drapebench.body.random_motion`, the training distribution) draws
every joint, the heading and the walking speed at random, capping angular velocity and acceleration;
the named motions are the held-out test motions. A sequence may begin with a transition: a C2 envelope (quintic smoothstep) scales
the whole motion from the rest pose (``pose = 0``, ``trans = 0``) to full amplitude, so velocity and
acceleration stay continuous.

Ground contact: motions without a flight phase are "grounded": the root height follows the soles of
a canonical body (the shipped ``anny_lowres`` at mean shape) through a smooth soft minimum over its
skinned sole vertices, so the lowest sole point stays at the rest floor level.
``run`` and ``jump`` use their designed vertical trajectories (a jump's flight is ballistic: the body
falls at g, so cloth can follow it); ``stress`` floats (its flailing legs
would make the support switch too fast).

The seed varies amplitude (+-15 %), cadence (+-10 %) and phase; ``amplitude``, ``cadence`` (Hz),
``speed`` (m/s) and motion-specific parameters override the defaults.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import torch

from drapebench.body.bake import JOINT_NAMES
from drapebench.body.lbs import lbs
from drapebench.body.limits import JOINT_LIMITS
from drapebench.body.random_motion import random_motion
from drapebench.keys import check_known, is_finite_number, is_number
from drapebench.progress import progress

NAMED_MOTIONS = ("walk", "run", "jump", "arm_raise", "squat", "twist", "kick", "dance", "static", "stress")
MOTIONS = (*NAMED_MOTIONS, "random")  # random: drapebench.body.random_motion
MOTION_VERSION = 3  # bump when generated poses change (part of dataset content hashes)
SOFT_MARGIN = 0.05  # fraction of a joint range at either end where soft_limit bends towards the limit
GROUND_SOFTNESS = 0.01  # metres; soft-min temperature of the foot-contact height
GROUND_CHUNK = 4096  # frames grounded at once by ground_offset
J = {name: i for i, name in enumerate(JOINT_NAMES)}
X, Y, Z = 0, 1, 2
GRAVITY = 9.81  # m/s^2, for the ballistic flight of jumps
THIGH, SHIN = 0.45, 0.45  # metres; approximate leg segment lengths for pelvis-height compensation


def smoothstep(u: np.ndarray) -> np.ndarray:
    """Quintic smoothstep on [0, 1] (C2: zero first and second derivative at both ends)."""
    u = np.clip(u, 0.0, 1.0)
    return u * u * u * (u * (6.0 * u - 15.0) + 10.0)


def soft_limit(x: np.ndarray, lo: np.ndarray, hi: np.ndarray, margin: float = SOFT_MARGIN) -> np.ndarray:
    """Identity inside ``[lo + d, hi - d]`` (d = margin x range), C1 exponential approach beyond; never leaves [lo, hi]."""
    d = margin * (hi - lo)
    a, b = lo + d, hi - d
    out = np.where(x > b, hi - d * np.exp(-(x - b) / d), x)
    return np.where(x < a, lo + d * np.exp(-(a - x) / d), out)


def _bump(u: np.ndarray, centre: float, width: float) -> np.ndarray:
    """Periodic Gaussian bump on the unit cycle u in [0, 1)."""
    w = (u - centre + 0.5) % 1.0 - 0.5
    return np.exp(-((w / width) ** 2))


def _leg_drop(hip_flex: np.ndarray, knee_flex: np.ndarray) -> np.ndarray:
    """Pelvis drop (m) when thighs flex forward by ``hip_flex`` and knees by ``knee_flex`` (radians, >= 0) with feet planted."""
    return THIGH + SHIN - (THIGH * np.cos(hip_flex) + SHIN * np.cos(knee_flex - hip_flex))


class _Motion:
    """Per-frame pose (T, 22, 3), root velocity (T, 3) and vertical offset (T,) under construction."""

    def __init__(self, t: np.ndarray):
        self.t = t
        self.pose = np.zeros((len(t), len(JOINT_NAMES), 3))
        self.velocity = np.zeros((len(t), 3))
        self.z = np.zeros(len(t))

    def set(self, joint: str, axis: int, value) -> None:
        self.pose[:, J[joint], axis] = value

    def both(self, part: str, axis: int, left, right=None, mirror: bool = False) -> None:
        """Set left and right joints; ``mirror`` flips the sign for y/z axes of the right side."""
        self.set(f"left_{part}", axis, left)
        if right is None:
            right = -np.asarray(left) if mirror else left
        self.set(f"right_{part}", axis, right)


def _walk_like(m, t, rng, a, f, speed, run: bool):
    phi = 2 * np.pi * f * t + rng.uniform(0, 2 * np.pi)
    s, hip_amp = np.sin(phi), (0.65 if run else 0.4) * a
    m.both("hip", X, -0.05 - hip_amp * s, -0.05 + hip_amp * s)
    knee0, knee_amp = (0.3, 1.2) if run else (0.08, 0.6)
    bump_l, bump_r = ((1 + np.cos(phi)) / 2) ** 2, ((1 - np.cos(phi)) / 2) ** 2
    m.both("knee", X, knee0 + knee_amp * a * bump_l, knee0 + knee_amp * a * bump_r)
    m.both("ankle", X, -0.12 * a * s, 0.12 * a * s)
    m.both("shoulder", X, (0.6 if run else 0.3) * a * s, -(0.6 if run else 0.3) * a * s)
    m.both("shoulder", Y, 0.4, mirror=True)
    elbow = -1.4 if run else -0.25
    m.both("elbow", X, elbow - 0.15 * a * (1 + s) / 2, elbow - 0.15 * a * (1 - s) / 2)
    m.set("pelvis", Z, 0.08 * a * s)
    m.set("spine1", Z, -0.06 * a * s)
    m.set("spine1", X, 0.15 if run else 0.03)
    m.velocity[:, 1] = -speed
    if run:  # flight: the root bounces twice per cycle (walking is grounded through the feet instead)
        m.z[:] = 0.04 * a * np.cos(2 * phi)


def ballistic_height(tau: np.ndarray, apex: float, smoothing: float = 0.04, g: float = GRAVITY) -> np.ndarray:
    """Height (m) of a jump's flight at time ``tau`` (s) from its apex: the free-fall parabola
    max(apex - g tau^2 / 2, 0), convolved with a Gaussian of ``smoothing`` seconds so take-off and
    landing (the leg push) are smooth. Inside the flight the body falls at exactly g, as cloth does."""
    half = np.sqrt(2.0 * apex / g)
    s = np.linspace(-half, half, 801)
    w = np.exp(-0.5 * ((np.asarray(tau)[:, None] - s[None]) / smoothing) ** 2)
    parabola = apex - 0.5 * g * s**2
    return np.trapezoid(w * parabola, s, axis=1) / (np.sqrt(2 * np.pi) * smoothing)


def _jump(m, t, rng, a, f, height):
    u = (f * t + rng.uniform(0, 0.2)) % 1.0
    # countermovement and landing crouches wide enough that the pelvis never drops much faster than g
    crouch = _bump(u, 0.2, 0.18) + 0.6 * _bump(u, 0.9, 0.12)
    flight = _bump(u, 0.57, 0.08)  # toes point through the flight
    tau = ((u - 0.57 + 0.5) % 1.0 - 0.5) / f  # seconds from the flight's apex
    hip, knee = 0.75 * a * crouch, 1.275 * a * crouch
    m.both("hip", X, -hip)
    m.both("knee", X, knee)
    m.both("ankle", X, -0.45 * a * crouch + 0.5 * flight)
    m.set("spine1", X, 0.3 * a * crouch)
    swing = _bump(u, 0.55, 0.16)  # arms swing up through take-off and flight, slower than the legs
    m.both("shoulder", X, 0.5 * _bump(u, 0.2, 0.14) - 1.3 * a * swing)
    m.both("shoulder", Y, 0.3, mirror=True)
    m.both("elbow", X, -0.3)
    m.z[:] = -_leg_drop(hip, knee) + ballistic_height(tau, height * a)


def _arm_raise(m, t, rng, a, f, mode):
    r = (1 - np.cos(2 * np.pi * f * t + rng.uniform(-0.3, 0.3))) / 2
    if mode == "side":
        m.both("shoulder", Y, -1.9 * a * r, mirror=True)
        m.both("collar", Y, -0.2 * a * r, mirror=True)
    else:
        m.both("shoulder", X, -1.8 * a * r)
    m.both("elbow", X, -0.15)


def _squat(m, t, rng, a, f):
    r = (1 - np.cos(2 * np.pi * f * t + rng.uniform(-0.3, 0.3))) / 2
    hip, knee = 1.5 * a * r, 1.9 * a * r
    m.both("hip", X, -hip)
    m.both("knee", X, knee)
    m.both("ankle", X, -(knee - hip))
    m.set("spine1", X, 0.35 * a * r)
    m.both("shoulder", X, -1.0 * a * r)


def _twist(m, t, rng, a, f):
    s = np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi))
    for j in ("spine1", "spine2", "spine3"):
        m.set(j, Z, 0.3 * a * s)
    m.set("pelvis", Z, 0.15 * a * s)
    m.set("neck", Z, -0.3 * a * s)
    m.both("shoulder", Y, -0.7, mirror=True)
    m.both("elbow", X, -0.3)


def _kick(m, t, rng, a, f, side):
    u = (f * t + rng.uniform(0, 0.1)) % 1.0
    kick, windup = _bump(u, 0.5, 0.1), _bump(u, 0.4, 0.08)
    other = "left" if side == "right" else "right"
    m.set(f"{side}_hip", X, -1.4 * a * kick + 0.3 * windup)
    m.set(f"{side}_knee", X, 0.2 + 1.2 * windup + 0.2 * kick)
    m.set(f"{side}_ankle", X, 0.4 * kick)
    m.set(f"{other}_knee", X, 0.15 * kick)
    m.set(f"{other}_shoulder", X, -0.7 * a * kick)
    m.set(f"{side}_shoulder", X, 0.4 * a * kick)
    m.both("shoulder", Y, 0.2, mirror=True)
    m.set("spine1", X, -0.15 * a * kick)


def _random_smooth(m, t, rng, a, freq_range, reach, joints, max_acc, bias=0.5, n_harmonics=3):
    """Each joint axis: a centre plus a few random sinusoids that stay inside the limits by design.

    The centre lies ``bias`` of the way from the rest pose (0) to the middle of the range, moved by up
    to 30 % of the half-range; the sinusoid amplitudes sum to ``reach`` (x ``a``) times the room left to
    the nearer limit. Frequencies are lowered where the axis's peak angular acceleration would exceed
    ``max_acc`` (rad/s^2).
    """
    for name in joints:
        j = J[name]
        for axis in range(3):
            lo, hi = JOINT_LIMITS[j, axis]
            mid, half = (lo + hi) / 2, (hi - lo) / 2
            centre = np.clip(bias * mid + rng.uniform(-0.3, 0.3) * half, lo, hi)
            amps = rng.dirichlet(np.ones(n_harmonics)) * min(reach * a, 1.0) * (half - abs(centre - mid))
            omega = 2 * np.pi * rng.uniform(*freq_range, n_harmonics)
            peak = (amps * omega**2).sum()
            if peak > max_acc:
                omega = omega * np.sqrt(max_acc / peak)
            phases = rng.uniform(0, 2 * np.pi, n_harmonics)
            m.pose[:, j, axis] = centre + (amps * np.sin(omega * t[:, None] + phases)).sum(-1)


_DANCE_JOINTS = ("spine1", "spine2", "spine3", "neck", "head", "left_collar", "right_collar",
                 "left_shoulder", "right_shoulder", "left_elbow", "right_elbow", "left_wrist",
                 "right_wrist", "left_hip", "right_hip", "left_knee", "right_knee")  # fmt: skip


def _dance(m, t, rng, a, f, max_acc):
    _random_smooth(m, t, rng, a, (0.3 * f, 1.2 * f), 0.5, _DANCE_JOINTS, max_acc, bias=0.3)
    m.set("pelvis", Z, 0.5 * a * np.sin(2 * np.pi * 0.2 * f * t + rng.uniform(0, 2 * np.pi)))
    sway = rng.uniform(0, 2 * np.pi, 2)
    m.velocity[:, 0] = 0.25 * a * np.sin(2 * np.pi * 0.5 * f * t + sway[0])
    m.velocity[:, 1] = 0.25 * a * np.sin(2 * np.pi * 0.4 * f * t + sway[1])


def _static(m, t, rng, a):
    """A relaxed stance held still: the rest pose plus small random offsets (<= 15 % of each range)."""
    lo, hi = JOINT_LIMITS[1:, :, 0], JOINT_LIMITS[1:, :, 1]
    span = 0.15 * a * (hi - lo) / 2
    m.pose[:, 1:] = rng.uniform(np.maximum(lo, -span), np.minimum(hi, span))


def _stress(m, t, rng, a, f, max_acc):
    _random_smooth(m, t, rng, a, (0.75 * f, 1.25 * f), 0.9, JOINT_NAMES[1:], max_acc, bias=0.5, n_harmonics=2)
    m.set("pelvis", Z, 1.0 * a * np.sin(2 * np.pi * 0.5 * f * t))
    m.velocity[:, 0] = 1.0 * a * np.sin(2 * np.pi * 0.5 * f * t)


def _random(m, t, rng, p):
    """Random joint trajectories inside the soft-limit band (soft_limit leaves them unchanged) and random root travel."""
    m.pose[:], m.velocity[:] = random_motion(t, rng, margin=SOFT_MARGIN, **p)


# name -> (builder, default parameters). ``amplitude`` scales angles, ``cadence`` is the cycle frequency (Hz).
_SPECS = {
    "walk": (lambda m, t, r, p: _walk_like(m, t, r, p["amplitude"], p["cadence"], p["speed"], False),
             dict(amplitude=1.0, cadence=0.9, speed=1.2)),
    "run": (lambda m, t, r, p: _walk_like(m, t, r, p["amplitude"], p["cadence"], p["speed"], True),
            dict(amplitude=1.0, cadence=1.4, speed=3.0)),
    "jump": (lambda m, t, r, p: _jump(m, t, r, p["amplitude"], p["cadence"], p["height"]),
             dict(amplitude=1.0, cadence=0.8, height=0.3)),
    "arm_raise": (lambda m, t, r, p: _arm_raise(m, t, r, p["amplitude"], p["cadence"], p["mode"]),
                  dict(amplitude=1.0, cadence=0.4, mode="side")),
    "squat": (lambda m, t, r, p: _squat(m, t, r, p["amplitude"], p["cadence"]), dict(amplitude=1.0, cadence=0.4)),
    "twist": (lambda m, t, r, p: _twist(m, t, r, p["amplitude"], p["cadence"]), dict(amplitude=1.0, cadence=0.5)),
    "kick": (lambda m, t, r, p: _kick(m, t, r, p["amplitude"], p["cadence"], p["side"]),
             dict(amplitude=1.0, cadence=0.6, side="right")),
    "dance": (lambda m, t, r, p: _dance(m, t, r, p["amplitude"], p["cadence"], p["max_acc"]),
              dict(amplitude=1.0, cadence=1.0, max_acc=30.0)),
    "static": (lambda m, t, r, p: _static(m, t, r, p["amplitude"]), dict(amplitude=1.0)),
    "stress": (lambda m, t, r, p: _stress(m, t, r, p["amplitude"], p["cadence"], p["max_acc"]),
               dict(amplitude=1.0, cadence=2.0, max_acc=80.0)),
    "random": (_random, dict(amplitude=1.0, cadence=0.5, max_vel=4.0, max_acc=30.0, speed=1.2, turn=2.35)),
}  # fmt: skip
# Motions with a designed vertical root motion (flight; stress flails its legs and floats); the others are grounded.
UNGROUNDED_MOTIONS = ("run", "jump", "stress")


def motion_defaults(motion: str) -> dict:
    """Default parameters of a motion (a copy)."""
    _check_motion(motion)
    return dict(_SPECS[motion][1])


def split_motions(held_out=("kick", "stress"), motions=MOTIONS) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """Split motion kinds into (train, test): ``held_out`` kinds only ever appear in test sets.

    Raises ValueError on an unknown name or when nothing is left for training.
    """
    for m in (*held_out, *motions):
        _check_motion(m)
    train = tuple(m for m in motions if m not in held_out)
    if not train:
        raise ValueError(f"holding out {list(held_out)} leaves no motion for training out of {list(motions)}")
    return train, tuple(m for m in motions if m in held_out)


def _check_motion(motion: str) -> None:
    if motion not in _SPECS:
        raise ValueError(f"unknown motion {motion!r}; valid motions: {', '.join(MOTIONS)}")


def generate(motion: str, n_frames: int, fps: float, seed: int, transition: int = 0, **params):
    """Poses (T, 22, 3) radians and root translation (T, 3) metres, T = transition + n_frames.

    The first ``transition`` frames blend from the rest pose into the motion (C2 envelope).
    """
    _check_motion(motion)
    if n_frames < 1 or transition < 0:
        raise ValueError(f"n_frames must be >= 1 and transition >= 0, got {n_frames}, {transition} (motion.n_frames, motion.transition)")
    if not (fps > 0 and np.isfinite(fps)):
        raise ValueError(f"fps must be positive and finite, got {fps}: give frames per second, e.g. motion.fps=30")
    if seed < 0:
        raise ValueError(f"motion.seed must be >= 0 (it seeds numpy's generator), got {seed}; e.g. motion.seed=1000")
    builder, defaults = _SPECS[motion]
    check_known(params, defaults, "parameter", f"for motion {motion!r}")
    for name, value in params.items():  # a NaN made a NaN pose, an inf a silently saturated one
        if is_number(defaults[name]) and not is_finite_number(value):
            raise ValueError(f"motion.params.{name} must be a finite number, got {value!r}; e.g. motion.params.{name}={defaults[name]}")
    p = {**defaults, **params}
    rng = np.random.default_rng(seed)
    if "amplitude" in p:
        p["amplitude"] = p["amplitude"] * rng.uniform(0.85, 1.15)
    if "cadence" in p:
        p["cadence"] = p["cadence"] * rng.uniform(0.9, 1.1)
    T = transition + n_frames
    t = np.arange(T) / fps
    m = _Motion(t)
    builder(m, t, rng, p)
    lo, hi = JOINT_LIMITS[None, ..., 0], JOINT_LIMITS[None, ..., 1]
    pose = soft_limit(m.pose, lo, hi)
    envelope = smoothstep(t / (transition / fps)) if transition > 0 else np.ones(T)
    pose = pose * envelope[:, None, None]
    velocity = m.velocity * envelope[:, None]
    trans = np.concatenate([np.zeros((1, 3)), np.cumsum(0.5 * (velocity[1:] + velocity[:-1]), 0) / fps])
    trans[:, 2] += envelope * m.z if motion in UNGROUNDED_MOTIONS else ground_offset(pose)
    return pose.astype(np.float32), trans.astype(np.float32)


@lru_cache(maxsize=1)
def _canonical_feet():
    """The shipped ``anny_lowres`` body (float64) and its sole vertices (rest height < floor + 1 cm) with their weights."""
    from drapebench.body.model import load_body  # lazy: only grounded motions need the body

    body = load_body("anny_lowres", dtype=torch.float64)
    z = body.v_template[:, 2]
    sole = z < z.min() + 0.01
    return body, body.v_template[sole], body.weights[sole]


def _soft_floor(z: torch.Tensor) -> torch.Tensor:
    """Softmax-weighted mean of heights (T, N) -> (T,), weights exp(-z / :data:`GROUND_SOFTNESS`): a smooth lowest height."""
    return (torch.softmax(-z / GROUND_SOFTNESS, dim=-1) * z).sum(-1)


def ground_offset(pose: np.ndarray) -> np.ndarray:
    """Root height offset (T,) metres that keeps the lowest sole point of the canonical body at the rest floor level.

    ``pose`` (T, 22, 3) axis-angle. The soft minimum over the skinned sole vertices is smooth, so the
    offset has bounded acceleration where the support moves between heel, toes and feet; it is
    0 (to rounding) for the rest pose.
    """
    body, sole, weights = _canonical_feet()
    offset = np.empty(len(pose))
    for a in progress(range(0, len(pose), GROUND_CHUNK), desc="grounding the motion", unit="chunk"):
        with torch.no_grad():  # GROUND_CHUNK frames at a time: no float64 transforms of a whole long motion
            transforms = body.forward(None, torch.as_tensor(pose[a : a + GROUND_CHUNK], dtype=torch.float64, device=body.device), skin=False).transforms
            z = lbs(sole, weights, transforms)[..., 2]
        offset[a : a + GROUND_CHUNK] = (_soft_floor(sole[None, :, 2]) - _soft_floor(z)).numpy()
    return offset
