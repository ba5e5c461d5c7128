"""The garment model of Eq. 7-8: canonical (unposed, deshaped) vertices X, the diffused shape (and pose)
offsets added, then skinned with the diffused weights evaluated at X. The same function unprojects a
canonical garment and is the data term of the projection (Eq. 10)."""

from __future__ import annotations

import torch

from drapebench.body.lbs import lbs


def unposed(diffused, X: torch.Tensor, betas: torch.Tensor) -> torch.Tensor:
    """T_G of Eq. 8 without pose correctives: X (B, V, 3) m + the diffused shape offsets of body shape
    betas (B, S) -> (B, V, 3) m on the shaped rest body."""
    return X + diffused.shape_offsets(X, betas[:, None, :].expand(-1, X.shape[1], -1))


def pose_garments(diffused, X: torch.Tensor, betas: torch.Tensor, transforms: torch.Tensor) -> torch.Tensor:
    """:func:`garment_model` for one body shape betas (S',) shared by all B garments X (B, V, 3) m with
    transforms (B, J, 4, 4): the diffused weights and shape offsets in one pass
    (``diffused.weights_and_shape_offsets``) -> (B, V, 3) m; inference only."""
    weights, offsets = diffused.weights_and_shape_offsets(X, betas)
    return lbs(X + offsets, weights, transforms)


def garment_model(diffused, X: torch.Tensor, betas: torch.Tensor, transforms: torch.Tensor, rest: torch.Tensor | None = None) -> torch.Tensor:
    """M_G of Eq. 7: canonical vertices X (B, V, 3) m posed by the body's skinning transforms (B, J, 4, 4)
    (translation included) for body shapes betas (B, S) -> (B, V, 3) m; ``rest`` is T_G when already
    computed (:func:`unposed`). Differentiable in X."""
    return lbs(unposed(diffused, X, betas) if rest is None else rest, diffused.weights(X), transforms)
