"""The VAE collision model's settings and their defaults (:class:`VaeParams`, ``method.params``; the reference data
it trains on is the ``data`` config group, the shared budget ``conf/train``).

Every value the paper leaves open is chosen here and listed in ``methods/vae/README.md``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal, Mapping

from methods.params import params_dict, schedule


@dataclass(frozen=True)
class Projection:
    """The projection of reference drapes to the canonical space (``method.params.projection``)."""

    init: Literal["inverse_skinning", "previous"] = "previous"  # previous: each frame starts from the previous frame's X (the paper) | inverse_skinning: then 2 fixed-point inversions
    steps: int = 40  # Adam steps per frame (the first frame: 4x)
    lr: float = 2.0e-4  # m per step
    strain_weight: float = 1.0  # w1 of Eq. 9 on the mean squared Green-Lagrange strain (Eq. 11)
    collision_weight: float = 300.0  # w2 of Eq. 9 on the mean hinge max(eps - SDF(X), 0) in mm (Eq. 12)
    eps: float = 0.002  # collision margin (m) of Eq. 12 and Eq. 16


@dataclass(frozen=True)
class Vae:
    """The garment VAE and its training (``method.params.vae``)."""

    latent: int = 25  # latent size (the paper does not state it)
    hidden: tuple[int, ...] = (512, 256)  # encoder widths; the decoder mirrors them
    laplacian: float = 1.0  # lambda_1 of Eq. 13 (Eq. 15, L1 of mesh Laplacians, mm)
    collision: float = 1.0  # lambda_2 (Eq. 16, mean hinge in mm over vertices)
    selfsup: bool = True  # the second (sampled latent) term of Eq. 16; vae_no_selfsup: False
    kl: float = 3.0e-2  # lambda_3 (KL per sample, summed over latent dimensions): training codes' per-dimension std about 1.5
    kl_warmup: float = 0.3  # fraction of the VAE's steps over which lambda_3 ramps linearly from 0 (0: constant; without it 3e-2 collapses the posterior)
    logvar_init: float | None = None  # initial bias of the log-variance head: posterior sigma starts at exp(-3) = 0.05 (None: sigma ~ 1)
    samples: int = 8  # latent samples per step for the self-supervised term
    sample_scale: str | float = "prior"  # where they are drawn: prior (z ~ N(0, I), the paper) | codes (the batch codes' mean and std, a diagnostic) | a number s (N(0, s^2 I))
    steps: int | None = None  # training steps; None: the budget's (conf/train and schedule below)
    # max_minutes: a guard above the 16 min the 1,920 steps of data=cpu's tshirt take on one loaded thread (train=cpu's 9.5 cut them at half)
    schedule: dict = schedule(epochs=60, batch_size=32, lr=1.0e-3, lr_after=1.0e-4, lr_switch_epoch=45, ema_decay=None,
                              lr_decay_fraction=None, grad_clip=10.0, checkpoint_every=200, max_minutes=40.0)  # fmt: skip

    def __post_init__(self) -> None:
        scale = self.sample_scale
        if scale not in ("prior", "codes") and not (isinstance(scale, (int, float)) and not isinstance(scale, bool) and scale > 0):
            raise ValueError(f"vae parameter vae.sample_scale must be prior, codes or a positive number, not {scale!r}")
        if not 0 <= float(self.kl_warmup) < 1:
            raise ValueError(f"vae parameter vae.kl_warmup must be a fraction of the steps in [0, 1), got {self.kl_warmup}")
        if int(self.latent) < 1:
            raise ValueError(f"vae parameter vae.latent must be >= 1, got {self.latent}")


@dataclass(frozen=True)
class Regressor:
    """The regressor of the latent code from the body's motion (``method.params.regressor``)."""

    pose: Literal["learned", "rotations"] = "learned"  # learned (a 10-D pose descriptor, the paper's [52]) | rotations (the joints' axis-angles)
    pose_code: int = 10  # size of the learned pose descriptor
    betas: int = 10  # leading body-shape components in the regressor's input (the paper: beta in R^10; the public model: 4; 0: none)
    root: Literal["world", "vertical"] = "world"  # root translation velocity/acceleration: world (3 components, the paper's text) | vertical (z only, the public model)
    pose_steps: int = 1500  # training steps of the pose descriptor's autoencoder (batch 256)
    pose_sequences: int = 16  # generated sequences per motion kind of the training sequences that the pose descriptor also trains on (0: the training poses only)
    predict: Literal["gru", "mean_code"] = "gru"  # gru (the paper) | mean_code: every frame decodes the training codes' mean (vae_mean_code, a control)
    hidden: int = 256
    layers: int = 2
    dropout: float = 0.0  # between the GRU's layers (the paper states none)
    weight_decay: float = 0.0  # L2 penalty on the regressor's weights, Adam's (the paper states none)
    window: int = 30  # frames per training window (the GRU starts from a zero state)
    window_stride: int = 5  # frames between the starts of consecutive training windows
    select: Literal["validation", "last"] = "last"  # last: the last epoch's weights (the paper) | validation: the epoch's whose decoded codes are closest (mm) to the held-out validation sequences' garments (val_sequences)
    velocity: float = 1.0  # rho_1 of Eq. 18
    acceleration: float = 1.0  # rho_2
    schedule: dict = schedule(epochs=150, batch_size=8, lr=1.0e-3, lr_after=1.0e-4, lr_switch_epoch=120, ema_decay=None,
                              lr_decay_fraction=None, grad_clip=10.0, checkpoint_every=200, max_minutes=40.0)  # fmt: skip

    def __post_init__(self) -> None:
        for key, least in (("pose_sequences", 0), ("window_stride", 1), ("dropout", 0), ("weight_decay", 0)):
            if float(getattr(self, key)) < least:
                raise ValueError(f"vae parameter regressor.{key} must be >= {least}, got {getattr(self, key)}")
        if not float(self.dropout) < 1:
            raise ValueError(f"vae parameter regressor.dropout must be in [0, 1), got {self.dropout}")
        if int(self.betas) < 0:
            raise ValueError(f"vae parameter regressor.betas must be >= 0 (leading shape components), got {self.betas}")


@dataclass(frozen=True)
class VaeParams:
    """The VAE model's settings (``method.params``)."""

    diffused: dict = field(default_factory=dict)  # drapebench.body.diffused settings (N samples, spread, MLP sizes), see DIFFUSED_DEFAULTS
    sdf: dict = field(default_factory=dict)  # drapebench.body.canonical_sdf settings of the canonical body's learned SDF
    projection: Projection = field(default_factory=Projection)
    vae: Vae = field(default_factory=Vae)
    regressor: Regressor = field(default_factory=Regressor)
    val_sequences: int = 3  # reference sequences held out of training, spread over the motion kinds: the validation set of Fig. 4 and of the regressor


def vae_params(cfg: Mapping[str, Any] | None) -> dict:
    """The VAE model's parameters as a dict: :class:`VaeParams` from ``cfg`` (``method.params``). Raises ValueError
    naming an unknown key, a bad choice or a bad value."""
    return params_dict(VaeParams, cfg, "vae")
