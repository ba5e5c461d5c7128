"""GAPS's settings and their defaults: the model (:class:`GapsParams`), the training keys only GAPS reads
(:class:`GapsTrain`, under ``method.params.train``; the budget itself is ``conf/train``), and the solver settings
of ``gaps_optimum`` (:class:`GapsOptimumSettings`, under ``method.params.optimum``).

Training defaults are the paper's / public code's; ``conf/method/gaps_budget/<train preset>.yaml``
gives the values a training preset needs (e.g. the CPU budget's k_ext ramp)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal, Mapping

from drapebench.keys import is_number
from drapebench.optimum import SolverSettings
from methods.params import at_least, params_dict, positive, schedule


@dataclass(frozen=True)
class GapsTrain:
    """The training keys only GAPS reads (``method.params.train``)."""

    window: int = 3  # consecutive frames per training item (at least 3: inertia reads the two frames before the last)
    lr_output_factor: float = 1.0  # the output layer's learning rate relative to train.lr
    kext_ramp_epochs: int = 100  # epochs over which k_ext rises to its cap (GAPS Eq. 16; at least 1: 1 reaches it after the first)
    hidden_init_std: float = 0.1  # GRU state drawn from N(0, std^2) in training
    beta_range: tuple[float, ...] = (2.0, 2.0, 2.0, 2.0)  # beta_k ~ U(-r_k, r_k) on the first len(beta_range) components (the code)
    output_adam_eps: float = 1e-8  # Adam's eps for the output layer (torch's default; the code's Keras default is 1e-7)
    output_smoothing: int = 0  # rounds of 1-ring averaging of the output layer's gradient over the garment (0: none, the paper)
    exclude_motions: tuple[str, ...] = ()  # motions of the training dataset left out of GAPS's training windows
    redraw_motions: bool = False  # each epoch after the first trains on a new draw of train.dataset (new motions and shapes)
    schedule: dict = schedule()  # overrides of the budget (conf/train) for GAPS alone, e.g. {lr: 1.0e-3, grad_clip: 50}

    def __post_init__(self) -> None:
        at_least("gaps", "train.", self, window=3, kext_ramp_epochs=1, hidden_init_std=0, output_smoothing=0, lr_output_factor=0)
        positive("gaps", "train.", self, "output_adam_eps")
        if any(not is_number(r) or r < 0 for r in self.beta_range):
            raise ValueError(f"gaps parameter method.params.train.beta_range holds the half-widths (>= 0) of the shapes training draws, got {list(self.beta_range)}")


@dataclass(frozen=True)
class GapsParams:
    """GAPS's model and loss settings (``method.params``)."""

    skinning: Literal["rbf", "nearest", "smoothed"] = "rbf"
    rbf_k: float = 0.25
    smooth_iterations: int = 10
    trainable_weights: bool = False  # the code trains them; frozen here (methods/gaps/README.md)
    shape_transfer: Literal["none", "nearest", "rbf"] = "rbf"  # none (the paper) | nearest (SNUG) | rbf: the body's shape blend shape at the garment
    canonical: Literal["template", "relaxed"] = "template"  # template: the garment as cut | relaxed: at rest under GAPS's loss on the rest-pose body (methods/gaps/canonical.py)
    relax_grid: tuple[float, ...] = (-2.0, 0.0, 2.0)  # canonical: relaxed: shape-offset values solved on each relaxed component
    relax_components: int = 2  # canonical: relaxed: the first that many shape components are relaxed (grid: len(relax_grid)^K solves)
    relax_iterations: int = 200  # canonical: relaxed: L-BFGS iterations of each solve
    relax_clearance: float = 6e-3  # canonical: relaxed: the collision margin (m) of the solves (training's is collision_eps)
    relax_inextensibility_weight: float | None = None  # canonical: relaxed: L_inext's weight in the solves (None: inextensibility_weight)
    normalisation: Literal["code", "batch"] = "code"  # code: per-frame terms / (B x W), collision and inertia / B | batch: every term / B
    inextensibility_weight: float = 2e8
    kext: Literal["collision", "one"] = "collision"
    kext_gradient: bool = True  # k_ext differentiated through the body distance n . (x - p), as the code's | false: held constant
    collision_weight: float = 250.0
    collision_eps: float = 2e-3
    collision_distance: Literal["surface", "vertex"] = "surface"  # surface: exact signed distance to the body mesh | vertex: nearest body vertex (the code)
    bending: Literal["blend", "flat", "template"] = "blend"
    bending_scale: Literal["edge", "rest"] = "edge"  # edge: the hinge's deformed length over its rest face areas (the code) | rest: both at rest
    bending_blend: Literal["normal", "distance"] = "normal"  # blend's alpha from the signed distance along the nearest body vertex's normal (the code) | distance: its Euclidean distance
    single_shape: bool = False  # NCS: train on the mean body only
    normalize_inputs: bool = False  # the code: raw inputs; conf/method/gaps.yaml standardises them (methods/gaps/README.md)
    hidden: int = 256
    layers: int = 4
    zero_init_output: bool = True
    output_basis: Literal["dense", "laplacian"] = "dense"  # dense: V x 3 displacements (the paper) | laplacian: basis_modes Laplacian eigenmodes of the template (beyond the paper; methods/gaps/basis.py)
    basis_modes: int = 128  # output_basis: laplacian: the number K of lowest-frequency modes (the network outputs K x 3 coefficients)
    collision_postprocess: bool = False  # SNUG's push-out at inference; off unless a config asks for it
    train: GapsTrain = field(default_factory=GapsTrain)

    def __post_init__(self) -> None:
        positive("gaps", "", self, "rbf_k")  # 0: every RBF weight 0/0
        at_least("gaps", "", self, collision_eps=0, relax_clearance=0, smooth_iterations=0, relax_components=0, relax_iterations=0,
                 inextensibility_weight=0, collision_weight=0, hidden=1, layers=1, basis_modes=1)  # fmt: skip
        if self.relax_inextensibility_weight is not None:
            at_least("gaps", "", self, relax_inextensibility_weight=0)
        if not self.relax_grid or any(not is_number(v) for v in self.relax_grid):
            raise ValueError(f"gaps parameter method.params.relax_grid lists the shape-offset values the relaxation solves at (numbers), got {list(self.relax_grid)}")


ADDED_KEYS = dict(canonical="template", relax_grid=(-2.0, 0.0, 2.0), relax_components=2, relax_iterations=200, relax_clearance=2e-3,
                  relax_inextensibility_weight=None, bending_scale="rest", bending_blend="distance",
                  output_basis="dense", basis_modes=128, kext_gradient=False)  # keys newer than some checkpoints, at the behaviour those were trained with


@dataclass(frozen=True)
class GapsOptimumSettings(SolverSettings):
    """``gaps_optimum``'s solver settings (``method.params.optimum``)."""

    kext_epoch: int | None = None  # the training epoch whose k_ext the loss uses; None: the end of train.kext_ramp_epochs (its final value)


def gaps_params(cfg: Mapping[str, Any] | None) -> dict:
    """GAPS's parameters as a dict: :class:`GapsParams` from ``cfg`` (``method.params``). Raises ValueError naming
    an unknown key or an invalid choice."""
    return params_dict(GapsParams, cfg, "gaps")


def optimum_params(cfg: Mapping[str, Any] | None) -> dict:
    """The solver settings of ``gaps_optimum`` as a dict: :class:`GapsOptimumSettings` from ``cfg``
    (``method.params.optimum``). Raises ValueError naming an unknown key (as ``method.params.optimum.<key>``), an
    invalid solver, or a section given as null or a scalar."""
    return params_dict(GapsOptimumSettings, cfg, "gaps_optimum", section="optimum")
