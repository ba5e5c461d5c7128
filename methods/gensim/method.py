"""GenSim (Tiwari, Bhowmick, Sinha, CVPR-W 2023): motion-aware ARAP, then the Physics Enforcing Network;
one model for every garment, trained without supervision. See ``methods/gensim/README.md`` for the
paper-to-code map and every choice the paper leaves open."""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from functools import partial

import numpy as np
import torch

from drapebench.cache import Cache, body_key, content_hash
from drapebench.garments.pins import garment_pins
from drapebench.geometry.ops import vertex_normals
from drapebench.geometry.proximity import nearest_body_vertex
from drapebench.geometry.sdf import closest_body_point
from drapebench.geometry.topology import boundary_loops
from drapebench.progress import progress
from drapebench.train import Objective, train, train_config
from methods.base import DrapeResult, DrapingMethod, FitReport
from methods.gensim import losses
from methods.gensim.arap import ArapConfig, Binding, bind, front_aligned, handle_targets, motion_aware_arap, skinned_template
from methods.gensim.config import ADDED_KEYS, INFERENCE_KEYS, gensim_params
from methods.gensim.network import PEN

log = logging.getLogger("drapebench")
FRAMES = Cache("gensim", 4)  # the ARAP stage of the training frames


@dataclass
class GarmentGraph:
    """What PEN needs of one garment, whatever the frame: template (V, 3) m on the canonical body,
    topology, pins (P,) and the pin mask (V,), directed edges senders/receivers (2E,), template edge
    vectors (2E, 3), vertex masses (V,) g, the canonical binding, the betas it was made on, and u_surface (V, 3) m:
    each template vertex's offset from its closest point on the canonical body's outer surface."""

    template: torch.Tensor
    topology: object
    pins: torch.Tensor
    pin_mask: torch.Tensor
    senders: torch.Tensor
    receivers: torch.Tensor
    rest_edges: torch.Tensor
    mass_g: torch.Tensor
    binding: Binding
    betas: torch.Tensor
    u_surface: torch.Tensor

    def to(self, device) -> GarmentGraph:
        """This graph on ``device``."""
        move = {k: v.to(device) for k, v in vars(self).items() if isinstance(v, torch.Tensor)}
        return GarmentGraph(**move, topology=self.topology.to(device=device), binding=self.binding.to(device))


def garment_graph(garment, body, material) -> GarmentGraph:
    """The :class:`GarmentGraph` of a garment on its canonical body (the rest body of ``garment.betas``), on the
    body's device (the garment, a CPU record, is moved once)."""
    pins = garment_pins(garment, body).to(body.device)
    with torch.no_grad():
        canonical = body.shaped(garment.betas[None, : body.n_betas].to(body.device, body.dtype))[0][0]
    template = garment.vertices.to(body.device, body.dtype)
    topology = garment.topology.to(device=body.device)
    e = topology.edges
    senders, receivers = torch.cat([e[:, 0], e[:, 1]]), torch.cat([e[:, 1], e[:, 0]])
    b = bind(template, canonical, pins)
    surface = closest_body_point(template[None], canonical[None], body.faces, outer_faces=body.outer_faces).point[0]
    return GarmentGraph(template, topology, pins, b.pin, senders, receivers, template[receivers] - template[senders],
                        topology.vertex_masses(material).to(body.dtype) * 1e3, b, garment.betas.to(body.device, body.dtype),
                        template - surface)  # fmt: skip


def hem_vertices(garment) -> torch.Tensor:
    """(H,) long: the vertices of the garment's lowest boundary loop (mean height of its rest vertices; z up)."""
    loops = boundary_loops(garment.faces.cpu().numpy())
    if not loops:
        raise ValueError(f"gensim: garment {garment.name!r} has no boundary loop, so no hem to measure")
    z = garment.vertices[:, 2]
    return torch.as_tensor(min(loops, key=lambda loop: z[torch.as_tensor(loop, device=z.device)].mean().item()), device=z.device).long()


def _moved(items: list[tuple], device) -> list[tuple]:
    """Training items (tuples of tensors and plain values) with their tensors on ``device``."""
    return [tuple(v.to(device) if isinstance(v, torch.Tensor) else v for v in item) for item in items]


class GenSim(DrapingMethod):
    """Motion-aware ARAP + PEN (see the module docstring)."""

    name = "gensim"
    displaced_from = ("arap",)  # the recording colours PEN's displacement (Fig. 11)
    generic = True
    needs_reference = False
    learns = True

    def __init__(self, cfg=None):
        super().__init__(cfg)
        self.p = gensim_params(self.cfg)
        self.arap = ArapConfig(self.p["eps"], self.p["handle_side"], self.p["pin_rule"], self.p["arap_steps"], self.p["arap_iterations"],
                               handle_smoothing=self.p["handle_smoothing"], push_smoothing=self.p["push_smoothing"], solver=self.p["arap_solver"],
                               contact=self.p["contact"], push_margin=float(self.p["push_margin"]),
                               push_handles=bool(self.p["push_handles"]))  # fmt: skip
        self.net = None
        self._compiled = None
        self.fabric = None
        self.learns = type(self).learns and self.p["stage"] != "arap"  # the ARAP stage alone has nothing to train

    # ------------------------------------------------------------------ the two stages
    def _new_net(self) -> PEN:
        p = self.p
        return PEN(p["latent"], p["geometry"], p["steps"], p["direction"], p["magnitude_scale"], p["decoder"], p["decoder_init"],
                   p["input_norm"], p["normal_part"], PEN.N_NODE + int(p["distance_input"])).to(self.body.device, self.body.dtype)  # fmt: skip

    def arap_stage(self, graph: GarmentGraph, betas: torch.Tensor, poses: torch.Tensor):
        """ARAP-deformed garment (T, V, 3), handle masks (T, V) bool and body motion d (T, V, 3), all in the
        front-aligned frame, for a body shape ``betas`` (S,) and poses (T, J, 3); plus the aligned bodies
        (T, Vb, 3), their normals and skinning transforms (T, J, 4, 4); all on the body's device."""
        inputs = self.arap_inputs(graph, betas, poses)
        G, H, D = zip(*(self.arap_frame(inputs, t) for t in range(len(poses))))
        return *(torch.stack(a).to(self.body.device) for a in (G, H, D)), *inputs[-3:]

    def arap_inputs(self, graph: GarmentGraph, betas: torch.Tensor, poses: torch.Tensor) -> tuple:
        """What :meth:`arap_frame` reads, for all frames at once, on the CPU (the ARAP solve and its body queries
        run there: the frames' inputs go there once): the garment graph, the canonical body (Vb, 3), the
        front-aligned bodies (T, Vb, 3), their normals and the skinned pins (T, V, 3); then on the body's device
        the front-aligned bodies, their normals and skinning transforms (T, J, 4, 4)."""
        body = self.body
        verts, transforms = front_aligned(body, betas.to(body.device), poses.to(body.device, body.dtype))
        normals = vertex_normals(verts, body.faces)
        with torch.no_grad():
            canonical = body.shaped(graph.betas[None, : body.n_betas])[0][0]
            pins_at = skinned_template(graph.template, graph.binding, body, graph.betas, betas, transforms)
        return (graph.to("cpu"), *(t.cpu() for t in (canonical, verts, normals, pins_at)), verts, normals, transforms)

    def arap_frame(self, inputs: tuple, t: int) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Frame t of the ARAP stage from :meth:`arap_inputs`, on the CPU: deformed garment (V, 3), handle mask (V,)
        and d (V, 3)."""
        host, canonical, verts, normals, pins_at = inputs[:5]
        handles, targets, d = handle_targets(host.binding, host.template, canonical, verts[t], normals[t], pins_at[t], self.arap,
                                             host.topology.edges)  # fmt: skip
        G = motion_aware_arap(host.template, host.topology.faces, handles, targets, verts[t], normals[t], self.arap,
                              body_faces=self.body.faces.cpu(), outer_faces=self.body.outer_faces.cpu())  # fmt: skip
        return G, handles, d

    def features(self, graph: GarmentGraph, G, d, body_vertices, body_normals):
        """PEN's inputs for ARAP results G (B, V, 3) with body motion d (B, V, 3) on front-aligned bodies (B, Vb, 3)
        with normals: node features (B, V, 14) [u, G - body point, d, its normal, pin, mass (g)] (u and the body point
        as :meth:`body_query` reads them; with ``distance_input`` a 15th, (G - body point) . normal), edge features (B, 2E, 8) [E_ij, |E_ij|, E_ij^ARAP, |E_ij^ARAP|] (m), and
        the body normals (B, V, 3)."""
        point, normal = self.body_query(G, body_vertices, body_normals)
        B, V, _ = G.shape
        pin = graph.pin_mask.to(G.dtype)[None, :, None].expand(B, V, 1)
        mass = graph.mass_g[None, :, None].expand(B, V, 1)
        u = (graph.binding.u if self.p["body_query"] == "vertex" else graph.u_surface)[None].expand(B, V, 3)
        v = G - point
        extra = [(v * normal).sum(-1, keepdim=True)] if self.p["distance_input"] else []
        node = torch.cat([u, v, d, normal, pin, mass, *extra], -1)
        rest = graph.rest_edges[None].expand(B, -1, 3)
        arap_e = G[:, graph.receivers] - G[:, graph.senders]
        edge = torch.cat([rest, rest.norm(dim=-1, keepdim=True), arap_e, arap_e.norm(dim=-1, keepdim=True)], -1)
        return node, edge, normal

    def body_query(self, G, body_vertices, body_normals) -> tuple[torch.Tensor, torch.Tensor]:
        """The body point and outward normal PEN sees at each vertex of G (B, V, 3) m: the nearest body vertex
        and its normal (``body_query`` "vertex"), or the closest point of the body's outer surface and the
        distance field's direction there ("surface": both continuous over the garment)."""
        if self.p["body_query"] == "vertex":
            nn = nearest_body_vertex(G, body_vertices, body_normals)
            return nn.point, nn.normal
        sp = closest_body_point(G, body_vertices, self.body.faces, outer_faces=self.body.outer_faces)
        return sp.point, sp.normal

    def pen(self, graph: GarmentGraph, G, d, body_vertices, body_normals, betas, geometry=None, inference: bool = False) -> tuple[torch.Tensor, torch.Tensor]:
        """PEN's corrected garment G + delta (B, V, 3) and delta, for ARAP results G (B, V, 3), body motion
        d (B, V, 3), front-aligned bodies (B, Vb, 3) with normals, and body shapes betas (B, S);
        ``geometry``: :meth:`encode` of the garment and body shape when already computed; ``inference``: as a drape
        runs it (``pen_compile``, ``pen_precision``), else eager in the model's dtype (training)."""
        node, edge, normal = self.features(graph, G, d, body_vertices, body_normals)
        geometry = self.encode(graph, betas) if geometry is None else geometry
        index = graph.binding.nu[None].expand(G.shape[0], -1)  # each vertex's canonical closest body vertex: its body feature
        net = self.inference_net() if inference else self.net
        with torch.autocast(G.device.type, torch.bfloat16, enabled=inference and self.p["pen_precision"] == "bf16"):
            delta, _ = net(node, edge, graph.senders, graph.receivers, graph.template, None, index, normal, geometry)
        delta = delta.to(G.dtype)
        return G + delta, delta

    def input_statistics(self, n_items: int = 64) -> tuple[torch.Tensor, ...]:
        """Mean and std of PEN's node (14 or 15,) and edge (8,) inputs over about ``n_items`` training frames spread over
        the training garments (what ``input_norm`` standardises the inputs with)."""
        picked = np.unique(np.linspace(0, len(self._items) - 1, min(n_items, len(self._items))).round().astype(int))
        nodes, edges = [], []
        with torch.no_grad():
            for graph, G, d, verts, normals, _, _ in self._batch(picked, None):
                node, edge, _ = self.features(graph, G, d, verts, normals)
                nodes.append(node.flatten(0, 1))
                edges.append(edge.flatten(0, 1))
        node, edge = torch.cat(nodes), torch.cat(edges)
        return node.mean(0), node.std(0), edge.mean(0), edge.std(0)

    def encode(self, graph: GarmentGraph, betas: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """PEN's PointNet features of the garment template and of the rest bodies of shapes betas (B, S) (one
        body when every row is the same shape, as in a sequence)."""
        with torch.no_grad():
            body_rest = self.body.shaped(betas[:1] if bool((betas == betas[:1]).all()) else betas)[0]
        return self.net.encode_geometry(graph.template, body_rest)

    # ------------------------------------------------------------------ training
    def settings_key(self) -> dict:
        """The resolved parameters (code defaults included) but the inference-only ones: a changed default retrains
        instead of loading a checkpoint trained with the old one."""
        return {k: v for k, v in self.p.items() if k not in INFERENCE_KEYS}

    def trained_body(self, run_body):
        """``method.params.train.body`` when set (PEN's features do not depend on the body mesh, so the
        training frames may be posed on a cheaper body), else the run's body."""
        from drapebench.body import load_body

        name = self.p["train"]["body"]
        return run_body if name is None else load_body(name, dtype=run_body.dtype, device=run_body.device)

    def fit(self, data, train_cfg=None) -> FitReport:
        """Train PEN once on the training garments of ``method.params.train`` (see ``methods/gensim/config.py``)
        posed on random motions and body shapes, with the unsupervised losses of Eq. 9, on ``train.threads``
        torch threads; with ``stage`` "arap" there is nothing to train."""
        self.bind(data.body, data.material)
        if self.p["stage"] == "arap":  # nothing to train: the ARAP stage alone
            return FitReport(train_s=0.0, n_steps=0)
        threads, run_threads = self.p["train"]["threads"], torch.get_num_threads()
        if threads is not None:
            torch.set_num_threads(int(threads))
        try:
            return self._fit(data, train_cfg)
        finally:
            torch.set_num_threads(run_threads)

    def _fit(self, data, train_cfg) -> FitReport:
        run_body = self.body
        self.body = self.trained_body(run_body)
        train_cfg = dict(train_cfg or {})
        log_dir = train_cfg.pop("log_dir", None)
        train_cfg.pop("dataset", None)  # GenSim builds its own training frames (below)
        budget = train_config({**train_cfg, **self.p["train"]["schedule"]})
        self.fabric = self._fabric()
        torch.manual_seed(budget.seed)
        self.net = self._new_net()
        self._graphs, self._items = self._training_frames(budget.seed)
        if self.p["input_norm"]:
            self.net.set_input_statistics(*self.input_statistics())
        key = content_hash(self.p, budget, body_key(self.body), data.material, self.fabric,
                           [(g.template, g.topology.faces) for g in self._graphs])  # fmt: skip
        objective = Objective("gensim", [{"params": list(self.net.parameters()), "lr_factor": 1.0}], len(self._items),
                              self._batch, self._loss_terms, key)  # fmt: skip
        res = train(objective, budget, log_dir=log_dir)
        self.body = run_body
        return FitReport(train_s=res.train_s, n_steps=res.n_steps, stopped=res.stopped, final_losses=res.history[-1] if res.history else {},
                         history=res.history, resumed_from=res.resumed_from)  # fmt: skip

    def _fabric(self) -> dict:
        """mu_fabric and sigma_fabric (m): the configured values, or the cached fit to reference simulations."""
        if self.p["fabric_mean"] is not None:
            return {"mean": float(self.p["fabric_mean"]), "std": float(self.p["fabric_std"])}
        from methods.gensim.fabric import fit_fabric

        fit = fit_fabric()
        return {"mean": fit["mean"], "std": fit["std"]}

    def _training_frames(self, seed: int):
        """Training garments (graphs) and items (garment index, betas, poses (1, J, 3), ARAP G (V, 3), d (V, 3),
        reference drape (V, 3) or None): the ARAP stage of sampled frames of the training motions (``train.motions``)
        on random body shapes (and, when ``supervised``, their reference drapes), cached by content."""
        from drapebench.body import make_sequence
        from drapebench.garments import make_garment

        tp, body = self.p["train"], self.body
        garments = []
        for kind, params in tp["garments"]:
            for s in tp["seeds"]:
                for r in tp["resolutions"]:
                    try:
                        garments.append(make_garment(kind, body, seed=s, **{**dict(params), "resolution": r}))
                    except ValueError as err:  # a variant the factory cannot mesh well: train without it
                        log.warning("gensim: training garment %s %s (seed %d, resolution %g) skipped: %s", kind, dict(params), s, r,
                                    str(err).splitlines()[-1].strip())  # fmt: skip
        if not garments:
            raise ValueError("gensim: none of the training garments (method.params.train.garments) could be built")
        graphs = [garment_graph(g, body, self.material) for g in garments]
        path = FRAMES.path(tp, seed, self.p["supervised"], self.material, body_key(body), self.arap,
                           [(g.vertices, g.faces, g.pins) for g in garments], prefix="frames", suffix=".pt")  # fmt: skip
        items = FRAMES.load(path, partial(torch.load, map_location="cpu", weights_only=False))
        if items is not None:  # prepared (and cached) on the CPU, moved to the body's device once
            return graphs, _moved(items, body.device)
        log.info("gensim: computing the ARAP stage of %d training frames (%d garments; cached after)",
                 len(garments) * tp["sequences"] * tp["frames_per_sequence"], len(garments))  # fmt: skip
        rng = np.random.default_rng(seed)
        items = []
        plan = [(gi, k) for gi in range(len(graphs)) for k in range(tp["sequences"])]
        for gi, k in progress(plan, desc="gensim ARAP training frames", unit="seq"):
            betas = torch.zeros(body.n_betas, dtype=body.dtype, device="cpu")
            n = tp["n_shape_betas"]
            betas[:n] = torch.as_tensor(np.clip(rng.normal(0, tp["beta_std"], n), -tp["beta_clip"], tp["beta_clip"]), dtype=body.dtype, device="cpu")
            motion = tp["motions"][(gi * tp["sequences"] + k) % len(tp["motions"])]  # the list cycles over every garment's sequences
            seq = make_sequence(motion, tp["n_frames"], seed=int(rng.integers(2**31)), betas=betas.tolist())
            frames = np.linspace(seq.n_transition, seq.n_frames - 1, tp["frames_per_sequence"]).round().astype(int)
            poses = seq.poses[frames].to(body.dtype)
            refs = self._reference_frames(garments[gi], seq, frames) if self.p["supervised"] else [None] * len(frames)
            if refs is None:
                continue
            G, _, D, *_ = self.arap_stage(graphs[gi], betas, poses)
            items += [(gi, betas, poses[j : j + 1], G[j].cpu(), D[j].cpu(), refs[j]) for j in range(len(frames))]
        if not items:
            raise RuntimeError("gensim: no training frames (every reference simulation failed); see the warnings above")
        FRAMES.store(path, lambda tmp: torch.save(items, tmp))  # on the CPU: a cache any device reads
        return graphs, _moved(items, body.device)

    def _reference_frames(self, garment, seq, frames):
        """Reference drapes (F, V, 3) of ``frames`` of ``seq`` in the front-aligned frame (the supervised
        variant's targets), or None (with a warning) when the simulation fails."""
        from drapebench.errors import DrapeFailed
        from drapebench.reference import simulate

        try:
            x = simulate(garment, seq, self.body, self.material)[frames].to(self.body.dtype)
        except DrapeFailed as err:
            log.warning("gensim: no reference for %s on %s, sequence skipped: %s", garment.name, seq.name, err)
            return None
        root = seq.transforms(self.body)[frames, 0].to(x.device, x.dtype)  # aligned -> world: x = R y + t
        return ((x - root[:, None, :3, 3]) @ root[:, :3, :3]).cpu()  # a training frame, prepared on the CPU

    def _batch(self, items: np.ndarray, at) -> list:
        """Items grouped by garment: [(graph, G (B, V, 3), d, body (B, Vb, 3), normals, betas (B, S), reference
        drapes (B, V, 3) or None)]."""
        groups: dict[int, list] = {}
        for j in items:
            groups.setdefault(self._items[j][0], []).append(self._items[j])
        out = []
        for gi, rows in groups.items():
            betas = torch.stack([r[1] for r in rows])
            poses = torch.cat([r[2] for r in rows])
            verts, _ = front_aligned(self.body, betas, poses)
            ref = torch.stack([r[5] for r in rows]) if self.p["supervised"] else None
            out.append((self._graphs[gi], torch.stack([r[3] for r in rows]), torch.stack([r[4] for r in rows]), verts,
                        vertex_normals(verts, self.body.faces), betas, ref))  # fmt: skip
        return out

    def _loss_terms(self, batch: list, at) -> dict:
        """Eq. 9's weighted terms, averaged over the frames of the batch (each garment's frames together)."""
        total, n = {}, sum(len(b[1]) for b in batch)
        for graph, G, d, verts, normals, betas, ref in batch:
            x, _ = self.pen(graph, G, d, verts, normals, betas)
            for name, value in self.terms(graph, x, G, verts, normals, ref).items():
                total[name] = total.get(name, 0.0) + value * (len(G) / n)
        return total

    def terms(self, graph: GarmentGraph, x, G, body_vertices, body_normals, reference=None) -> dict:
        """The weighted loss terms (frame means) of predictions x (B, V, 3) for ARAP results G: Eq. 9's, or with
        ``supervised`` L2 to ``reference`` (B, V, 3) + smoothness + collision; a term of weight 0 is left out."""
        w, mat, topo = self.p["weights"], self.material, graph.topology
        make = {
            "restrain": lambda: losses.restrain(x, topo, self.fabric["mean"], self.fabric["std"], w["restrain"], self.p["restrain_reduction"],
                                                self.p["restrain_offset"], self.p["restrain_huber"]),  # fmt: skip
            "bending": lambda: losses.bending(x, topo, mat, w["bending"], self.p["bending_rest"]),
            "pin": lambda: losses.pin(x, G, graph.pins, w["pin"]),
            "potential": lambda: losses.potential(x, topo, mat, ~graph.pin_mask, w["potential"]),
            "smoothness": lambda: losses.smoothness(x, topo, w["smoothness"]),
            "collision": lambda: losses.collision(x, body_vertices, body_normals, self.p["collision_eps"], w["collision"], contact=self.p["contact"],
                                                  body_faces=self.body.faces, outer_faces=self.body.outer_faces),  # fmt: skip
            "l2": lambda: losses.l2(x, reference, w["l2"]),
        }
        names = losses.SUPERVISED if self.p["supervised"] else losses.UNSUPERVISED
        return {name: make[name]() for name in names if w[name] != 0}

    # ------------------------------------------------------------------ inference
    def drape(self, garment, seq) -> DrapeResult:
        """Each frame: ARAP on the front-aligned body, PEN, then the root rotation and translation put back;
        ``workers`` frames at once (threads, torch single-threaded in each). ``extras`` holds the ARAP stage
        (T, V, 3) and its handle masks (T, V). ``timings_ms`` splits the wall time of the frames between
        "arap" and "pen" in proportion to the two stages' summed time over the frames (with the bodies and pins
        of every frame in "arap", PEN's geometry encoding in "pen")."""
        self._require_bound()
        if self.net is None and self.p["stage"] == "full":
            raise RuntimeError("gensim: not trained; call fit() or load_state_dict() first")
        t0 = time.perf_counter()
        graph = garment_graph(garment, self.body, self.material)
        betas = self.sequence_shape(seq)
        t1 = time.perf_counter()
        inputs = self.arap_inputs(graph, betas, seq.poses)
        full = self.p["stage"] == "full"
        t_inputs = time.perf_counter()
        with torch.inference_mode():
            geometry = self.encode(graph, betas[None]) if full else None  # one garment and body shape for the whole drape
        verts, normals, device = inputs[-3], inputs[-2], self.body.device

        def frame(t: int):
            a = time.perf_counter()
            G, H, D = (v.to(device) for v in self.arap_frame(inputs, t))
            b = time.perf_counter()
            if full:
                with torch.inference_mode():
                    x = self.pen(graph, G[None], D[None], verts[t : t + 1], normals[t : t + 1], betas[None], geometry, inference=True)[0][0]
            c = time.perf_counter()
            return (x if full else G), G, H, b - a, c - b

        t_frames = time.perf_counter()
        workers = min(int(self.p["workers"]), seq.n_frames)
        if workers > 1:
            from concurrent.futures import ThreadPoolExecutor

            threads = torch.get_num_threads()
            torch.set_num_threads(1)
            try:
                out = [frame(0)] if self.p["pen_compile"] else []  # torch.compile compiles on one thread, then the frames share it
                with ThreadPoolExecutor(workers) as pool:
                    out += list(pool.map(frame, range(len(out), seq.n_frames)))
            finally:
                torch.set_num_threads(threads)
        else:
            out = [frame(t) for t in range(seq.n_frames)]
        t2 = time.perf_counter()
        x, G = torch.stack([o[0] for o in out]), torch.stack([o[1] for o in out])
        H = torch.stack([o[2] for o in out])
        x, G = self.to_world(seq, x, G)
        t3 = time.perf_counter()
        arap_s, pen_s = sum(o[3] for o in out), sum(o[4] for o in out)
        share = arap_s / max(arap_s + pen_s, 1e-12)
        ms = lambda a, b: (b - a) * 1e3  # noqa: E731
        extras = {"arap": G, "handles": H} if full else {"handles": H}
        timings = {"setup": ms(t0, t1), "arap": ms(t1, t_inputs) + ms(t_frames, t2) * share,
                   "pen": ms(t_inputs, t_frames) + ms(t_frames, t2) * (1 - share), "pose": ms(t2, t3)}  # fmt: skip
        return DrapeResult(x.clone(), timings, extras)

    def inference_net(self):
        """PEN as inference runs it: under torch.compile with ``pen_compile`` (compiled once, on first use)."""
        if not self.p["pen_compile"]:
            return self.net
        if self._compiled is None or self._compiled[0] is not self.net:
            self._compiled = (self.net, torch.compile(self.net, dynamic=True))
        return self._compiled[1]

    def sequence_shape(self, seq) -> torch.Tensor:
        """(S,) the body shape of ``seq`` in the body's betas (zeros where the sequence gives fewer)."""
        betas = torch.zeros(self.body.n_betas, dtype=self.body.dtype, device=self.body.device)
        given = seq.betas[: self.body.n_betas]
        betas[: len(given)] = given.to(self.body.device, self.body.dtype)
        return betas

    def to_world(self, seq, *drapes: torch.Tensor) -> list[torch.Tensor]:
        """Drapes (T, V, 3) in the front-aligned frame moved to the world by each frame's root transform of ``seq``."""
        root = seq.transforms(self.body)[:, 0].to(drapes[0].dtype)  # the root's skinning transform: aligned -> world
        return [y @ root[:, :3, :3].transpose(1, 2) + root[:, None, :3, 3] for y in drapes]

    def diagnostics(self, garment, seq, result: DrapeResult) -> dict:
        """PEN's displacement from the ARAP stage over the vertices of every frame after the transition: mean,
        p99 and max |delta| (mm; "pen_mm", "pen_p99_mm", "pen_max_mm"), "hem_drop_mm", how far PEN lowers
        the hem (the garment's lowest boundary loop; positive: down) on average, and "pin_drop_mm", how far it
        lowers the pinned vertices (the waistband: the whole garment's fall, which a hem that curls up hides;
        Fig. 10); none for the ARAP stage alone."""
        if "arap" not in result.extras:
            return {}
        delta = (result.vertices - result.extras["arap"])[seq.n_transition :].double() * 1e3
        if not len(delta):
            return {}
        moved = delta.norm(dim=-1).flatten()
        stats = {"pen_mm": moved.mean().item(), "pen_p99_mm": moved.quantile(0.99).item(), "pen_max_mm": moved.max().item()}
        if garment is not None:
            stats["hem_drop_mm"] = -delta[:, hem_vertices(garment).to(delta.device), 2].mean().item()
            if len(garment.pins):
                stats["pin_drop_mm"] = -delta[:, garment.pins.long().to(delta.device), 2].mean().item()
        return stats

    # ------------------------------------------------------------------ state
    def state_dict(self) -> dict:
        if self.net is None:
            return {}
        return {"net": self.net.state_dict(), "params": dict(self.p), "fabric": dict(self.fabric)}

    def load_state_dict(self, state) -> None:
        if not state:
            return
        model = self.settings_key()
        trained = {**ADDED_KEYS, **{k: v for k, v in state["params"].items() if k not in INFERENCE_KEYS}}  # a key added later: its old behaviour
        if trained != model:
            raise ValueError(f"gensim checkpoint was trained with {trained}, not {model}")
        self._require_bound()
        self.net = self._new_net()
        self.net.load_state_dict(state["net"])
        self.fabric = dict(state["fabric"])
