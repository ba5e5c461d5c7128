"""GenSim step 2: the Physics Enforcing Network (paper Sec. 3.2) and its displacement direction (Eq. 1).

PEN encodes the ARAP-deformed garment as a graph (a node per vertex, two directed edges per mesh edge),
runs L message-passing steps (edge update from its end nodes, node update from the mean of its incoming
edges, residual MLPs) and decodes per vertex a displacement in the half-space of the closest body normal
(Eq. 1): a unit direction and a non-negative magnitude, or the same half-space in the local frame. Everything is batched over frames: inputs are (B, V, .)
with one garment topology shared by the batch.
"""

from __future__ import annotations

import torch
from torch import nn


def mlp(n_in: int, n_out: int, hidden: int, layers: int = 2, norm: bool = True) -> nn.Sequential:
    """``layers`` linear layers with ReLU between them (and a LayerNorm on the output when ``norm``)."""
    dims = [n_in] + [hidden] * (layers - 1) + [n_out]
    mods: list[nn.Module] = []
    for i in range(layers):
        mods.append(nn.Linear(dims[i], dims[i + 1]))
        if i < layers - 1:
            mods.append(nn.ReLU())
    if norm:
        mods.append(nn.LayerNorm(n_out))
    return nn.Sequential(*mods)


class PointNetEncoder(nn.Module):
    """PointNet geometry encoder: a shared per-point MLP, a max-pooled global feature, and per point the
    concatenation [local, global] mapped to ``n_out`` features. points (B, N, 3) -> (B, N, n_out)."""

    def __init__(self, n_out: int = 32, hidden: int = 64):
        super().__init__()
        self.local = mlp(3, hidden, hidden, layers=2, norm=False)
        self.out = mlp(2 * hidden, n_out, hidden, layers=2, norm=False)

    def forward(self, points: torch.Tensor) -> torch.Tensor:
        h = torch.relu(self.local(points))
        g = h.max(dim=-2, keepdim=True).values.expand_as(h)
        return self.out(torch.cat([h, g], -1))


def tangent_basis(n: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Orthonormal tangent vectors (t1, t2) of unit normals n (..., 3), smooth and finite for every n
    (Duff et al. 2017, "Building an orthonormal basis, revisited")."""
    x, y, z = n.unbind(-1)
    sign = torch.where(z >= 0, torch.ones_like(z), -torch.ones_like(z))
    a = -1.0 / (sign + z)
    b = x * y * a
    t1 = torch.stack([1.0 + sign * x * x * a, sign * b, -sign * x], -1)
    t2 = torch.stack([b, sign + y * y * a, -y], -1)
    return t1, t2


def displacement_direction(b1: torch.Tensor, b2: torch.Tensor, rho: torch.Tensor, normal: torch.Tensor, mode: str = "tangent") -> torch.Tensor:
    """Unit displacement direction of GenSim Eq. 1: D = |rho| n + (1 - |rho|) s b_hat, D_hat = D / |D|,
    with b orthogonal to the unit body normal n (..., 3) and rho in [-1, 1] (..., ) (tanh output).

    ``mode`` "paper": b = (b1, b2, b3), b3 = (-b1 n1 - b2 n2) / n3 and s = rho / |rho| as printed
    (NaN/Inf where n3 = 0, rho = 0 or b = 0); "tangent": b = b1 t1 + b2 t2 in a tangent basis of n and
    s = +1 at rho = 0, finite for every input. Both give D_hat . n = |rho| / |D| >= 0."""
    if mode == "paper":
        n1, n2, n3 = normal.unbind(-1)
        b = torch.stack([b1, b2, (-b1 * n1 - b2 * n2) / n3], -1)
        b_hat = b / b.norm(dim=-1, keepdim=True)
        s = rho / rho.abs()
    elif mode == "tangent":
        t1, t2 = tangent_basis(normal)
        b = b1[..., None] * t1 + b2[..., None] * t2
        norm = b.norm(dim=-1, keepdim=True)
        b_hat = torch.where(norm > 1e-12, b / norm.clamp_min(1e-12), t1)
        s = torch.where(rho >= 0, torch.ones_like(rho), -torch.ones_like(rho))
    else:
        raise ValueError(f"gensim direction must be 'paper' or 'tangent', not {mode!r}")
    r = rho.abs()[..., None]
    D = r * normal + (1.0 - r) * s[..., None] * b_hat
    return D / D.norm(dim=-1, keepdim=True)


class EdgeUpdate(nn.Module):
    """Residual edge update e + MLP([e, h_senders, h_receivers]) on node-major features, edges e (2E, B, n) and
    nodes h (V, B, n), with the first layer applied to the nodes before the gather (W [e; h_s; h_r] + b =
    W_e e + (W_s h + b)[s] + (W_r h)[r]): the same function, a third of the work on the (many more) edges."""

    def __init__(self, latent: int):
        super().__init__()
        self.edge_in = nn.Linear(latent, latent)
        self.sender_in = nn.Linear(latent, latent, bias=False)
        self.receiver_in = nn.Linear(latent, latent, bias=False)
        self.rest = nn.Sequential(nn.ReLU(), nn.Linear(latent, latent), nn.LayerNorm(latent))

    def forward(self, e, h, senders, receivers):
        nodes = nn.functional.linear(h, self.sender_in.weight, self.edge_in.bias).index_select(0, senders)
        nodes = nodes + self.receiver_in(h).index_select(0, receivers)
        first = torch.addmm(nodes.flatten(0, 1), e.flatten(0, 1), self.edge_in.weight.t()).view_as(e)
        return e + self.rest(first)


NORMAL_PARTS = ("abs", "softplus", "relu", "square")


def local_frame_displacement(a: torch.Tensor, b: torch.Tensor, c: torch.Tensor, normal: torch.Tensor, scale: float, sharpness: float = 100.0,
                             normal_part: str = "abs") -> torch.Tensor:  # fmt: skip
    """Displacement (..., 3) m in the local frame (n, t1, t2) of the unit body normal n (..., 3):
    scale (m) x [f(a) n + b t1 + c t2] with f = ``normal_part``: "abs" |a| (Eq. 1's |rho|: its gradient is
    +-1 wherever a != 0) or "softplus" of the given ``sharpness`` (a smooth max(a, 0); its gradient vanishes
    once a is a few 1/sharpness below 0) or "relu" max(a, 0) (exactly 0 for a <= 0, where its gradient is 0)
    or "square" a^2 (gradient 2a on both sides of 0, so noise of spread s in a around 0 moves the cloth out by
    s^2, not by s). The normal component is >= 0, so it spans the half-space of Eq. 1
    (every direction D_hat with D_hat . n >= 0, any magnitude) and is linear in b, c at zero: it can leave
    zero displacement."""
    t1, t2 = tangent_basis(normal)
    if normal_part == "abs":
        along = a.abs()
    elif normal_part == "softplus":
        along = nn.functional.softplus(a, beta=sharpness)
    elif normal_part == "relu":
        along = a.clamp_min(0.0)
    elif normal_part == "square":
        along = a.square()
    else:
        raise ValueError(f"gensim normal_part must be one of {NORMAL_PARTS}, not {normal_part!r}")
    return scale * (along[..., None] * normal + b[..., None] * t1 + c[..., None] * t2)


class PEN(nn.Module):
    """Physics Enforcing Network. ``forward(node_inputs (B, V, n_node), edge_inputs (B, 2E, n_edge),
    senders (2E,), receivers (2E,), garment_points (V, 3), body_points (B or 1, Vb, 3), body_index (B, V),
    normal (B, V, 3))`` -> displacements (B, V, 3) m and the decoded (b1, b2, rho, w).

    ``decoder`` "eq1": Eq. 1's direction (``displacement_direction`` in mode ``direction``) times the magnitude
    w = magnitude_scale x softplus(raw), the output layer scaled by 0.01 with the magnitude's bias at -4 (a
    start at about 0.2 mm); "local": :func:`local_frame_displacement` with scale ``magnitude_scale`` and
    ``normal_part`` (b1, b2 the tangent coefficients, rho the normal one, w = |delta|) and, by ``decoder_init``,
    PyTorch's default output layer ("default": a start at a few mm) or a zero one ("zero", with ``normal_part``
    "softplus" only: softplus(0) / 100 x scale = 0.07 mm along the normal; the output stays linear in the
    layer's weights, so it leaves zero). ``n_node``: node inputs per vertex (N_NODE, one more with GenSim's
    ``distance_input``). With ``input_norm`` the
    node and edge inputs are standardised by the statistics given to :meth:`set_input_statistics`."""

    N_NODE = 3 * 4 + 2  # u, v, d, n, pin, mass
    N_EDGE = 8  # E_ij, |E_ij|, E_ij^ARAP, |E_ij^ARAP|

    def __init__(self, latent: int = 128, geometry: int = 32, steps: int = 8, direction: str = "tangent", magnitude_scale: float = 0.01,
                 decoder: str = "local", decoder_init: str = "default", input_norm: bool = False, normal_part: str = "abs", n_node: int = N_NODE):  # fmt: skip
        super().__init__()
        if normal_part not in NORMAL_PARTS:
            raise ValueError(f"gensim normal_part must be one of {NORMAL_PARTS}, not {normal_part!r}")
        self.normal_part = normal_part
        self.input_norm = bool(input_norm)
        if self.input_norm:  # standardised node and edge inputs (set_input_statistics), saved with the weights
            for name, n in (("node", n_node), ("edge", self.N_EDGE)):
                self.register_buffer(f"{name}_mean", torch.zeros(n))
                self.register_buffer(f"{name}_std", torch.ones(n))
        if decoder not in ("eq1", "local"):
            raise ValueError(f"gensim decoder must be 'eq1' or 'local', not {decoder!r}")
        if decoder_init not in ("default", "zero"):
            raise ValueError(f"gensim decoder_init must be 'default' or 'zero', not {decoder_init!r}")
        if decoder == "local" and decoder_init == "zero" and normal_part != "softplus":
            raise ValueError(f"gensim decoder_init 'zero' with normal_part {normal_part!r} would start the normal coefficient at a = 0, where "
                             "it has no gradient, so PEN could never push outward; use normal_part 'softplus' or decoder_init 'default'")  # fmt: skip
        self.direction, self.magnitude_scale, self.decoder_kind = direction, magnitude_scale, decoder
        self.garment_encoder = PointNetEncoder(geometry)
        self.body_encoder = PointNetEncoder(geometry)
        self.node_encoder = mlp(2 * geometry + n_node, latent, latent)
        self.edge_encoder = mlp(self.N_EDGE, latent, latent)
        self.edge_updates = nn.ModuleList(EdgeUpdate(latent) for _ in range(steps))
        self.node_updates = nn.ModuleList(mlp(2 * latent, latent, latent) for _ in range(steps))
        self.decoder = mlp(latent, 4 if decoder == "eq1" else 3, latent, norm=False)
        if decoder == "local" and decoder_init == "zero":
            with torch.no_grad():
                self.decoder[-1].weight.zero_()
                self.decoder[-1].bias.zero_()
        if decoder == "eq1":
            with torch.no_grad():  # start near zero displacement: softplus(-4) x scale ~ 0.2 mm
                self.decoder[-1].weight.mul_(0.01)
                self.decoder[-1].bias.zero_()
                self.decoder[-1].bias[3] = -4.0

    def set_input_statistics(self, node_mean, node_std, edge_mean, edge_std, min_std: float = 1e-6) -> None:
        """Store the mean and std of the node (n_node,) and edge (N_EDGE,) inputs that ``input_norm`` standardises
        with (a std below ``min_std``, a constant input, counts as ``min_std``)."""
        if not self.input_norm:
            raise ValueError("PEN was built without input_norm: it has no input statistics to set")
        with torch.no_grad():
            self.node_mean.copy_(node_mean)
            self.node_std.copy_(node_std.clamp_min(min_std))
            self.edge_mean.copy_(edge_mean)
            self.edge_std.copy_(edge_std.clamp_min(min_std))

    def encode_geometry(self, garment_points: torch.Tensor, body_points: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """PointNet features of the garment template (V, 3) -> (1, V, g) and of the bodies (B or 1, Vb, 3) -> (B or 1, Vb, g)."""
        return self.garment_encoder(garment_points[None]), self.body_encoder(body_points)

    def forward(self, node_inputs, edge_inputs, senders, receivers, garment_points, body_points, body_index, normal, geometry=None):
        """See the class docstring; ``geometry``: :meth:`encode_geometry`'s output when already computed."""
        B, V, _ = node_inputs.shape
        if self.input_norm:
            node_inputs = (node_inputs - self.node_mean) / self.node_std
            edge_inputs = (edge_inputs - self.edge_mean) / self.edge_std
        f_gar, f_body_all = geometry if geometry is not None else self.encode_geometry(garment_points, body_points)
        f_gar, f_body_all = f_gar.expand(B, -1, -1), f_body_all.expand(B, -1, -1)
        f_body = torch.gather(f_body_all, 1, body_index[..., None].expand(-1, -1, f_body_all.shape[-1]))
        # node-major (V, B, .) and edge-major (2E, B, .) features: gathers and scatters move whole rows
        h = self.node_encoder(torch.cat([f_gar, f_body, node_inputs], -1).transpose(0, 1).contiguous())
        e = self.edge_encoder(edge_inputs.transpose(0, 1).contiguous())
        count = torch.zeros(V, dtype=h.dtype, device=h.device).index_add_(0, receivers, torch.ones_like(receivers, dtype=h.dtype))
        inverse_count = (1.0 / count.clamp_min(1.0))[:, None, None]
        for edge_mlp, node_mlp in zip(self.edge_updates, self.node_updates):
            e = edge_mlp(e, h, senders, receivers)
            agg = torch.zeros_like(h).index_add_(0, receivers, e) * inverse_count
            h = h + node_mlp(torch.cat([h, agg], -1))
        h = h.transpose(0, 1)
        out = self.decoder(h)
        if self.decoder_kind == "local":
            delta = local_frame_displacement(out[..., 2], out[..., 0], out[..., 1], normal, self.magnitude_scale, normal_part=self.normal_part)
            return delta, (out[..., 0], out[..., 1], out[..., 2], delta.norm(dim=-1))
        b1, b2, rho, w = out[..., 0], out[..., 1], torch.tanh(out[..., 2]), out[..., 3]
        magnitude = self.magnitude_scale * nn.functional.softplus(w)
        direction = displacement_direction(b1, b2, rho, normal, self.direction)
        return direction * magnitude[..., None], (b1, b2, rho, magnitude)
