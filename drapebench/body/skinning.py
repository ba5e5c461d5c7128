"""Bind any points (a garment template, sample points) to the body and move them with it.

A binding is each point's nearest vertex of the rest body of the shape the points were made on. From it
come the points' skinning weights (the body's at that vertex), a shape transfer to another body shape
(the body's shape blend shape at that vertex); :func:`drapebench.body.lbs.lbs` poses them. Every function is batched over frames
and differentiable in the points, the weights and the transforms.
"""

from __future__ import annotations

import torch

from drapebench.geometry.proximity import nearest_indices


def nearest_body_vertices(points: torch.Tensor, body, betas: torch.Tensor | None = None) -> torch.Tensor:
    """(N,) long index of the nearest vertex of the rest body of shape ``betas`` ((S',) or None = mean)
    for each rest-pose point of ``points`` (N, 3) m."""
    if points.dim() != 2 or points.shape[-1] != 3:
        raise ValueError(f"points must be (N, 3) rest-pose positions, got {tuple(points.shape)}")
    with torch.no_grad():
        rest = body.shaped(body.full_betas(betas)[None])[0][0]
    return nearest_indices(points[None], rest[None].to(points.dtype))[0]


def nearest_weights(index: torch.Tensor, body) -> torch.Tensor:
    """(N, J) skinning weights copied from the body vertices ``index`` (N,) (SNUG's and the skinning baseline's)."""
    return body.weights[index].clone()


def transfer_shape(points: torch.Tensor, index: torch.Tensor, body, betas_from, betas_to) -> torch.Tensor:
    """Rest-pose points (N, 3) moved from body shape ``betas_from`` to ``betas_to`` ((S',) each, zero-padded
    by :meth:`BodyModel.full_betas`) by the body's shape blend shape at their bound vertices ``index`` (N,)."""
    dbeta = (body.full_betas(betas_to) - body.full_betas(betas_from)).reshape(-1).to(points.device, points.dtype)
    dirs = body.shapedirs[index].to(points.dtype)  # (N, 3, S)
    return points + torch.einsum("vcs,s->vc", dirs, dbeta)

