"""Rotations and linear blend skinning, batched over frames, differentiable, any float dtype."""

from __future__ import annotations

import torch


def axis_angle_to_matrix(aa: torch.Tensor) -> torch.Tensor:
    """Rodrigues' formula. ``aa`` (..., 3) axis * angle (radians) -> rotation matrices (..., 3, 3).

    Smooth at zero angle (uses the Taylor expansion of sin(t)/t and (1-cos t)/t^2), so gradients
    stay finite for the rest pose.
    """
    theta2 = (aa * aa).sum(-1, keepdim=True).unsqueeze(-1)  # (...,1,1)
    small = theta2 < 1e-8
    theta2_safe = torch.where(small, torch.ones_like(theta2), theta2)
    theta = theta2_safe.sqrt()
    a = torch.where(small, 1.0 - theta2 / 6.0, torch.sin(theta) / theta)
    b = torch.where(small, 0.5 - theta2 / 24.0, (1.0 - torch.cos(theta)) / theta2_safe)
    x, y, z = aa.unbind(-1)
    zero = torch.zeros_like(x)
    K = torch.stack([zero, -z, y, z, zero, -x, -y, x, zero], dim=-1).reshape(*aa.shape[:-1], 3, 3)
    eye = torch.eye(3, dtype=aa.dtype, device=aa.device).expand_as(K)
    return eye + a * K + b * (K @ K)


def matrix_to_axis_angle(R: torch.Tensor) -> torch.Tensor:
    """Inverse of :func:`axis_angle_to_matrix` for angles in [0, pi). (..., 3, 3) -> (..., 3)."""
    cos = ((R.diagonal(dim1=-2, dim2=-1).sum(-1) - 1.0) / 2.0).clamp(-1.0, 1.0)
    angle = torch.acos(cos)
    vec = torch.stack(
        [R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], R[..., 1, 0] - R[..., 0, 1]], -1
    )
    sin = torch.sin(angle)
    scale = torch.where(sin.abs() < 1e-6, 0.5 + angle**2 / 12.0, angle / (2.0 * sin.clamp_min(1e-12)))
    return vec * scale.unsqueeze(-1)


LBS_CHUNK = 256  # frames skinned at once by lbs()


def _blended(weights: torch.Tensor, transforms: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Per-point blended transforms (B, N, 3, 4) of the joint transforms (B, J, 4, 4) relative to each frame's
    root translation o = transforms[:, 0, :3, 3], and o (B, 3): the translations are blended as offsets from o
    (Σ_j w_j (t_j - o)) and o is added back whole, so a weight row that sums to 1 only within rounding moves no
    point by that rounding times the distance from the origin."""
    origin = transforms[:, 0, :3, 3]
    A = transforms[..., :3, :].clone()  # (B,J,3,4)
    A[..., 3] -= origin[:, None]
    if weights.dim() == 2:
        return torch.einsum("nj,bjkl->bnkl", weights, A), origin
    return torch.einsum("bnj,bjkl->bnkl", weights, A), origin


def lbs(points: torch.Tensor, weights: torch.Tensor, transforms: torch.Tensor) -> torch.Tensor:
    """Linear blend skinning of arbitrary points.

    Args:
        points: (N, 3) rest-pose points shared by all frames, or (B, N, 3) per frame.
        weights: (N, J) skinning weights (rows normally sum to 1), or (B, N, J).
        transforms: (B, J, 4, 4) skinning transforms (global joint transform with the rest joint
            position removed, translation included), e.g. ``BodyOutput.transforms``.
    Returns:
        (B, N, 3) skinned points, blended relative to each frame's root (:func:`_blended`), so exact to the
        dtype's resolution at the body's scale however far from the origin. Frames are skinned in chunks of
        ``LBS_CHUNK`` (the per-point blended transforms, 12 floats per point and frame, are never held for a
        whole long sequence).
    """
    B = transforms.shape[0]
    if B > LBS_CHUNK:
        def part(t, a):  # the frames [a, a + LBS_CHUNK) of a per-frame input, a shared one as it is
            return t[a : a + LBS_CHUNK] if t.dim() == 3 and t.shape[0] == B else t

        chunks = (lbs(part(points, a), part(weights, a), transforms[a : a + LBS_CHUNK]) for a in range(0, B, LBS_CHUNK))
        if torch.is_grad_enabled() and any(t.requires_grad for t in (points, weights, transforms)):
            return torch.cat(list(chunks))
        out = None  # filled chunk by chunk: no second copy of a long sequence's result
        for a, x in zip(range(0, B, LBS_CHUNK), chunks):
            out = x.new_empty((B, *x.shape[1:])) if out is None else out
            out[a : a + len(x)] = x
        return out
    T, origin = _blended(weights, transforms)
    if points.dim() == 2:
        points = points.unsqueeze(0).expand(T.shape[0], -1, -1)
    return torch.einsum("bnkl,bnl->bnk", T[..., :3], points) + T[..., 3] + origin[:, None]


def inverse_lbs(points: torch.Tensor, weights: torch.Tensor, transforms: torch.Tensor) -> torch.Tensor:
    """Unpose points: invert the blended transform per point (relative to each frame's root, as :func:`lbs`).
    Shapes as in :func:`lbs`."""
    T, origin = _blended(weights, transforms)
    if points.dim() == 2:
        points = points.unsqueeze(0).expand(T.shape[0], -1, -1)
    rhs = (points - origin[:, None] - T[..., 3]).unsqueeze(-1)
    return torch.linalg.solve(T[..., :3], rhs).squeeze(-1)
