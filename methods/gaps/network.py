"""GAPS's network: a GRU regressing canonical garment displacements per frame."""

from __future__ import annotations

import torch


class GapsNet(torch.nn.Module):
    """GRU regressor: (B, T, in) -> (B, T, V*3) canonical displacements (m); returns the new hidden state too."""

    def __init__(self, n_in: int, n_out: int, hidden: int = 256, layers: int = 4, zero_init_output: bool = True):
        super().__init__()
        self.gru = torch.nn.GRU(n_in, hidden, num_layers=layers, batch_first=True)
        self.out = torch.nn.Linear(hidden, n_out)
        if zero_init_output:  # start from the skinned template instead of displacements of tens of cm
            torch.nn.init.zeros_(self.out.weight)
            torch.nn.init.zeros_(self.out.bias)

    def forward(self, x: torch.Tensor, h0: torch.Tensor | None = None):
        y, h = self.gru(x, h0)
        return self.out(y), h
