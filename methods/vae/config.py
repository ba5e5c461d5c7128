"""The VAE collision model's settings and their defaults (``method.params``; the reference data it trains
on is the ``data`` config group, the shared budget ``conf/train``).

Every value the paper leaves open is chosen here and listed in ``methods/vae/README.md``.
"""

from __future__ import annotations

from typing import Any, Mapping

from methods.params import method_params

PROJECTION_DEFAULTS = dict(
    init="previous",  # previous: each frame starts from the previous frame's X (the paper) | inverse_skinning: then 2 fixed-point inversions
    steps=40,  # Adam steps per frame (the first frame: 4x)
    lr=2.0e-4,  # m per step
    strain_weight=1.0,  # w1 of Eq. 9 on the mean squared Green-Lagrange strain (Eq. 11)
    collision_weight=300.0,  # w2 of Eq. 9 on the mean hinge max(eps - SDF(X), 0) in mm (Eq. 12)
    eps=0.002,  # collision margin (m) of Eq. 12 and Eq. 16
)
VAE_DEFAULTS = dict(
    latent=25,  # latent size (the paper does not state it)
    hidden=(512, 256),  # encoder widths; the decoder mirrors them
    laplacian=1.0,  # lambda_1 of Eq. 13 (Eq. 15, L1 of mesh Laplacians, mm)
    collision=1.0,  # lambda_2 (Eq. 16, mean hinge in mm over vertices)
    selfsup=True,  # the second (sampled latent) term of Eq. 16; vae_no_selfsup: False
    kl=3.0e-2,  # lambda_3 (KL per sample, summed over latent dimensions): training codes' per-dimension std about 1.5
    kl_warmup=0.3,  # fraction of the VAE's steps over which lambda_3 ramps linearly from 0 (0: constant; without it 3e-2 collapses the posterior)
    logvar_init=None,  # initial bias of the log-variance head: posterior sigma starts at exp(-3) = 0.05 (None: sigma ~ 1)
    samples=8,  # latent samples per step for the self-supervised term
    sample_scale="prior",  # where they are drawn: prior (z ~ N(0, I), the paper) | codes (the batch codes' mean and std, a diagnostic) | a number s (N(0, s^2 I))
    steps=None,  # training steps; None: the budget's (conf/train and schedule below)
    schedule=dict(epochs=60, batch_size=32, lr=1.0e-3, lr_after=1.0e-4, lr_switch_epoch=45, ema_decay=None,
                  lr_decay_fraction=None, grad_clip=10.0, checkpoint_every=200, max_minutes=40.0),  # fmt: skip
)  # max_minutes: a guard above the 16 min the 1,920 steps of data=cpu's tshirt take on one loaded thread (train=cpu's 9.5 cut them at half)
REGRESSOR_DEFAULTS = dict(
    pose="learned",  # learned (a 10-D pose descriptor, the paper's [52]) | rotations (the joints' axis-angles)
    pose_code=10,  # size of the learned pose descriptor
    betas=10,  # leading body-shape components in the regressor's input (the paper: beta in R^10; the public model: 4; 0: none)
    root="world",  # root translation velocity/acceleration: world (3 components, the paper's text) | vertical (z only, the public model)
    pose_steps=1500,  # training steps of the pose descriptor's autoencoder (batch 256)
    pose_sequences=16,  # generated sequences per motion kind of the training sequences that the pose descriptor also trains on (0: the training poses only)
    predict="gru",  # gru (the paper) | mean_code: every frame decodes the training codes' mean (vae_mean_code, a control)
    hidden=256,
    layers=2,
    dropout=0.0,  # between the GRU's layers (the paper states none)
    weight_decay=0.0,  # L2 penalty on the regressor's weights, Adam's (the paper states none)
    window=30,  # frames per training window (the GRU starts from a zero state)
    window_stride=5,  # frames between the starts of consecutive training windows
    select="last",  # last: the last epoch's weights (the paper) | validation: the epoch's whose decoded codes are closest (mm) to the held-out validation sequences' garments (val_sequences)
    velocity=1.0,  # rho_1 of Eq. 18
    acceleration=1.0,  # rho_2
    schedule=dict(epochs=150, batch_size=8, lr=1.0e-3, lr_after=1.0e-4, lr_switch_epoch=120, ema_decay=None,
                  lr_decay_fraction=None, grad_clip=10.0, checkpoint_every=200, max_minutes=40.0),  # fmt: skip
)
METHOD_DEFAULTS = dict(
    diffused={},  # drapebench.body.diffused settings (N samples, spread, MLP sizes), see DIFFUSED_DEFAULTS
    sdf={},  # drapebench.body.canonical_sdf settings of the canonical body's learned SDF
    projection=PROJECTION_DEFAULTS,
    vae=VAE_DEFAULTS,
    regressor=REGRESSOR_DEFAULTS,
    val_sequences=3,  # reference sequences held out of training, spread over the motion kinds: the validation set of Fig. 4 and of the regressor
)


def vae_params(cfg: Mapping[str, Any] | None) -> dict:
    """The VAE model's parameters: the defaults updated by ``cfg`` (``method.params``; ``projection``, ``vae``
    and ``regressor`` update their own defaults). Raises ValueError naming an unknown key or a bad choice."""
    p = method_params("vae", cfg, METHOD_DEFAULTS, {"projection": PROJECTION_DEFAULTS, "vae": VAE_DEFAULTS,
                                                     "regressor": REGRESSOR_DEFAULTS})  # fmt: skip
    for section, key, allowed in (("projection", "init", ("inverse_skinning", "previous")), ("regressor", "pose", ("learned", "rotations")),
                                  ("regressor", "root", ("world", "vertical")), ("regressor", "select", ("validation", "last")),
                                  ("regressor", "predict", ("gru", "mean_code"))):  # fmt: skip
        if p[section][key] not in allowed:
            raise ValueError(f"vae parameter {section}.{key} must be one of {', '.join(allowed)}, not {p[section][key]!r}")
    scale = p["vae"]["sample_scale"]
    if scale not in ("prior", "codes") and not (isinstance(scale, (int, float)) and not isinstance(scale, bool) and scale > 0):
        raise ValueError(f"vae parameter vae.sample_scale must be prior, codes or a positive number, not {scale!r}")
    if not 0 <= float(p["vae"]["kl_warmup"]) < 1:
        raise ValueError(f"vae parameter vae.kl_warmup must be a fraction of the steps in [0, 1), got {p['vae']['kl_warmup']}")
    for key, least in (("pose_sequences", 0), ("window_stride", 1), ("dropout", 0), ("weight_decay", 0)):
        if float(p["regressor"][key]) < least:
            raise ValueError(f"vae parameter regressor.{key} must be >= {least}, got {p['regressor'][key]}")
    if not float(p["regressor"]["dropout"]) < 1:
        raise ValueError(f"vae parameter regressor.dropout must be in [0, 1), got {p['regressor']['dropout']}")
    if int(p["regressor"]["betas"]) < 0:
        raise ValueError(f"vae parameter regressor.betas must be >= 0 (leading shape components), got {p['regressor']['betas']}")
    if int(p["vae"]["latent"]) < 1:
        raise ValueError(f"vae parameter vae.latent must be >= 1, got {p['vae']['latent']}")
    return p
