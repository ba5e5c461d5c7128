"""The VAE collision model's networks: the garment VAE (Eq. 13-16), the pose descriptor and the GRU regressor (Eq. 17-18)."""

from __future__ import annotations

import torch


def mlp(sizes: list[int], last_activation: bool = False) -> torch.nn.Sequential:
    """Fully connected layers of ``sizes`` (in, hidden..., out) with ReLU between them."""
    layers = []
    for i, (a, b) in enumerate(zip(sizes[:-1], sizes[1:])):
        layers.append(torch.nn.Linear(a, b))
        if i < len(sizes) - 2 or last_activation:
            layers.append(torch.nn.ReLU())
    return torch.nn.Sequential(*layers)


class GarmentVAE(torch.nn.Module):
    """Fully connected VAE of canonical garments: X (B, V, 3) m is normalised by the training mean (V, 3)
    and one scale (m), encoded to a Gaussian of ``latent`` dimensions and decoded back to (B, V, 3) m.
    ``logvar_init`` (None: PyTorch's default initialisation, posterior sigma about 1 at the start) sets the
    log-variance head's bias and scales its weights by 0.01, so training starts at sigma = exp(logvar_init / 2).
    The buffers ``code_mean``, ``code_std`` (latent,) hold the per-dimension mean and std of the training
    garments' posterior means (set after training; 0 and 1 before)."""

    def __init__(self, n_vertices: int, latent: int = 25, hidden=(512, 256), logvar_init: float | None = None):
        super().__init__()
        hidden = [int(h) for h in hidden]
        self.encoder = mlp([3 * n_vertices, *hidden], last_activation=True)
        self.mu = torch.nn.Linear(hidden[-1], latent)
        self.logvar = torch.nn.Linear(hidden[-1], latent)
        if logvar_init is not None:
            with torch.no_grad():
                self.logvar.bias.fill_(float(logvar_init))
                self.logvar.weight.mul_(0.01)
        self.decoder = mlp([latent, *hidden[::-1], 3 * n_vertices])
        self.register_buffer("mean", torch.zeros(n_vertices, 3))
        self.register_buffer("scale", torch.ones(()))
        self.register_buffer("code_mean", torch.zeros(latent))
        self.register_buffer("code_std", torch.ones(latent))
        self.latent = latent

    def encode(self, X: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Mean and log-variance (B, latent) of the posterior of canonical garments X (B, V, 3)."""
        h = self.encoder(((X - self.mean) / self.scale).flatten(1))
        return self.mu(h), self.logvar(h).clamp(-20.0, 10.0)

    def decode(self, z: torch.Tensor) -> torch.Tensor:
        """Canonical garments (B, V, 3) m of latent codes z (B, latent)."""
        return self.mean + self.scale * self.decoder(z).reshape(len(z), -1, 3)


class PoseDescriptor(torch.nn.Module):
    """The learned pose descriptor: an autoencoder of the non-root joint rotations (as rotation matrices)
    whose ``code`` (B, pose_code) replaces the joint rotations in the motion descriptor."""

    def __init__(self, n_joints: int, pose_code: int = 10, hidden: int = 128):
        super().__init__()
        n_in = 9 * (n_joints - 1)
        self.encoder = mlp([n_in, hidden, hidden, pose_code])
        self.decoder = mlp([pose_code, hidden, hidden, n_in])

    def code(self, rotations: torch.Tensor) -> torch.Tensor:
        """(..., pose_code) codes of non-root joint rotation matrices (..., J-1, 3, 3)."""
        return self.encoder(rotations.flatten(-3))

    def forward(self, rotations: torch.Tensor) -> torch.Tensor:
        """Reconstructed rotation matrices (flattened, (..., 9 (J-1))) of rotations (..., J-1, 3, 3)."""
        return self.decoder(self.code(rotations))


class Regressor(torch.nn.Module):
    """GRU regressor R(beta, gamma): per-frame inputs (B, T, n_in) (motion descriptor and body shape,
    normalised by the training statistics) -> latent codes (B, T, latent); ``dropout`` on the outputs of every
    GRU layer but the last (in training mode only)."""

    def __init__(self, n_in: int, latent: int, hidden: int = 256, layers: int = 2, dropout: float = 0.0):
        super().__init__()
        self.gru = torch.nn.GRU(n_in, hidden, num_layers=layers, batch_first=True, dropout=float(dropout) if layers > 1 else 0.0)
        self.out = torch.nn.Linear(hidden, latent)
        self.register_buffer("input_mean", torch.zeros(n_in))
        self.register_buffer("input_std", torch.ones(n_in))

    def forward(self, x: torch.Tensor, h0: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        y, h = self.gru((x - self.input_mean) / self.input_std, h0)
        return self.out(y), h
