"""GAPS's settings and their defaults: the model (``METHOD_DEFAULTS``) and the training keys only GAPS
reads (``TRAIN_DEFAULTS``, under ``method.params.train``; the budget itself is ``conf/train``), and the
solver settings of ``gaps_optimum`` (``OPTIMUM_DEFAULTS``, under ``method.params.optimum``).

Training defaults are the paper's / public code's; ``conf/method/gaps_budget/<train preset>.yaml``
gives the values a training preset needs (e.g. the CPU budget's k_ext ramp)."""

from __future__ import annotations

from typing import Any, Mapping

from drapebench.optimum import SOLVER_DEFAULTS, SOLVERS
from methods.params import method_params

TRAIN_DEFAULTS = dict(
    window=3,  # consecutive frames per training item
    lr_output_factor=1.0,  # the output layer's learning rate relative to train.lr
    kext_ramp_epochs=100,  # epochs over which k_ext rises to its cap (GAPS Eq. 16)
    hidden_init_std=0.1,  # GRU state drawn from N(0, std^2) in training
    beta_range=(2.0, 2.0, 2.0, 2.0),  # beta_k ~ U(-r_k, r_k) on the first len(beta_range) components (the code)
    output_adam_eps=1e-8,  # Adam's eps for the output layer (torch's default; the code's Keras default is 1e-7)
    output_smoothing=0,  # rounds of 1-ring averaging of the output layer's gradient over the garment (0: none, the paper)
    exclude_motions=(),  # motions of the training dataset left out of GAPS's training windows
    redraw_motions=False,  # each epoch after the first trains on a new draw of train.dataset (new motions and shapes)
    schedule={},  # overrides of the budget (conf/train) for GAPS alone, e.g. {lr: 1.0e-3, grad_clip: 50}
)
METHOD_DEFAULTS = dict(
    skinning="rbf",  # rbf | nearest | smoothed
    rbf_k=0.25,
    smooth_iterations=10,
    trainable_weights=False,  # the code trains them; frozen here (methods/gaps/README.md)
    shape_transfer="rbf",  # none (the paper) | nearest (SNUG) | rbf: the body's shape blend shape at the garment
    canonical="template",  # template: the garment as cut | relaxed: at rest under GAPS's loss on the rest-pose body (methods/gaps/canonical.py)
    relax_grid=(-2.0, 0.0, 2.0),  # canonical: relaxed: shape-offset values solved on each relaxed component
    relax_components=2,  # canonical: relaxed: the first that many shape components are relaxed (grid: len(relax_grid)^K solves)
    relax_iterations=200,  # canonical: relaxed: L-BFGS iterations of each solve
    relax_clearance=6e-3,  # canonical: relaxed: the collision margin (m) of the solves (training's is collision_eps)
    relax_inextensibility_weight=None,  # canonical: relaxed: L_inext's weight in the solves (None: inextensibility_weight)
    normalisation="code",  # code: per-frame terms / (B x W), collision and inertia / B | batch: every term / B
    inextensibility_weight=2e8,
    kext="collision",  # collision | one
    collision_weight=250.0,
    collision_eps=2e-3,
    collision_distance="surface",  # surface: exact signed distance to the body mesh | vertex: nearest body vertex (the code)
    bending="blend",  # blend | flat | template
    bending_scale="edge",  # edge: the hinge's deformed length over its rest face areas (the code) | rest: both at rest
    bending_blend="normal",  # blend's alpha from the signed distance along the nearest body vertex's normal (the code) | distance: its Euclidean distance
    single_shape=False,  # NCS: train on the mean body only
    normalize_inputs=False,  # the code: raw inputs; conf/method/gaps.yaml standardises them (methods/gaps/README.md)
    hidden=256,
    layers=4,
    zero_init_output=True,
    collision_postprocess=False,  # SNUG's push-out at inference; off unless a config asks for it
    train=TRAIN_DEFAULTS,
)
ADDED_KEYS = dict(canonical="template", relax_grid=(-2.0, 0.0, 2.0), relax_components=2, relax_iterations=200, relax_clearance=2e-3,
                  relax_inextensibility_weight=None, bending_scale="rest", bending_blend="distance")  # keys newer than some checkpoints, at the behaviour those were trained with
OPTIMUM_DEFAULTS = dict(
    **SOLVER_DEFAULTS,  # drapebench.optimum: solver, iterations, lr, history
    kext_epoch=None,  # the training epoch whose k_ext the loss uses; None: the end of train.kext_ramp_epochs (its final value)
)
CHOICES = dict(skinning=("rbf", "nearest", "smoothed"), shape_transfer=("none", "nearest", "rbf"), canonical=("template", "relaxed"), normalisation=("code", "batch"),
               collision_distance=("surface", "vertex"), kext=("collision", "one"), bending=("blend", "flat", "template"),
               bending_scale=("edge", "rest"), bending_blend=("normal", "distance"))  # fmt: skip


def gaps_params(cfg: Mapping[str, Any] | None) -> dict:
    """GAPS's parameters: the defaults updated by ``cfg`` (``method.params``; its ``train`` sub-dict
    updates ``TRAIN_DEFAULTS``). Raises ValueError naming an unknown key or an invalid choice."""
    return method_params("gaps", cfg, METHOD_DEFAULTS, {"train": TRAIN_DEFAULTS}, CHOICES)


def optimum_params(cfg: Mapping[str, Any] | None) -> dict:
    """The solver settings of ``gaps_optimum`` (``method.params.optimum``): ``OPTIMUM_DEFAULTS`` updated by
    ``cfg``. Raises ValueError naming an unknown key or an invalid solver."""
    return method_params("gaps_optimum", cfg, OPTIMUM_DEFAULTS, choices={"solver": SOLVERS})
