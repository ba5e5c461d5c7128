"""The diffused body model (Santesteban et al. 2021, Sec. 4.1, Eq. 4-6): skinning weights, shape
blend shapes and (when the body has them) pose blend shapes defined at any point of the canonical
body's space (mean shape, rest pose), fitted by small MLPs and cached by body content.

The diffused value at a point p at distance d from the canonical body surface is the average of the
surface values at the closest surface points of ``n_samples`` points q ~ N(p, sigma^2 I), with sigma = d
(``spread="distance"``, the paper) or sqrt(d) (``"sqrt_distance"``, HOOD's port, which measures d to the
nearest body vertex; here d is always the distance to the surface). A point on the surface gets its
surface value; the surface value at a point is the barycentric interpolation of the per-vertex values
on its face. :func:`diffused_targets` computes these averages exactly (Monte Carlo over q);
:func:`fit_diffused_body` fits a :class:`DiffusedBody` to them.
"""

from __future__ import annotations

import logging
import time

import torch

from drapebench.body.fields import (FieldMLP, barycentric, body_frame, cached_field, fit_field, freeze, interpolate,
                                    resolve_config, sample_surface, shell_points)
from drapebench.cache import Cache, body_key
from drapebench.geometry.sdf import closest_body_point

log = logging.getLogger(__name__)

SPREADS = ("distance", "sqrt_distance")
DIFFUSED = Cache("diffused", 1)

DIFFUSED_DEFAULTS = dict(
    n_samples=64,  # N of Eq. 4-6: surface samples averaged per training point
    spread="distance",  # sigma = d (the paper) or "sqrt_distance" (sigma = sqrt(d), HOOD's port)
    shell_outside=0.2,  # m: training points reach this far outside the canonical body ...
    shell_inside=0.02,  # m: ... and this deep inside it
    n_surface=20000,  # training points on the surface (exact values)
    n_shell=20000,  # training points in the shell (diffused values)
    n_heldout=2000,  # held-out surface and shell points for the reported fit error
    width=64,  # hidden units per layer of each MLP (128: 2.5x slower posing, held-out errors 0.015 / 0.15 mm instead of 0.023 / 0.22 mm)
    depth=3,  # hidden layers of each MLP
    n_frequencies=6,  # Fourier octaves of the input encoding (0 = plain coordinates)
    steps=3000,  # Adam steps
    batch=2048,  # points per step
    lr=1e-2,  # initial Adam learning rate (cosine decay to lr / 20)
    seed=0,
)


def surface_values(body) -> dict[str, torch.Tensor]:
    """The body's per-vertex values that get diffused: weights (V, J), shapedirs (V, 3, S) and, when the
    body has pose correctives, posedirs (V, 3, P)."""
    values = {"weights": body.weights, "shapedirs": body.shapedirs}
    if body.posedirs is not None:
        values["posedirs"] = body.posedirs
    return values


def _check_points(points: torch.Tensor) -> None:
    if points.dim() != 2 or points.shape[-1] != 3:
        raise ValueError(f"points must have shape (N, 3) in metres; got {tuple(points.shape)}")
    if not torch.isfinite(points).all():
        raise ValueError("points contain NaN or Inf; clean the input first")


def diffused_targets(points: torch.Tensor, body, n_samples: int = DIFFUSED_DEFAULTS["n_samples"],
                     spread: str = DIFFUSED_DEFAULTS["spread"], generator: torch.Generator | None = None,
                     chunk: int = 200_000) -> dict[str, torch.Tensor]:
    """Eq. 4-6 at points (N, 3) m of the canonical body's space (mean shape, rest pose).

    For each point at distance d from the surface, ``n_samples`` points q ~ N(p, sigma^2 I) (sigma = d
    or sqrt(d), ``spread``) are drawn with ``generator`` (CPU; None = torch's global one), their
    closest surface points found exactly and the body's values there (barycentric on the closest face)
    averaged. Queries run in chunks of about ``chunk`` samples. Returns a dict with ``weights`` (N, J),
    ``shapedirs`` (N, 3, S) and, when the body has pose correctives, ``posedirs`` (N, 3, P), in the
    points' dtype.
    """
    _check_points(points)
    if spread not in SPREADS:
        raise ValueError(f"unknown spread {spread!r}; use one of {SPREADS}")
    if int(n_samples) < 1:
        raise ValueError(f"n_samples must be >= 1 (got {n_samples})")
    n_samples = int(n_samples)
    verts = body.shaped()[0][0].detach().cpu().double()
    faces = body.faces.cpu()
    values = surface_values(body)
    shapes = {k: v.shape[1:] for k, v in values.items()}
    table = torch.cat([v.detach().cpu().double().reshape(len(verts), -1) for v in values.values()], 1)
    pts = points.detach().cpu().double()
    d = closest_body_point(pts[None], verts[None], faces).distance[0].abs()
    sigma = d if spread == "distance" else d.sqrt()
    out, per = [], max(1, chunk // n_samples)
    for start in range(0, len(pts), per):
        p, s = pts[start:start + per], sigma[start:start + per]
        q = p[:, None] + s[:, None, None] * torch.randn(len(p), n_samples, 3, generator=generator, dtype=p.dtype)
        sp = closest_body_point(q.reshape(1, -1, 3), verts[None], faces)
        face = sp.face[0]
        bary = barycentric(sp.point[0], verts[faces[face]])
        out.append(interpolate(table, faces, face, bary).reshape(len(p), n_samples, -1).mean(1))
    flat = torch.cat(out).to(points.dtype) if out else table.new_zeros(0, table.shape[1]).to(points.dtype)
    result, col = {}, 0
    for key, shape in shapes.items():
        width = shape.numel()
        result[key] = flat[:, col:col + width].reshape(-1, *shape)
        col += width
    return result


class DiffusedBody(torch.nn.Module):
    """Diffused skinning weights, shape (and pose) blend shapes at points of the canonical body's space.

    One :class:`~drapebench.body.fields.FieldMLP` per field (Fourier-encoded coordinates, ``width`` x
    ``depth`` SiLU layers). The weights come out of a softmax (non-negative, summing to 1 by
    construction); the blend-shape fields are scaled by the targets' standard deviation. ``body_key``
    is the content hash of the body it was fitted to (:meth:`matches`), ``report`` the fit error.
    Bodies without pose correctives (the shipped Anny bakes) have no pose field: :meth:`pose_offsets`
    returns None and ``has_posedirs`` is False.
    """

    def __init__(self, n_joints: int, n_betas: int, n_pose: int, center: torch.Tensor, scale: float, cfg: dict,
                 body_key: str = ""):
        super().__init__()
        self.cfg = resolve_config(cfg, DIFFUSED_DEFAULTS, "diffused body")
        self.body_key, self.report = body_key, {}
        self.n_joints, self.n_betas, self.n_pose = int(n_joints), int(n_betas), int(n_pose)
        net = dict(center=center, scale=scale, width=self.cfg["width"], depth=self.cfg["depth"],
                   n_frequencies=self.cfg["n_frequencies"])
        self.weight_net = FieldMLP(self.n_joints, **net)
        self.shape_net = FieldMLP(3 * self.n_betas, **net)
        self.register_buffer("shape_scale", torch.ones(()))
        self.pose_net = FieldMLP(3 * self.n_pose, **net) if self.n_pose else None
        self.register_buffer("pose_scale", torch.ones(()))

    @property
    def has_posedirs(self) -> bool:
        return self.pose_net is not None

    def matches(self, body) -> bool:
        """True when this model was fitted to ``body`` (same content hash)."""
        return self.body_key == body_key(body)

    def weight_logits(self, p: torch.Tensor) -> torch.Tensor:
        """Pre-softmax weights (..., J) at points p (..., 3) m."""
        return self.weight_net(p)

    def weights(self, p: torch.Tensor) -> torch.Tensor:
        """Skinning weights (..., J), non-negative and summing to 1, at points p (..., 3) m."""
        return torch.softmax(self.weight_logits(p), -1).to(p.dtype)

    def shapedirs(self, p: torch.Tensor) -> torch.Tensor:
        """Shape blend shapes (..., 3, S) m per unit beta at points p (..., 3) m."""
        return (self.shape_net(p) * self.shape_scale).reshape(*p.shape[:-1], 3, self.n_betas).to(p.dtype)

    def shape_offsets(self, p: torch.Tensor, betas: torch.Tensor) -> torch.Tensor:
        """Offsets (..., 3) m of shape betas (..., S') (S' <= S, the first S' components, broadcast
        against p's leading dimensions) at points p (..., 3) m."""
        if betas.shape[-1] > self.n_betas:
            raise ValueError(f"betas has {betas.shape[-1]} components; this body has {self.n_betas}")
        return (self.shapedirs(p)[..., : betas.shape[-1]] * betas[..., None, :].to(p.dtype)).sum(-1)

    def weights_and_shape_offsets(self, p: torch.Tensor, betas: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """:meth:`weights` (..., J) and :meth:`shape_offsets` (..., 3) m at points p (..., 3) m for one body
        shape betas (S',) shared by every point, in one pass: the Fourier encoding is computed once for both
        fields (they share centre, scale and frequencies) and betas are folded into the shape field's last
        layer (width -> 3 instead of width -> 3 S). The same values up to float rounding."""
        if betas.dim() != 1 or betas.shape[0] > self.n_betas:
            raise ValueError(f"betas must be one shape (S',) with S' <= {self.n_betas}; got {tuple(betas.shape)}")
        x = self.weight_net.encode(p)
        weights = torch.softmax(self.weight_net.net(x), -1).to(p.dtype)
        last = self.shape_net.net[-1]
        n = betas.shape[0]
        b = betas.to(last.weight.dtype) * self.shape_scale
        W = (last.weight.reshape(3, self.n_betas, -1)[:, :n] * b[None, :, None]).sum(1)  # (3, width)
        bias = last.bias.reshape(3, self.n_betas)[:, :n] @ b
        offsets = torch.nn.functional.linear(self.shape_net.net[:-1](x), W, bias).to(p.dtype)
        return weights, offsets

    def posedirs(self, p: torch.Tensor) -> torch.Tensor | None:
        """Pose blend shapes (..., 3, P) at points p (..., 3) m; None without pose correctives."""
        if self.pose_net is None:
            return None
        return (self.pose_net(p) * self.pose_scale).reshape(*p.shape[:-1], 3, self.n_pose).to(p.dtype)

    def pose_offsets(self, p: torch.Tensor, pose_feature: torch.Tensor) -> torch.Tensor | None:
        """Pose-corrective offsets (..., 3) m for the SMPL pose feature (..., P) (rotation matrices minus
        identity of the non-root joints, flattened) at points p (..., 3); None when the body has no pose
        correctives."""
        dirs = self.posedirs(p)
        if dirs is None:
            return None
        return (dirs * pose_feature[..., None, :].to(p.dtype)).sum(-1)

    def state(self) -> dict:
        """What :meth:`from_state` rebuilds the module from (sizes, config, body key, report, weights)."""
        return dict(sizes=[self.n_joints, self.n_betas, self.n_pose], cfg=self.cfg, body_key=self.body_key,
                    report=self.report, state_dict=self.state_dict())

    @classmethod
    def from_state(cls, state: dict) -> "DiffusedBody":
        sd = state["state_dict"]
        center, scale = sd["weight_net.center"], float(sd["weight_net.scale"])
        model = cls(*state["sizes"], center=center, scale=scale, cfg=state["cfg"], body_key=state["body_key"])
        model.load_state_dict(sd)
        model.report = dict(state["report"])
        return freeze(model)


def _training_set(body, cfg: dict, generator: torch.Generator, n_surface: int, n_shell: int,
                  n_samples: int) -> tuple[torch.Tensor, dict]:
    """Points (n_surface + n_shell, 3) and their target values: surface samples with their exact values,
    then shell points with values diffused from n_samples samples each."""
    verts = body.shaped()[0][0].detach().cpu().float()
    faces = body.faces.cpu()
    surf, face, bary, _ = sample_surface(verts, faces, n_surface, generator)
    values = {k: interpolate(v.detach().cpu().float().reshape(len(verts), -1), faces, face, bary).reshape(-1, *v.shape[1:])
              for k, v in surface_values(body).items()}
    shell = shell_points(verts, faces, n_shell, cfg["shell_inside"], cfg["shell_outside"], generator)
    diffused = diffused_targets(shell, body, n_samples, cfg["spread"], generator)
    return torch.cat([surf, shell]), {k: torch.cat([values[k], diffused[k]]) for k in values}


def _weight_error(model: DiffusedBody, points: torch.Tensor, weights: torch.Tensor) -> float:
    """Mean over points of the summed absolute weight error."""
    with torch.no_grad():
        return float((model.weights(points) - weights).abs().sum(-1).mean())


def _fit(body, cfg: dict) -> DiffusedBody:
    start = time.perf_counter()
    gen = torch.Generator().manual_seed(int(cfg["seed"]))
    points, targets = _training_set(body, cfg, gen, cfg["n_surface"], cfg["n_shell"], cfg["n_samples"])
    # held-out targets average 4x the samples, so their Monte Carlo noise barely enters the reported error
    held_points, held = _training_set(body, cfg, gen, cfg["n_heldout"], cfg["n_heldout"], 4 * cfg["n_samples"])
    center, scale = body_frame(body.v_template.detach().cpu().float())
    n_pose = targets["posedirs"].shape[-1] if "posedirs" in targets else 0
    model = DiffusedBody(body.n_joints, body.n_betas, n_pose, center, scale, cfg, body_key(body))
    flat = {k: v.reshape(len(v), -1) for k, v in targets.items()}
    model.shape_scale.fill_(max(float(flat["shapedirs"].std()), 1e-12))
    if n_pose:
        model.pose_scale.fill_(max(float(flat["posedirs"].std()), 1e-12))
    targets_s = time.perf_counter() - start

    def loss(idx):
        p = points[idx]
        # cross-entropy of the softmax against the target weights (a distribution per point)
        total = -(flat["weights"][idx] * torch.log_softmax(model.weight_logits(p), -1)).sum(-1).mean()
        total = total + ((model.shape_net(p) - flat["shapedirs"][idx] / model.shape_scale) ** 2).mean()
        if n_pose:
            total = total + ((model.pose_net(p) - flat["posedirs"][idx] / model.pose_scale) ** 2).mean()
        return total

    fit_field(model.parameters(), loss, len(points), cfg["steps"], cfg["batch"], cfg["lr"], gen, "diffused body fit")
    model = freeze(model)
    n = cfg["n_heldout"]
    with torch.no_grad():
        shape_err = (model.shapedirs(held_points) - held["shapedirs"]).abs().mean()
    model.report = dict(
        surface_weight_error=_weight_error(model, held_points[:n], held["weights"][:n]),
        shell_weight_error=_weight_error(model, held_points[n:], held["weights"][n:]),
        shapedirs_error_mm=float(shape_err) * 1e3,
        targets_s=targets_s,
        fit_s=time.perf_counter() - start,
    )
    log.info("diffused body fitted for %s: %s", body.name, model.report)
    return model


def fit_diffused_body(body, cfg: dict | None = None, force: bool = False) -> DiffusedBody:
    """The diffused body model of ``body`` (settings: :data:`DIFFUSED_DEFAULTS` updated by ``cfg``),
    loaded from the ``diffused`` cache (keyed by the body's content and the settings) or fitted and
    stored. The module is float32, in eval mode, with frozen parameters (differentiable in its input
    points). ``report`` holds the held-out fit errors: ``surface_weight_error`` and
    ``shell_weight_error`` (mean over points of sum_j |w_j - target_j|), ``shapedirs_error_mm`` (mean
    absolute error of a shapedirs entry over all held-out points, mm per unit beta) and the times in
    seconds."""
    cfg = resolve_config(cfg, DIFFUSED_DEFAULTS, "diffused body")
    if cfg["spread"] not in SPREADS:
        raise ValueError(f"unknown spread {cfg['spread']!r}; use one of {SPREADS}")
    return cached_field(DIFFUSED, "diffused", body, cfg, lambda: _fit(body, cfg), DiffusedBody.from_state, force)
