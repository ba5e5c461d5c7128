"""GAPS's network: a GRU regressing canonical garment displacements per frame."""

from __future__ import annotations

import torch


class GapsNet(torch.nn.Module):
    """GRU regressor: (B, T, in) -> (B, T, V*3) canonical displacements (m); returns the new hidden state too.

    Without ``basis`` (the paper) the output layer predicts the V x 3 displacements directly; with ``basis`` (V, K)
    (``output_basis: laplacian``, :mod:`methods.gaps.basis`) it predicts K x 3 coefficients, which the basis's
    columns map to V x 3 displacements, so every output lies in the basis's span."""

    def __init__(self, n_in: int, n_out: int, hidden: int = 256, layers: int = 4, zero_init_output: bool = True,
                 basis: torch.Tensor | None = None):  # fmt: skip
        super().__init__()
        if basis is not None and 3 * basis.shape[0] != n_out:
            raise ValueError(f"GapsNet: a basis of {basis.shape[0]} vertices for {n_out} outputs (3 per vertex)")
        self.n_out = n_out
        self.gru = torch.nn.GRU(n_in, hidden, num_layers=layers, batch_first=True)
        self.out = torch.nn.Linear(hidden, n_out if basis is None else 3 * basis.shape[1])
        self.register_buffer("basis", basis)  # in the state dict (unless None): a checkpoint carries the basis it was trained with
        if zero_init_output:  # start from the skinned template instead of displacements of tens of cm
            torch.nn.init.zeros_(self.out.weight)
            torch.nn.init.zeros_(self.out.bias)

    def displacements(self, y: torch.Tensor) -> torch.Tensor:
        """The output layer on GRU outputs y (..., hidden): (..., V*3) displacements (m)."""
        c = self.out(y)
        if self.basis is None:
            return c
        return torch.einsum("vk,...kc->...vc", self.basis, c.unflatten(-1, (-1, 3))).flatten(-2)

    def forward(self, x: torch.Tensor, h0: torch.Tensor | None = None):
        y, h = self.gru(x, h0)
        return self.displacements(y), h
