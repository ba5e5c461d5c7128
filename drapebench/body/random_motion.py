"""Procedural random motion: smooth random joint trajectories inside the joint limits, random root motion.

Every joint axis is a sum of a few random low-frequency sinusoids ``x(t)`` (unit RMS times
``amplitude``) mapped into its range by a logistic squash, ``lo + (hi - lo) sigmoid(x + b)``: smooth
(C-infinity), monotone, never at a limit, and equal to a random centre near the rest pose at ``x = 0``.
The squash bounds the derivatives analytically: ``|f'| <= R/4 |x'|`` and
``|f''| <= R/4 |x''| + R sqrt(3)/18 |x'|^2`` (R = hi - lo); where that bound would exceed ``max_vel``
(rad/s) or ``max_acc`` (rad/s^2), the axis's frequencies are slowed until it does not, so the caps hold
for any seed and any length. The root turns (heading about +Z within +-``turn`` rad, slower than the
limbs), tilts a little, and travels forwards along its heading at a smoothly varying speed in
[0, ``speed``] m/s. Height is left to the caller (``drapebench.body.motions`` grounds the feet).
"""

from __future__ import annotations

import numpy as np

from drapebench.body.limits import JOINT_LIMITS

SQUASH_SLOPE = 0.25  # max of sigmoid'
SQUASH_CURVE = np.sqrt(3.0) / 18.0  # max of |sigmoid''|
N_HARMONICS = 4
TILT = 0.15  # rad, the largest pelvis tilt forwards/backwards and sideways


def random_sinusoids(rng: np.random.Generator, n: int, freq_range: tuple[float, float],
                     rms: float = 1.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Amplitudes, angular frequencies (rad/s, drawn from ``freq_range`` in Hz) and phases, each (n, K), of
    ``n`` random signals, each a sum of K = :data:`N_HARMONICS` sinusoids with RMS ``rms`` (see :func:`evaluate`)."""
    amps = rng.dirichlet(np.ones(N_HARMONICS), n)
    amps *= rms * np.sqrt(2.0) / np.linalg.norm(amps, axis=1, keepdims=True)  # RMS of sum a_k sin = |a| / sqrt 2
    omega = 2 * np.pi * rng.uniform(*freq_range, (n, N_HARMONICS))
    return amps, omega, rng.uniform(0, 2 * np.pi, (n, N_HARMONICS))


def evaluate(t: np.ndarray, amps: np.ndarray, omega: np.ndarray, phases: np.ndarray) -> np.ndarray:
    """Sum of sinusoids at times ``t`` (T,): (T, n) from amplitudes, angular frequencies, phases (n, K)."""
    return (amps * np.sin(omega * t[:, None, None] + phases)).sum(-1)


def squashed(t: np.ndarray, rng: np.random.Generator, lo: np.ndarray, hi: np.ndarray, centre: np.ndarray,
             freq_range: tuple[float, float], rms: float, max_vel: float, max_acc: float) -> np.ndarray:
    """(T, n) smooth random trajectories strictly inside (lo, hi) (n,), equal to ``centre`` (n,) where the
    underlying sinusoid sum is 0, with |velocity| <= ``max_vel`` and |acceleration| <= ``max_acc`` (per s, s^2)."""
    if not ((lo < centre) & (centre < hi)).all():
        raise ValueError("random motion: every centre must lie strictly inside its range")
    span = hi - lo
    amps, omega, phases = random_sinusoids(rng, len(lo), freq_range, rms)
    vel = (amps * omega).sum(-1)  # bounds of |x'| and |x''| per signal
    acc = (amps * omega**2).sum(-1)
    vel_bound = span * SQUASH_SLOPE * vel
    acc_bound = span * (SQUASH_SLOPE * acc + SQUASH_CURVE * vel**2)
    slow = np.minimum(1.0, np.minimum(max_vel / vel_bound, np.sqrt(max_acc / acc_bound)))
    x = evaluate(t, amps, omega * slow[:, None], phases)
    p = (centre - lo) / span
    return lo + span / (1.0 + np.exp(-(x + np.log(p / (1 - p)))))


def random_motion(t: np.ndarray, rng: np.random.Generator, amplitude: float = 1.0, cadence: float = 0.5,
                  max_vel: float = 4.0, max_acc: float = 30.0, speed: float = 1.2, turn: float = 2.35,
                  bias: float = 0.3, margin: float = 0.05) -> tuple[np.ndarray, np.ndarray]:
    """Random poses (T, 22, 3) rad and root velocity (T, 3) m/s at times ``t`` (T,) s.

    Joints other than the pelvis stay inside :data:`JOINT_LIMITS` shrunk by ``margin`` of each range on
    both ends, centred ``bias`` of the way from the rest pose to the middle of the range (+-20 % of the
    half-range at random); ``amplitude`` scales the spread, ``cadence`` (Hz) the limb frequencies
    (drawn from [0.25, 1.5] x cadence, heading and speed from [0.05, 0.3] x cadence). The pelvis holds the
    heading (+Z, within +-``turn`` rad) and a tilt within +-:data:`TILT` rad; the root moves forwards
    (the body faces -Y at heading 0) at a speed in [0, ``speed``] m/s.
    """
    if not (amplitude > 0 and cadence > 0 and max_vel > 0 and max_acc > 0 and speed >= 0):
        raise ValueError(f"random motion needs amplitude, cadence, max_vel, max_acc > 0 and speed >= 0; got {amplitude}, "
                         f"{cadence}, {max_vel}, {max_acc}, {speed}")  # fmt: skip
    pelvis_band = np.pi * (1 - 2 * margin)
    if not 0 < turn < pelvis_band:
        raise ValueError(f"random motion: turn must be in (0, {pelvis_band:.3f}) rad (inside the pelvis limits), got {turn}")
    lo, hi = JOINT_LIMITS[1:, :, 0].ravel(), JOINT_LIMITS[1:, :, 1].ravel()
    d = margin * (hi - lo)
    lo, hi = lo + d, hi - d
    half = (hi - lo) / 2
    centre = np.clip(bias * (lo + hi) / 2 + rng.uniform(-0.2, 0.2, lo.shape) * half, lo + 0.05 * half, hi - 0.05 * half)
    limbs = squashed(t, rng, lo, hi, centre, (0.25 * cadence, 1.5 * cadence), amplitude, max_vel, max_acc)
    slow = (0.05 * cadence, 0.3 * cadence)
    root_lo, root_hi = np.array([-TILT, -TILT, -turn]), np.array([TILT, TILT, turn])
    root = squashed(t, rng, root_lo, root_hi, np.zeros(3), slow, amplitude, max_vel, max_acc)
    pace = squashed(t, rng, np.zeros(1), np.ones(1), np.full(1, rng.uniform(0.2, 0.8)), slow, 1.0, np.inf, np.inf)[:, 0]
    pose = np.concatenate([root[:, None], limbs.reshape(len(t), -1, 3)], axis=1)
    heading = root[:, 2]
    velocity = speed * pace[:, None] * np.stack([np.sin(heading), -np.cos(heading), np.zeros_like(heading)], -1)
    return pose, velocity
