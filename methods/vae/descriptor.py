"""The regressor's per-frame input (Eq. 17): a pose code with its velocity and acceleration, the root
translation's and root rotation's (Euler angles) velocities and accelerations, and the body shape.
Derivatives are backward finite differences at the sequence's frame rate (zero at the first frame)."""

from __future__ import annotations

import math

import numpy as np
import torch

from drapebench.body.lbs import axis_angle_to_matrix
from drapebench.body.motions import generate

GENERATED_POSE_SEED = 60000  # first seed of the generated pose sequences (the data presets draw theirs from 40000)


def euler_zxy(R: torch.Tensor) -> torch.Tensor:
    """Angles (a, b, c) (..., 3) rad with R = Rz(a) Rx(b) Ry(c) for rotation matrices R (..., 3, 3)."""
    b = torch.asin(R[..., 2, 1].clamp(-1.0, 1.0))
    a = torch.atan2(-R[..., 0, 1], R[..., 1, 1])
    c = torch.atan2(-R[..., 2, 0], R[..., 2, 2])
    return torch.stack([a, b, c], -1)


def unwrap(angles: torch.Tensor) -> torch.Tensor:
    """Angles (T, ...) rad made continuous over time (steps between frames wrapped into [-pi, pi))."""
    step = torch.diff(angles, dim=0)
    step = torch.remainder(step + math.pi, 2 * math.pi) - math.pi
    return torch.cat([angles[:1], angles[:1] + torch.cumsum(step, 0)])


def derivative(x: torch.Tensor, fps: float) -> torch.Tensor:
    """Backward difference of x (T, ...) per second (x units / s); zero at the first frame."""
    return torch.cat([torch.zeros_like(x[:1]), torch.diff(x, dim=0) * fps])


def pose_rotations(poses: torch.Tensor) -> torch.Tensor:
    """Rotation matrices (T, J-1, 3, 3) of the non-root joints of poses (T, J, 3) (axis-angle, rad)."""
    return axis_angle_to_matrix(poses[:, 1:])


def generated_poses(motions, per_motion: int, n_frames: int, transition: int, fps: float) -> torch.Tensor:
    """Poses (N, 22, 3) rad of ``per_motion`` generated sequences (``transition`` + ``n_frames`` frames at ``fps``,
    default motion parameters, seeds from GENERATED_POSE_SEED) of each motion kind in ``motions``, N =
    len(motions) * per_motion * (transition + n_frames)."""
    poses = [generate(m, n_frames, fps, GENERATED_POSE_SEED + i, transition)[0] for m in sorted(set(motions)) for i in range(per_motion)]
    return torch.as_tensor(np.concatenate(poses), device="cpu") if poses else torch.zeros(0, 22, 3, device="cpu")


ROOT_CHOICES = ("world", "vertical")


def motion_descriptor(seq, betas: torch.Tensor, pose_code=None, root: str = "world") -> torch.Tensor:
    """Per-frame regressor input (T, 3P + 2R + 6 + S) of a body sequence: [phi, dphi, d2phi, dH, d2H, dK, d2K,
    beta] with phi the pose code ``pose_code(rotations (T, J-1, 3, 3)) -> (T, P)`` (None: the non-root joints'
    axis-angles, P = 3 (J-1)), H the root translation (m; ``root`` "world": its 3 components, R = 3, the
    paper's text; "vertical": only the vertical (z) one, R = 1, heading-invariant, the public model), K the
    root rotation's Euler angles (rad) and beta the body shape ``betas`` (S,) (a prefix of
    ``BodyModel.full_betas(seq.betas)``; S = 0 leaves it out). Computed on ``betas``'s device."""
    if root not in ROOT_CHOICES:
        raise ValueError(f"root must be one of {', '.join(ROOT_CHOICES)}, not {root!r}")
    poses = seq.poses.to(betas.device).float()
    trans = seq.trans.to(betas.device).float()
    phi = poses[:, 1:].flatten(1) if pose_code is None else pose_code(pose_rotations(poses))
    H = trans if root == "world" else trans[:, 2:3]
    K = unwrap(euler_zxy(axis_angle_to_matrix(poses[:, 0])))
    fps = float(seq.fps)
    parts = [phi, derivative(phi, fps), derivative(derivative(phi, fps), fps)]
    for x in (H, K):
        v = derivative(x, fps)
        parts += [v, derivative(v, fps)]
    return torch.cat([*parts, betas.float()[None].expand(len(poses), -1)], -1)
