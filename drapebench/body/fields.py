"""Small neural fields over the canonical body's space: the coordinate MLP, its fitting loop, and
surface sampling with barycentric interpolation of per-vertex values. Shared by the diffused body
model (:mod:`drapebench.body.diffused`) and the canonical body's SDF (:mod:`drapebench.body.canonical_sdf`).
"""

from __future__ import annotations

import logging
import math
from typing import Callable

import torch

from drapebench.cache import Cache, body_key
from drapebench.geometry.ops import face_areas, face_normals
from drapebench.keys import check_known
from drapebench.progress import progress

log = logging.getLogger(__name__)


def resolve_config(cfg: dict | None, defaults: dict, what: str) -> dict:
    """``defaults`` updated by ``cfg``; an unknown key is a ValueError naming the valid ones."""
    cfg = dict(cfg or {})
    check_known(cfg, defaults, f"{what} setting")
    return {**defaults, **cfg}


class FieldMLP(torch.nn.Module):
    """A coordinate MLP ``(..., 3) m -> (..., n_out)``.

    Points are centred and scaled by the body's bounding box (``center`` (3,), ``scale`` m: its half
    largest extent), then encoded as ``[x, sin(2^k pi x), cos(2^k pi x)]`` for k < ``n_frequencies``
    (0 = the plain coordinates), followed by ``depth`` hidden layers of ``width`` SiLU units and a
    linear output layer.
    """

    def __init__(self, n_out: int, center: torch.Tensor, scale: float, width: int, depth: int, n_frequencies: int):
        super().__init__()
        if width < 1 or depth < 1 or n_frequencies < 0:
            raise ValueError(f"a field MLP needs width >= 1, depth >= 1, n_frequencies >= 0; "
                             f"got {width}, {depth}, {n_frequencies}")
        self.register_buffer("center", torch.as_tensor(center, dtype=torch.float32).reshape(3).clone())
        self.register_buffer("scale", torch.tensor(float(scale), dtype=torch.float32))
        self.register_buffer("freqs", (2.0 ** torch.arange(n_frequencies, dtype=torch.float32)) * math.pi)
        layers, n_in = [], 3 * (1 + 2 * n_frequencies)
        for _ in range(depth):
            layers += [torch.nn.Linear(n_in, width), torch.nn.SiLU()]
            n_in = width
        layers.append(torch.nn.Linear(n_in, n_out))
        self.net = torch.nn.Sequential(*layers)

    def encode(self, p: torch.Tensor) -> torch.Tensor:
        """The network's input (..., 3 (1 + 2 n_frequencies)) of points p (..., 3) m: the Fourier encoding."""
        if p.shape[-1] != 3:
            raise ValueError(f"points must have shape (..., 3); got {tuple(p.shape)}")
        x = (p.to(self.center.dtype) - self.center) / self.scale
        if len(self.freqs):
            ang = (x[..., None] * self.freqs).flatten(-2)
            x = torch.cat([x, ang.sin(), ang.cos()], -1)
        return x

    def forward(self, p: torch.Tensor) -> torch.Tensor:
        """p (..., 3) m -> (..., n_out) in the module's dtype."""
        return self.net(self.encode(p))


def body_frame(vertices: torch.Tensor) -> tuple[torch.Tensor, float]:
    """Centre (3,) and half largest extent (m) of the bounding box of vertices (V, 3)."""
    lo, hi = vertices.min(0).values, vertices.max(0).values
    return (lo + hi) / 2, float((hi - lo).max()) / 2


def barycentric(points: torch.Tensor, tri: torch.Tensor) -> torch.Tensor:
    """Barycentric coordinates (n, 3) of points (n, 3) lying on triangles tri (n, 3, 3), clamped to
    the triangle; a degenerate triangle gives its corner nearest to the point."""
    a, b, c = tri.unbind(1)
    v0, v1, v2 = b - a, c - a, points - a
    d00, d01, d11 = (v0 * v0).sum(-1), (v0 * v1).sum(-1), (v1 * v1).sum(-1)
    d20, d21 = (v2 * v0).sum(-1), (v2 * v1).sum(-1)
    den = d00 * d11 - d01 * d01
    ok = den > torch.finfo(den.dtype).eps * (d00 * d11).clamp_min(torch.finfo(den.dtype).tiny)
    den = torch.where(ok, den, torch.ones_like(den))
    v, w = (d11 * d20 - d01 * d21) / den, (d00 * d21 - d01 * d20) / den
    bary = torch.stack([1 - v - w, v, w], -1).clamp_min(0)
    bary = bary / bary.sum(-1, keepdim=True).clamp_min(torch.finfo(den.dtype).tiny)
    nearest = torch.nn.functional.one_hot((tri - points[:, None]).norm(dim=-1).argmin(-1), 3).to(bary.dtype)
    return torch.where(ok[:, None], bary, nearest)


def interpolate(values: torch.Tensor, faces: torch.Tensor, face: torch.Tensor, bary: torch.Tensor) -> torch.Tensor:
    """Per-vertex values (V, C) interpolated at surface points given by face ids (n,) and
    barycentric coordinates (n, 3) -> (n, C)."""
    return (values[faces[face]] * bary[..., None].to(values.dtype)).sum(1)


def sample_surface(vertices: torch.Tensor, faces: torch.Tensor, n: int, generator: torch.Generator | None = None):
    """n points uniform by area on the mesh (vertices (V, 3), faces (F, 3)). Returns points (n, 3),
    face ids (n,), barycentric coordinates (n, 3) and the unit face normals (n, 3) there."""
    f = torch.multinomial(face_areas(vertices, faces), n, replacement=True, generator=generator)
    r1, r2 = torch.rand(2, n, generator=generator, dtype=vertices.dtype)
    s = r1.sqrt()
    bary = torch.stack([1 - s, s * (1 - r2), s * r2], -1)
    points = (vertices[faces[f]] * bary[..., None]).sum(1)
    return points, f, bary, face_normals(vertices, faces)[f]


def shell_points(vertices: torch.Tensor, faces: torch.Tensor, n: int, inside: float, outside: float,
                 generator: torch.Generator | None = None) -> torch.Tensor:
    """n points (n, 3) around the mesh: surface samples moved along their face normal by an offset
    in [-inside, outside] m. A fraction inside / (inside + outside) goes inwards, uniform in depth; the
    rest outwards at outside * u^2 (u uniform), so half of those lie within outside / 4 of the surface."""
    points, _, _, normals = sample_surface(vertices, faces, n, generator)
    u, side = torch.rand(2, n, generator=generator, dtype=vertices.dtype)
    inward = side < inside / max(inside + outside, 1e-12)
    offset = torch.where(inward, -inside * u, outside * u * u)
    return points + offset[:, None] * normals


def fit_field(params, loss: Callable[[torch.Tensor], torch.Tensor], n_train: int, steps: int, batch: int, lr: float,
              generator: torch.Generator, desc: str) -> None:
    """Adam on ``loss(index)`` over random minibatches (``batch`` indices into ``n_train`` samples) for
    ``steps`` steps, the learning rate decaying on a cosine from ``lr`` to lr / 20; a non-finite loss
    raises."""
    params = list(params)
    opt = torch.optim.Adam(params, lr=lr)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, max(steps, 1), eta_min=lr / 20)
    bar = progress(range(steps), desc=desc, unit="step")
    for step in bar:
        idx = torch.randint(n_train, (min(batch, n_train),), generator=generator)
        value = loss(idx)
        if not torch.isfinite(value):
            raise FloatingPointError(f"{desc}: the loss became {float(value)} at step {step}; lower the learning rate")
        opt.zero_grad(set_to_none=True)
        value.backward()
        opt.step()
        sched.step()
        if step % 100 == 0:
            bar.set_postfix(loss=f"{float(value.detach()):.4g}")


def freeze(module: torch.nn.Module) -> torch.nn.Module:
    """The module in eval mode, float32, its parameters without gradients (still differentiable in its inputs)."""
    module = module.float().eval()
    for p in module.parameters():
        p.requires_grad_(False)
    return module


def cached_field(cache: Cache, prefix: str, body, cfg: dict, build: Callable[[], torch.nn.Module],
                 from_state: Callable[[dict], torch.nn.Module], force: bool = False) -> torch.nn.Module:
    """The field of ``body`` fitted with settings ``cfg``: read from ``cache`` (keyed by the body's content
    and ``cfg``; a torch file of the module's ``state()``, rebuilt by ``from_state``) or ``build()``-ed and stored."""
    return cache.get_or_build(
        cache.path(body_key(body), cfg, prefix=prefix, suffix=".pt"),
        build,
        lambda model, tmp: torch.save(model.state(), tmp),
        lambda path: from_state(torch.load(path, weights_only=True)),
        force=force,
    )
