"""GenSim step 1: body-motion-aware ARAP (paper Sec. 3.1, Alg. 1 and 2), frame by frame.

For one target frame: the target body is front-aligned (root rotation and translation removed), each
garment vertex is bound to its closest canonical body vertex, handles are the vertices the body motion
acts on, and ARAP moves them to their targets in ``n_iterations`` steps, pushing vertices that end up
inside the body out along the closest body normal after each step. The readings of the printed
algorithm that this code takes are listed in ``methods/gensim/README.md``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from drapebench.body.lbs import lbs
from drapebench.body.skinning import nearest_weights, transfer_shape
from drapebench.geometry.arap import BACKENDS, arap_solver
from drapebench.geometry.proximity import body_vertex_tree, nearest_indices
from drapebench.geometry.sdf import closest_body_point

CONTACTS = ("surface", "vertex")


@dataclass(frozen=True)
class ArapConfig:
    """eps: handle threshold on tau = u_hat . d_hat (paper -0.5); handle_side: "pushed" (vertices on the
    side the body part moves towards, tau >= -eps) or "printed" (Alg. 2 line 6 as printed, tau <= eps);
    pin_rule: "skinned" (pins follow the body by LBS with their closest vertex's weights, as the reference
    simulation drives them) or "normal" (Alg. 2 line 9: closest target body vertex + |u| along its normal);
    n_iterations / step (Alg. 1: 10 steps of 1/10); arap_iterations: local-global iterations per step;
    min_motion: body motion (m) below which a vertex is no handle (its direction is undefined);
    handle_smoothing: rounds of averaging each non-pin handle's move (target - template) with its handle
    neighbours' (0: Alg. 2 as printed, every handle placed on its own); push_smoothing: rounds of spreading
    the collision push (Alg. 1 line 10) to the free neighbours of pushed vertices (0: as printed);
    solver: the ARAP backend of :func:`drapebench.geometry.arap.arap_solver` ("sparse" or "libigl");
    contact: what the push (Alg. 1 line 10) finds inside the body and moves out: "surface" (the signed
    distance to the body's outer surface, inside by the whole body's winding number, as eps_c counts it;
    a vertex moves onto its closest surface point) or "vertex" (the nearest body vertex's normal distance,
    a vertex moves onto that vertex's tangent plane); push_margin (m): how far beyond that the push moves it;
    push_handles: the push also moves the handles' final targets (Alg. 2 line 8) that lie inside the body out
    (False: as printed, only the free vertices are pushed)."""

    eps: float = -0.5
    handle_side: str = "pushed"
    pin_rule: str = "skinned"
    n_iterations: int = 10
    arap_iterations: int = 2
    min_motion: float = 1e-4
    handle_smoothing: int = 0
    push_smoothing: int = 0
    solver: str = "sparse"
    contact: str = "vertex"
    push_margin: float = 0.0
    push_handles: bool = False

    def __post_init__(self):
        if self.handle_side not in ("pushed", "printed"):
            raise ValueError(f"gensim handle_side must be 'pushed' or 'printed', not {self.handle_side!r}")
        if self.pin_rule not in ("skinned", "normal"):
            raise ValueError(f"gensim pin_rule must be 'skinned' or 'normal', not {self.pin_rule!r}")
        if self.solver not in BACKENDS:
            raise ValueError(f"gensim arap_solver must be one of {BACKENDS}, not {self.solver!r}")
        if self.contact not in CONTACTS:
            raise ValueError(f"gensim contact must be one of {CONTACTS}, not {self.contact!r}")
        if self.handle_smoothing < 0 or self.push_smoothing < 0:
            raise ValueError("gensim handle_smoothing and push_smoothing must be >= 0")
        if self.n_iterations < 1 or self.arap_iterations < 1:
            raise ValueError("gensim n_iterations and arap_iterations must be >= 1")


@dataclass
class Binding:
    """Per garment (independent of the frame): closest canonical body vertex nu (V,), relative position
    u = G_bar - B_bar[nu] (V, 3) m, pin mask (V,) bool."""

    nu: torch.Tensor
    u: torch.Tensor
    pin: torch.Tensor

    def to(self, device) -> Binding:
        """This binding on ``device``."""
        return Binding(self.nu.to(device), self.u.to(device), self.pin.to(device))


def bind(template: torch.Tensor, canonical_body: torch.Tensor, pins: torch.Tensor) -> Binding:
    """Alg. 2 lines 2 and 4 for a template (V, 3) on the canonical body vertices (Vb, 3)."""
    nu = nearest_indices(template[None], canonical_body[None])[0]
    pin = torch.zeros(len(template), dtype=torch.bool, device=template.device)
    pin[pins.long()] = True
    return Binding(nu, template - canonical_body[nu], pin)


def neighbour_mean(values: torch.Tensor, edges: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """(V, 3): each vertex's ``values`` (V, 3) averaged with those of its neighbours along ``edges`` (E, 2)
    whose ``mask`` (V,) bool is set (a vertex outside the mask keeps its own value)."""
    a, b = edges[:, 0], edges[:, 1]
    keep = (mask[a] & mask[b]).to(values.dtype)[:, None]
    total = values.clone().index_add_(0, a, values[b] * keep).index_add_(0, b, values[a] * keep)
    count = torch.ones(len(values), dtype=values.dtype, device=values.device).index_add_(0, a, keep[:, 0]).index_add_(0, b, keep[:, 0])
    return torch.where(mask[:, None], total / count[:, None], values)


def handle_targets(binding: Binding, template, canonical_body, target_body, target_normals, skinned_pins, cfg: ArapConfig, edges=None):
    """Alg. 2: handle mask (V,) bool (pins included), target positions (V, 3) m (only handle rows are
    meaningful) and the body motion d (V, 3) m, for one front-aligned target body (Vb, 3) with its
    normals (Vb, 3); ``skinned_pins`` (V, 3) are the template skinned to that frame (pin_rule "skinned");
    ``edges`` (E, 2), the garment's, for ``cfg.handle_smoothing``."""
    d = target_body[binding.nu] - canonical_body[binding.nu]
    d_norm = d.norm(dim=-1)
    u_norm = binding.u.norm(dim=-1)
    moving = d_norm > cfg.min_motion
    d_hat = d / d_norm.clamp_min(1e-12)[:, None]
    tau = (binding.u * d_hat).sum(-1) / u_norm.clamp_min(1e-12)
    side = tau <= cfg.eps if cfg.handle_side == "printed" else tau >= -cfg.eps
    q = (binding.u * d_hat).sum(-1)
    reached = d_norm > q  # the body part has moved through the vertex's place (|d| - q > 0: line 8 moves it forward)
    handles = moving & side & reached & ~binding.pin
    move = d_hat * (d_norm - q)[:, None]
    if cfg.handle_smoothing:
        if edges is None:
            raise ValueError("gensim handle_smoothing needs the garment's edges")
        for _ in range(cfg.handle_smoothing):
            move = neighbour_mean(move, edges, handles)
    targets = template + move
    if cfg.pin_rule == "normal":
        pin_targets = target_body[binding.nu] + target_normals[binding.nu] * u_norm[:, None]
    else:
        pin_targets = skinned_pins
    targets = torch.where(binding.pin[:, None], pin_targets, targets)
    return handles | binding.pin, targets, d


def motion_aware_arap(template, faces, handles, targets, target_body, target_normals, cfg: ArapConfig, candidates=None,
                      body_faces=None, outer_faces=None) -> torch.Tensor:  # fmt: skip
    """Alg. 1: (V, 3) deformed garment. Handles (V,) bool move from the template (V, 3) to ``targets``
    (V, 3) in ``cfg.n_iterations`` equal steps (with ``cfg.push_handles`` a target inside the body first moves
    out as the push below moves a vertex); after each ARAP solve the non-handle vertices inside the
    front-aligned target body (Vb, 3) move out (``cfg.contact``: onto the closest point of the body's
    surface, which needs ``body_faces`` (Fb, 3) and its ``outer_faces`` (Fb,) bool; or by the nearest body
    vertex's normal distance zeta <= 0 along its normal (``target_normals`` (Vb, 3), body vertices
    restricted to ``candidates``))."""
    idx = torch.nonzero(handles).squeeze(1)
    solver = arap_solver(template, faces, idx, cfg.arap_iterations, cfg.solver)
    start, goal = template[idx].double().numpy(), targets[idx].double().numpy()
    free_mask = (~handles).numpy()
    free = np.nonzero(free_mask)[0]
    if cfg.push_smoothing:
        f = torch.as_tensor(faces).long()
        edges = torch.unique(torch.cat([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]).sort(dim=1).values, dim=0)
    contact = body_contact(target_body, target_normals, cfg.contact, candidates, body_faces, outer_faces)
    if cfg.push_handles:  # Alg. 2 line 8 brings a handle to the body: one that lands inside it is put on its surface
        zeta, n = body_contact(target_body, target_normals, cfg.contact, candidates, body_faces, outer_faces)(goal)  # its own query cache
        inside = zeta <= 0
        goal[inside] += (cfg.push_margin - zeta[inside, None]) * n[inside]
    G = template.double().numpy()
    for k in range(1, cfg.n_iterations + 1):
        G = solver.solve(start + (goal - start) * (k / cfg.n_iterations), G)
        zeta, n = contact(G[free])
        inside = zeta <= 0
        push = np.zeros_like(G)
        push[free[inside]] = (cfg.push_margin - zeta[inside, None]) * n[inside]
        if cfg.push_smoothing:  # free neighbours of a pushed vertex follow part of its push
            pushed = torch.zeros(len(G), dtype=torch.bool)
            pushed[torch.from_numpy(free[inside])] = True
            push_t, free_t = torch.from_numpy(push), torch.from_numpy(free_mask)
            for _ in range(cfg.push_smoothing):
                spread = neighbour_mean(push_t, edges, free_t)
                push_t = torch.where(pushed[:, None], push_t, torch.where(free_t[:, None], spread, push_t))
            push = push_t.numpy()
        G = G + push
    return torch.from_numpy(np.ascontiguousarray(G)).to(template.dtype)


def body_contact(body, normals, contact: str, candidates=None, body_faces=None, outer_faces=None):
    """A function of points (N, 3) float64 returning their signed distance zeta (N,) m to one body frame
    (Vb, 3) (negative inside) and the unit direction (N, 3) along which -zeta moves a point out: the
    body's outer surface (``contact`` "surface": ``body_faces`` (Fb, 3), ``outer_faces`` (Fb,) bool, the
    sign the whole body's winding number, :func:`drapebench.geometry.sdf.closest_body_point`) or the nearest
    body vertex (among ``candidates``) with its ``normals`` (Vb, 3) ("vertex": one k-d tree for the frame).
    "surface" is meant to be called with the same N points, moved, at every step: a point that moved less
    than its last measured distance is still outside (the distance is 1-Lipschitz), so only the others are
    queried again, and the rest read zeta = inf."""
    if contact == "surface":
        if body_faces is None:
            raise ValueError("gensim contact 'surface' needs the body's faces (and outer_faces)")
        verts = body[None].double()
        known: dict = {}  # the points and signed distances of the last exact query, per point

        def surface(points: np.ndarray):
            need = np.ones(len(points), dtype=bool)
            if known and len(known["points"]) == len(points):  # a point that moved less than its distance has not crossed the surface
                need = np.linalg.norm(points - known["points"], axis=1) >= known["distance"]
            else:
                known.update(points=points.copy(), distance=np.zeros(len(points)), normal=np.zeros_like(points))
            if need.any():
                sp = closest_body_point(torch.from_numpy(points[need])[None], verts, body_faces, outer_faces=outer_faces)
                known["points"][need], known["distance"][need], known["normal"][need] = points[need], sp.distance[0].numpy(), sp.normal[0].numpy()
            zeta = np.where(need, known["distance"], np.inf)  # outside by at least the distance left
            return zeta, known["normal"].copy()

        return surface
    tree = body_vertex_tree(body.double(), candidates)
    cand = None if candidates is None else torch.as_tensor(candidates).long().numpy()
    verts, norms = body.double().numpy(), normals.double().numpy()

    def vertex(points: np.ndarray):
        i = tree.query(points, workers=1)[1]
        i = i if cand is None else cand[i]
        n = norms[i]
        return ((points - verts[i]) * n).sum(-1), n

    return vertex


def front_aligned(body, betas: torch.Tensor, poses: torch.Tensor):
    """Front-aligned bodies: vertices (T, Vb, 3) and skinning transforms (T, J, 4, 4) with the root rotation
    and translation removed (paper Sec. 4.3), for betas (S,) or (T, S) and poses (T, J, 3)."""
    aligned = poses.clone()
    aligned[:, 0] = 0.0
    betas = betas.expand(len(poses), -1) if betas.dim() == 1 else betas
    with torch.no_grad():
        out = body.forward(betas, aligned, torch.zeros(len(poses), 3, dtype=poses.dtype, device=poses.device))
    return out.vertices, out.transforms


def skinned_template(template, binding: Binding, body, garment_betas, betas, transforms) -> torch.Tensor:
    """(T, V, 3) the template moved to body shape ``betas`` and skinned with its closest canonical vertex's
    weights by ``transforms`` (T, J, 4, 4): where pins go under pin_rule "skinned"."""
    rest = transfer_shape(template, binding.nu, body, garment_betas, betas)
    return lbs(rest, nearest_weights(binding.nu, body).to(template.dtype), transforms.to(template.dtype))
