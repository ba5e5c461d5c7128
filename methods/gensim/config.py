"""GenSim's settings and their defaults (:class:`GensimParams`, ``method.params``; the training budget itself is
``conf/train``).

``train`` (:class:`GensimTrain`) holds what only GenSim reads in training: the training garments (kinds, size
seeds, mesh resolutions), the random motions and body shapes they are posed on, and ``schedule``: values of the
budget (lr, epochs, ...) that GenSim's paper sets differently from the shared preset;
``conf/method/gensim_budget/<train preset>.yaml`` fills it per preset.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal, Mapping

from drapebench.optimum import SolverSettings
from methods.gensim.losses import WEIGHTS
from methods.params import params_dict, schedule


@dataclass(frozen=True)
class GensimTrain:
    """What only GenSim reads in training (``method.params.train``)."""

    body: str | None = None  # the body the training frames are posed on: None = the run's body (e.g. anny_lowres: faster)
    # tops and skirts (paper Sec. 4) as [kind, factory parameters]: tshirt, tank, longsleeve, skirt, the
    # flared and the straight skirt of conf/garment/skirt_flared.yaml and skirt_straight.yaml
    garments: tuple = (("tshirt", {}), ("tank", {}), ("longsleeve", {}), ("skirt", {}), ("skirt", {"flare": 0.3}), ("skirt", {"flare": 0.02}))
    seeds: tuple[int, ...] = (1, 2)  # garment size variations (drapebench.garments.factory: ease x0.9-1.1, length +-3 cm)
    resolutions: tuple[float, ...] = (0.015, 0.022)  # target edge length (m): two mesh resolutions per garment
    sequences: int = 8  # motion sequences per garment
    motions: tuple[str, ...] = ("random", "walk")  # sequence k of garment g: motions[(g x sequences + k) % len(motions)] (drapebench.body.dataset.TRAIN_MOTIONS or random)
    n_frames: int = 60  # frames per sequence (after the transition from the rest pose)
    frames_per_sequence: int = 6  # frames sampled per sequence (GenSim is quasi-static: frames are independent)
    beta_std: float = 1.0  # body shapes: betas ~ N(0, beta_std^2) clipped to +-beta_clip on the first n_shape_betas
    beta_clip: float = 2.0
    n_shape_betas: int = 4
    threads: int | None = 1  # torch threads while training (1: jobs that share the cores do not oversubscribe them; None: leave as set)
    schedule: dict = schedule()  # overrides of the budget (conf/train) for GenSim, e.g. the paper's lr 1e-4 x0.1 at epoch 20 of 30

    def __post_init__(self) -> None:
        from drapebench.body.dataset import HELD_OUT_MOTIONS, TRAIN_MOTIONS

        unknown = sorted(set(self.motions) - {"random", *TRAIN_MOTIONS})
        if not self.motions or unknown:
            raise ValueError(f"gensim: method.params.train.motions must name training motions ({', '.join(('random', *TRAIN_MOTIONS))}), "
                             f"not {unknown or 'none'}; the held-out ones ({', '.join(HELD_OUT_MOTIONS)}) are the test")  # fmt: skip
        if self.threads is not None and int(self.threads) < 1:
            raise ValueError(f"gensim train.threads must be >= 1 or null, got {self.threads}")


@dataclass(frozen=True)
class GensimParams:
    """GenSim's model, ARAP stage, inference and loss settings (``method.params``)."""

    latent: int = 64  # width of node/edge features and MLPs (a ~1 MB model, as the paper states)
    geometry: int = 32  # PointNet feature size per garment / body point
    steps: int = 8  # message-passing steps L
    stage: Literal["full", "arap"] = "full"  # full | arap (the motion-aware ARAP stage alone, untrained: the row PEN is measured against)
    decoder: Literal["local", "eq1"] = "local"  # local (Eq. 1's half-space in the normal's local frame) | eq1 (Eq. 1's direction x magnitude)
    direction: Literal["tangent", "paper"] = "tangent"  # decoder eq1: tangent | paper (Eq. 1 as printed, b3 = (-b1 n1 - b2 n2) / n3)
    magnitude_scale: float = 0.01  # m: the local decoder's scale, or eq1's magnitude w = scale x softplus(raw)
    input_norm: bool = True  # standardise PEN's node and edge inputs by their mean and std over training frames
    distance_input: bool = False  # add the signed body distance (G - body point) . n (m) to PEN's node inputs (not in the paper: v and n hold it as a product)
    normal_part: Literal["abs", "softplus", "relu", "square"] = "abs"  # local decoder's normal coefficient: abs (|a|, Eq. 1's |rho|) | softplus (sharpness 100: its gradient dies below 0) | relu (max(a, 0)) | square (a^2)
    body_query: Literal["vertex", "surface"] = "surface"  # PEN's body point, normal and u: surface (closest outer-surface point) | vertex (nearest body vertex, as printed)
    decoder_init: Literal["default", "zero"] = "default"  # local decoder's output layer: default (PyTorch's: starts at a few mm) | zero (starts at 0.07 mm)
    eps: float = -0.5  # handle threshold on tau (Alg. 2)
    handle_side: Literal["pushed", "printed"] = "pushed"  # pushed | printed (Alg. 2 line 6 as printed)
    pin_rule: Literal["skinned", "normal"] = "skinned"  # skinned | normal (Alg. 2 line 9)
    arap_steps: int = 10  # nitr (Alg. 1), step t = 1 / nitr
    arap_iterations: int = 2  # local-global ARAP iterations per step
    handle_smoothing: int = 0  # rounds of averaging a handle's move with its handle neighbours' (0: Alg. 2 as printed)
    push_smoothing: int = 0  # rounds of spreading the collision push to free neighbours (0: Alg. 1 line 10 as printed)
    arap_solver: Literal["sparse", "libigl"] = "sparse"  # the ARAP backend: sparse (scipy, prefactored; drapebench.geometry.arap) | libigl (the same frame within micrometres)
    contact: Literal["surface", "vertex"] = "surface"  # Eq. 8's distance and Alg. 1's push: surface (signed distance to the body's outer surface, as eps_c counts) | vertex (nearest body vertex and its normal)
    push_margin: float = 1e-5  # m beyond the surface (or tangent plane) that Alg. 1's push moves a vertex: above float32 rounding, so a pushed vertex counts as outside
    push_handles: bool = True  # Alg. 1's push also moves the handle targets that Alg. 2 line 8 puts inside the body onto its surface; False: only free vertices, as printed
    pen_compile: bool = False  # run PEN under torch.compile at inference (compiled once per process, tens of seconds)
    pen_precision: Literal["fp32", "bf16"] = "fp32"  # PEN's inference arithmetic: fp32 | bf16 (CPU autocast; moves the drape by well under a millimetre, README)
    workers: int = 1  # frames draped at once (threads, each running torch single-threaded); 1: frame by frame on torch's threads
    collision_eps: float = 0.003  # eps_coll (Eq. 8)
    bending_rest: Literal["flat", "template"] = "flat"  # flat (Eq. 4: theta^2) | template
    fabric_mean: float | None = None  # mu_fabric (m); None: fitted by methods.gensim.fabric (cached)
    fabric_std: float | None = None  # sigma_fabric (m)
    restrain_reduction: Literal["mean", "sum"] = "mean"  # Eq. 3 over the edges: mean | sum (as printed)
    restrain_offset: Literal["dead_zone", "printed", "none"] = "none"  # Eq. 3 on max(phi - mu, 0) (dead_zone), phi - mu (printed) or phi (none)
    restrain_huber: float | None = 5.0  # sigmas beyond which Eq. 3's square continues linearly; null: square everywhere (as printed)
    weights: dict = field(default_factory=lambda: dict(WEIGHTS), metadata={"keys": tuple(WEIGHTS)})  # gamma_1..6 (Eq. 9)
    supervised: bool = False  # gensim_l2: L2 to reference drapes + smoothness + collision (paper Table 2)
    train: GensimTrain = field(default_factory=GensimTrain)

    def __post_init__(self) -> None:
        if (self.fabric_mean is None) != (self.fabric_std is None):
            raise ValueError("gensim fabric_mean and fabric_std are set together (or both null to fit them)")
        if self.fabric_std is not None and not self.fabric_std > 0:
            raise ValueError(f"gensim fabric_std must be positive, got {self.fabric_std}")
        if self.restrain_huber is not None and not self.restrain_huber > 0:
            raise ValueError(f"gensim restrain_huber must be positive (sigmas) or null, got {self.restrain_huber}")
        if not self.push_margin >= 0:
            raise ValueError(f"gensim push_margin must be >= 0 (m), got {self.push_margin}")
        if int(self.workers) < 1:
            raise ValueError(f"gensim workers must be >= 1, got {self.workers}")


INFERENCE_KEYS = ("arap_solver", "pen_compile", "pen_precision", "workers")  # how a drape is computed, not what is trained: outside the checkpoint's key
ADDED_KEYS = dict(contact="vertex", push_margin=0.0, push_handles=False)  # keys newer than some checkpoints, at the behaviour those were trained with


def gensim_params(cfg: Mapping[str, Any] | None) -> dict:
    """GenSim's parameters as a dict: :class:`GensimParams` from ``cfg`` (``method.params``). Raises ValueError naming
    an unknown key, an invalid choice or an invalid value."""
    return params_dict(GensimParams, cfg, "gensim")


@dataclass(frozen=True)
class GensimOptimumSettings(SolverSettings):
    """``gensim_optimum``'s settings (``method.params.optimum``): the solver's and the space it solves in."""

    space: Literal["vertices", "half_space"] = "vertices"  # the free vertices | PEN's output space, Eq. 1's half-space of the body normal


def optimum_params(cfg: Mapping[str, Any] | None) -> dict:
    """The settings of ``gensim_optimum`` as a dict: :class:`GensimOptimumSettings` from ``cfg``
    (``method.params.optimum``). Raises ValueError naming an unknown key or an invalid solver or space."""
    return params_dict(GensimOptimumSettings, cfg, "gensim_optimum")
