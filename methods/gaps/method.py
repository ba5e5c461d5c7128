"""GAPS (Chen et al., 3DV 2024): GRU draping with RBF body-participation skinning and
collision-aware inextensibility, self-supervised by physics losses; plus the SNUG-like and
NCS-like ablations as configurations of the same code.

The paper-to-code map and every choice where the paper is silent or differs from the public code
(all configurable in ``method.params``, its ``train`` sub-dict, or the budget ``conf/train``):
``methods/gaps/README.md``. Defaults: ``methods/gaps/config.py``.
"""

from __future__ import annotations

import time

import numpy as np
import torch

from drapebench.body.dataset import redrawn, spec_sequences
from drapebench.body.lbs import lbs
from drapebench.body.skinning import nearest_body_vertices, nearest_weights
from drapebench.cache import content_hash
from drapebench.geometry.ops import ring_smooth, vertex_normals
from drapebench.geometry.proximity import culled_body_vertices, nearest_body_vertex
from drapebench.geometry.sdf import closest_body_point
from drapebench.optimum import sequence_terms
from drapebench.train import Objective, train, train_config
from methods.base import DrapeResult, DrapingMethod, FitReport
from methods.gaps import losses
from methods.gaps.basis import KEYS as BASIS_KEYS, laplacian_basis
from methods.gaps.canonical import RELAXED, relaxation
from methods.gaps.config import ADDED_KEYS, gaps_params
from methods.gaps.network import GapsNet
from methods.gaps.skinning import rbf_shapedirs, rbf_weights, smoothed_weights


def root_velocity(seq) -> torch.Tensor:
    """(T, 3) root translation velocity of a sequence in m/s (backward difference; 0 at the first frame), on the
    device of ``seq.trans``."""
    return torch.cat([torch.zeros(1, 3, dtype=seq.trans.dtype, device=seq.trans.device), (seq.trans[1:] - seq.trans[:-1]) * seq.fps])


class GAPS(DrapingMethod):
    """GAPS and its ablations (see the module docstring for every reading of the paper)."""

    name = "gaps"
    displaced_from = ("raw",)  # under collision_postprocess: the push-out's move
    generic = False
    needs_reference = False
    learns = True

    def __init__(self, cfg=None):
        super().__init__(cfg)
        self.p = gaps_params(self.cfg)
        self.net = None
        self.weights = None
        self.template = None
        self.garment_key = None

    # ------------------------------------------------------------------ garment set-up
    def _setup(self, garment) -> None:
        """Per-garment constants on the body's device: template, skinning weights, bending blend, nearest body
        vertices, culling (the garment, a CPU record, is moved once)."""
        body, p = self.body, self.p
        with torch.no_grad():
            rest_body = body.shaped(garment.betas[None, : body.n_betas])[0][0]
        self.template = garment.vertices.to(body.device, body.dtype)
        self.topology = garment.topology.to(device=body.device)
        self.nn_rest = nearest_body_vertices(self.template, body, garment.betas)
        self.shape_dirs = self._shape_dirs(rest_body)
        if p["skinning"] == "rbf":
            w = rbf_weights(self.template, rest_body, body.weights, p["rbf_k"])
        else:
            w = nearest_weights(self.nn_rest, body)
            if p["skinning"] == "smoothed":
                w = smoothed_weights(w, garment.topology, p["smooth_iterations"])
        if self.weights is None or self.weights.shape != w.shape:
            self.weights = torch.nn.Parameter(w, requires_grad=p["trainable_weights"])
        rest_normals = vertex_normals(rest_body[None], body.faces)[0]
        self.bend_blend = losses.blend_weights(self.template, rest_body, rest_normals, self.nn_rest, garment.topology.hinge_edges, p["bending_blend"])
        self.candidates = culled_body_vertices(self.template, rest_body, body.weights)
        self.garment_betas = garment.betas[: body.n_betas].to(body.device, body.dtype)
        self.n_in = body.n_betas + 3 * body.n_joints + 3
        if self.net is None:
            self.net = GapsNet(self.n_in, 3 * garment.n_vertices, p["hidden"], p["layers"], p["zero_init_output"], self._output_basis(garment)).to(body.device, body.dtype)
            self.input_mean = torch.zeros(self.n_in, device=body.device)
            self.input_std = torch.ones(self.n_in, device=body.device)
        self.garment_key = content_hash(garment.vertices, garment.faces)
        self.relaxed = relaxation(self).to(body.device) if p["canonical"] == "relaxed" else None

    def _output_basis(self, garment) -> torch.Tensor | None:
        """(V, K) the network's output basis per ``output_basis`` (laplacian: the template's ``basis_modes``
        lowest Laplacian eigenmodes, :mod:`methods.gaps.basis`, in the body's dtype), None for dense (the paper)."""
        if self.p["output_basis"] == "dense":
            return None
        return laplacian_basis(garment.vertices, garment.faces, self.p["basis_modes"]).vectors.to(self.body.dtype)

    # ------------------------------------------------------------------ forward model
    def _inputs(self, betas: torch.Tensor, poses: torch.Tensor, vel: torch.Tensor) -> torch.Tensor:
        """(B, T, S + 3J + 3) network input from betas (B, S), poses (B, T, J, 3), root velocity (B, T, 3) m/s."""
        B, T = poses.shape[:2]
        x = torch.cat([betas[:, None].expand(B, T, -1), poses.reshape(B, T, -1), vel], -1)
        return (x - self.input_mean) / self.input_std if self.p["normalize_inputs"] else x

    def _shape_dirs(self, rest_body: torch.Tensor) -> torch.Tensor | None:
        """(V, 3, S) m per unit beta: the body's shape blend shapes on the garment per ``shape_transfer``
        (nearest: the nearest body vertex's, SNUG; rbf: averaged by GAPS's body participation), None for none."""
        mode = self.p["shape_transfer"]
        if mode == "nearest":
            return self.body.shapedirs[self.nn_rest]
        if mode == "rbf":
            return rbf_shapedirs(self.template, rest_body, self.body.shapedirs, self.p["rbf_k"])
        return None

    def _canonical(self, delta: torch.Tensor, betas: torch.Tensor, relaxed: bool = True) -> torch.Tensor:
        """Template + displacements delta (B, T, 3V) m -> (B, T, V, 3) m, plus the body's shape blend shape
        for betas (B, S) away from the garment's own shape unless ``shape_transfer`` is none, plus (``relaxed``
        and ``canonical: relaxed``) the canonical garment's relaxation at that shape (:mod:`methods.gaps.canonical`)."""
        x = self.template + delta.reshape(*delta.shape[:2], -1, 3)
        if self.shape_dirs is not None:
            x = x + torch.einsum("vcs,bs->bvc", self.shape_dirs, betas - self.garment_betas)[:, None]
        if relaxed and getattr(self, "relaxed", None) is not None:
            x = x + self.relaxed.at(betas - self.garment_betas).to(x.dtype)[:, None]
        return x

    # ------------------------------------------------------------------ training
    def trained_beta_bound(self) -> tuple[float, ...]:
        """``train.beta_range``: training draws beta_k ~ U(-r_k, r_k) on its first components (0 after); all 0
        with ``single_shape`` (NCS: the mean body only)."""
        bound = tuple(self.p["train"]["beta_range"])
        return tuple(0.0 for _ in bound) if self.p["single_shape"] else bound

    def fit(self, data, train_cfg=None) -> FitReport:
        """Self-supervised training on ``data.train_sequences`` with :func:`drapebench.train.train` under the
        budget ``train_cfg`` (``conf/train``; its ``log_dir`` entry, if any, receives ``losses.csv``)."""
        self.bind(data.body, data.material)
        train_cfg = dict(train_cfg or {})
        log_dir = train_cfg.pop("log_dir", None)
        tp = self.p["train"]
        budget = train_config({**train_cfg, **tp["schedule"]})
        torch.manual_seed(budget.seed)  # before the network is created: initial weights follow the seed
        self._setup(data.garment)
        if len(tp["beta_range"]) > self.body.n_betas:
            raise ValueError(f"method.params.train.beta_range has {len(tp['beta_range'])} entries but the body has {self.body.n_betas} betas")
        seqs = self._training_sequences(data.train_sequences)
        self._use_sequences(seqs, 0)
        self._dataset = budget.dataset
        if self.p["normalize_inputs"]:
            allx = torch.cat([torch.cat([p.reshape(len(p), -1), v], -1) for p, v in zip(self._poses, self._vels)])
            self.input_mean[self.body.n_betas :] = allx.mean(0)
            self.input_std[self.body.n_betas :] = allx.std(0).clamp_min(1e-3)
        body_params = list(self.net.gru.parameters()) + ([self.weights] if self.weights.requires_grad else [])
        groups = [{"name": "trunk", "params": body_params, "lr_factor": 1.0},
                  {"name": "output", "params": list(self.net.out.parameters()), "lr_factor": tp["lr_output_factor"], "eps": tp["output_adam_eps"]}]  # fmt: skip
        key = content_hash(self._model_key(), budget, self.garment_key, dict(self.body.state_dict()), self.body.parents, data.material,
                           [(s.betas, s.poses, s.trans, s.fps) for s in seqs], None if self.relaxed is None else self.relaxed.d)  # fmt: skip
        objective = Objective("gaps", groups, len(self._windows), self._batch, self._loss_terms, key)
        rounds = int(tp["output_smoothing"])
        if rounds and self.net.basis is not None:
            raise ValueError("gaps: method.params.train.output_smoothing smooths a dense output layer's gradient over the garment; "
                             "with output_basis: laplacian the output is smooth already: set output_smoothing to 0")  # fmt: skip
        hooks = [w.register_hook(lambda g: self._smooth_over_garment(g, rounds)) for w in self.net.out.parameters()] if rounds else []
        try:
            res = train(objective, budget, log_dir=log_dir)
        finally:
            for h in hooks:
                h.remove()
        return FitReport(train_s=res.train_s, n_steps=res.n_steps, stopped=res.stopped, final_losses=res.history[-1] if res.history else {},
                         history=res.history, resumed_from=res.resumed_from)  # fmt: skip

    def _use_sequences(self, seqs: list, draw: int) -> None:
        """Train on ``seqs`` (draw ``draw`` of the dataset, :meth:`_batch`): their windows, poses, root velocities and
        translations. Raises ValueError if a redraw gives another number of windows than the first draw."""
        W = self.p["train"]["window"]
        windows = [(i, t) for i, s in enumerate(seqs) for t in range(1, s.n_frames - W + 1)]
        if draw and len(windows) != len(self._windows):
            raise ValueError(f"gaps: draw {draw} of the training dataset has {len(windows)} windows, the first {len(self._windows)}")
        self._windows, self._draw = windows, draw
        dev, dtype = self.body.device, self.body.dtype  # the training sequences, read on the CPU, moved to the device once
        self._poses = [s.poses.to(dev, dtype) for s in seqs]
        self._vels = [root_velocity(s).to(dev, dtype) for s in seqs]
        self._trans = [s.trans.to(dev, dtype) for s in seqs]

    def _smooth_over_garment(self, grad: torch.Tensor, rounds: int) -> torch.Tensor:
        """The output layer's gradient (3V, H) or (3V,) smoothed over the garment's 1-rings ``rounds`` times
        (``train.output_smoothing``): a step of the layer then moves the displacement field by a smoothed
        gradient, without per-vertex noise."""
        return ring_smooth(grad.reshape(len(self.template), -1), self.topology, rounds).reshape(grad.shape)

    def _training_sequences(self, seqs: list) -> list:
        """The training dataset's sequences less those of ``train.exclude_motions``; raises ValueError naming an
        excluded motion the dataset lacks, or when nothing is left."""
        exclude = set(self.p["train"]["exclude_motions"])
        unknown = exclude - {s.motion for s in seqs}
        if unknown:
            raise ValueError(f"method.params.train.exclude_motions names {sorted(unknown)}, which the training dataset does not hold "
                             f"(it has {sorted({s.motion for s in seqs})})")  # fmt: skip
        kept = [s for s in seqs if s.motion not in exclude]
        if not kept:
            raise ValueError("gaps needs training sequences (train.dataset), and train.exclude_motions leaves none")
        return kept

    def _batch(self, items: np.ndarray, at) -> tuple:
        """Windows ``items`` of the training data: random body shapes (B, S), poses (B, W, J, 3), root
        velocity (B, W, 3) and translation (B, W, 3), and the posed body (no gradient). With
        ``train.redraw_motions``, epoch e >= 1 draws its sequences anew (:func:`drapebench.body.dataset.redrawn`)."""
        body, p, W = self.body, self.p, self.p["train"]["window"]
        if p["train"]["redraw_motions"] and at.epoch != self._draw:  # a new epoch: new motions and body shapes of the same dataset
            self._use_sequences(self._training_sequences(spec_sequences(redrawn(self._dataset, at.epoch))), at.epoch)
        batch = [self._windows[j] for j in items]
        B = len(batch)
        betas = torch.zeros(B, body.n_betas, dtype=body.dtype, device=body.device)
        if not p["single_shape"]:
            r = np.asarray(p["train"]["beta_range"], dtype=np.float64)
            betas[:, : len(r)] = torch.as_tensor(at.rng.uniform(-r, r, (B, len(r))), dtype=body.dtype, device=body.device)
        pose = torch.stack([self._poses[i][t : t + W] for i, t in batch])
        vel = torch.stack([self._vels[i][t : t + W] for i, t in batch])
        tr = torch.stack([self._trans[i][t : t + W] for i, t in batch])
        with torch.no_grad():
            out = body.forward(betas.repeat_interleave(W, 0), pose.reshape(B * W, -1, 3), tr.reshape(B * W, 3))
            normals = vertex_normals(out.vertices, body.faces)
        return betas, pose, vel, tr, out, normals

    def _loss_terms(self, batch: tuple, at) -> dict:
        """The drape of a batch by the network (GRU state drawn from N(0, hidden_init_std^2)) and its loss terms."""
        betas, pose, vel, tr, out, normals = batch
        p, B, W = self.p, len(betas), self.p["train"]["window"]
        h0 = torch.randn(p["layers"], B, p["hidden"], dtype=self.body.dtype, device=self.body.device) * p["train"]["hidden_init_std"]
        delta, _ = self.net(self._inputs(betas, pose, vel), h0)
        xc = self._canonical(delta, betas).reshape(B * W, -1, 3)
        x = lbs(xc, self.weights, out.transforms)  # (B*W, V, 3)
        return self._terms(x, out.vertices, normals, at.epoch)

    def _terms(self, x: torch.Tensor, body_vertices: torch.Tensor, body_normals: torch.Tensor, epoch: int, p: dict | None = None) -> dict:
        """The training loss's named, weighted terms of drapes x (B*W, V, 3) m, B windows of ``train.window``
        frames, on the posed body (body_vertices, body_normals (B*W, Vb, 3)), with k_ext at ``epoch``, under the
        parameters ``p`` (default: the model's)."""
        nn = self._body_contact(x, body_vertices, body_normals)
        terms, k_ext = losses.loss_terms(x, self.p["train"]["window"], nn, self.topology, self.material, p or self.p, epoch, self.bend_blend)
        if k_ext is not None:
            self.last_kext_max = float(k_ext.max())
        return terms

    def window_loss(self, seq, epoch: int):
        """GAPS's training loss as a function of the drape, for :func:`drapebench.optimum.optimise_sequence`:
        a callable (t, window (W, V, 3) m, the drapes of frames t-W+1..t of ``seq``) -> (loss, {term: value}),
        the same terms, weights, normalisation (one window: B = 1) and body contact as a training step at
        ``epoch`` (which sets k_ext, GAPS Eq. 16). Needs the garment's constants (:meth:`_setup`)."""
        W = self.p["train"]["window"]
        body_vertices = seq.vertices(self.body).to(self.body.dtype)
        body_normals = seq.vertex_normals(self.body).to(self.body.dtype)

        def loss(t: int, window: torch.Tensor):
            frames = [max(i, 0) for i in range(t - W + 1, t + 1)]  # before the sequence: its first frame (at rest)
            terms = self._terms(window, body_vertices[frames], body_normals[frames], epoch)
            return sum(terms.values()), terms

        return loss

    def _body_contact(self, x: torch.Tensor, body_vertices: torch.Tensor, body_normals: torch.Tensor):
        """Where each garment vertex x (B, V, 3) m meets the posed body (body_vertices, body_normals
        (B, Vb, 3)): ``.point``, unit ``.normal`` and signed ``.distance`` (m, negative inside), for the
        collision term, k_ext and the push-out. ``collision_distance`` "surface": the closest point of
        the body mesh and the exact signed distance (:mod:`drapebench.geometry.sdf`); "vertex": the
        nearest body vertex and its normal (the GAPS/SNUG code)."""
        if self.p["collision_distance"] == "surface":
            return closest_body_point(x.detach(), body_vertices.detach(), self.body.faces, outer_faces=self.body.outer_faces)
        return nearest_body_vertex(x, body_vertices, body_normals, self.candidates)

    # ------------------------------------------------------------------ inference
    def drape(self, garment, seq) -> DrapeResult:
        """Drape all frames: one GRU pass (state carried, zeros at start), the output layer and skinning batched over
        frames, then the collision push-out if ``collision_postprocess`` (``extras["raw"]``: the drape before it)."""
        self._require_bound()
        if self.net is None:
            raise RuntimeError("gaps: not trained; call fit() or load_state_dict() first")
        if self.net.n_out != 3 * garment.n_vertices:
            raise ValueError(f"gaps: this model was trained for a {self.net.n_out // 3}-vertex garment, not {garment.n_vertices}")
        t_setup = time.perf_counter()
        if getattr(self, "template", None) is None or content_hash(garment.vertices, garment.faces) != self.garment_key:
            self._setup(garment)  # per-garment constants (after load_state_dict); learned weights are kept
        t0 = time.perf_counter()
        transforms = seq.transforms(self.body)
        betas = self._sequence_betas(seq)
        t1 = time.perf_counter()
        with torch.no_grad():  # not inference_mode: the result is an ordinary tensor, no copy of the sequence needed
            delta = self.displacements(seq)
            t2 = time.perf_counter()
            xc = self._canonical(delta, betas)[0]
            del delta  # (T, 3V): freed before skinning, which holds another (T, V, 3)
            x = lbs(xc, self.weights, transforms)
            del xc
        t3 = time.perf_counter()
        ms = lambda a, b: (b - a) * 1e3  # noqa: E731
        timings = {"setup": ms(t_setup, t0), "body": ms(t0, t1), "network": ms(t1, t2), "skinning": ms(t2, t3)}
        if self.p["collision_postprocess"]:  # SNUG's in-graph fix
            pushed = self._push_out(x, seq)
            timings["postprocess"] = ms(t3, time.perf_counter())
            return DrapeResult(pushed, timings, {"raw": x})
        return DrapeResult(x, timings)

    def scored_variants(self, seq, result: DrapeResult) -> dict:
        """Drapes scored beside the drape, each (T, V, 3) m: the other side of the collision push-out (the paper
        scores before it), "postprocessed", or "raw", the network's drape, under ``collision_postprocess``; and
        "untrained", the skinning with the network's output zero (what training starts from)."""
        with torch.no_grad():
            untrained = self.untrained_drape(seq).to(result.vertices.dtype)
            if self.p["collision_postprocess"]:
                return {"raw": result.extras["raw"], "untrained": untrained}
            return {"postprocessed": self._push_out(result.vertices, seq), "untrained": untrained}

    def kext_epoch(self) -> int:
        """The training epoch whose k_ext a drape's own loss is scored at: the end of the ramp (k_ext's final value)."""
        return self.p["train"]["kext_ramp_epochs"]

    def diagnostics(self, garment, seq, result: DrapeResult) -> dict:
        """GAPS's own training loss (:meth:`window_loss` at :meth:`kext_epoch`; J per frame, mean over the frames after
        the transition) on the drape before any push-out, ``gaps_loss``, and on the untrained skinning,
        ``gaps_loss@untrained``: with a ``gaps_optimum`` run of the scene, the report's ``loss_gap_closed``."""
        loss, start, W = self.window_loss(seq, self.kext_epoch()), int(seq.n_transition), self.p["train"]["window"]
        drapes = {"gaps_loss": result.extras.get("raw", result.vertices), "gaps_loss@untrained": self.untrained_drape(seq)}
        return {name: float(np.mean([sum(t.values()) for t in sequence_terms(loss, x.to(self.body.dtype), W)[start:]])) for name, x in drapes.items()}

    def _push_out(self, x: torch.Tensor, seq) -> torch.Tensor:
        """SNUG's collision post-processing: each vertex of the drape x (T, V, 3) m of ``seq`` moved out along the
        body's normal by max(collision_eps - d, 0), d its signed distance (m) to the posed body."""
        bv, bn = seq.vertices(self.body).to(x.dtype), seq.vertex_normals(self.body).to(x.dtype)
        nn = self._body_contact(x, bv, bn)
        return x + torch.relu(self.p["collision_eps"] - nn.distance)[..., None] * nn.normal

    def _sequence_betas(self, seq) -> torch.Tensor:
        """(1, S) the sequence's shape coefficients, zero-padded to the body's S (a sequence may give fewer)."""
        betas = torch.zeros(1, self.body.n_betas, dtype=self.body.dtype, device=self.body.device)
        given = seq.betas[: self.body.n_betas]
        betas[0, : len(given)] = given.to(self.body.device, self.body.dtype)
        return betas

    def sequence_inputs(self, seq) -> torch.Tensor:
        """(1, T, S + 3J + 3): the network's input on ``seq`` (its betas, poses and root velocity)."""
        dev, dtype = self.body.device, self.body.dtype
        vel = root_velocity(seq)[None].to(dev, dtype)
        return self._inputs(self._sequence_betas(seq), seq.poses[None].to(dev, dtype), vel)

    def displacements(self, seq) -> torch.Tensor:
        """(1, T, 3V) m: the network's canonical displacements on ``seq`` (GRU state zero), no gradient."""
        with torch.no_grad():
            return self.net(self.sequence_inputs(seq))[0]

    def forward_sequence(self, garment, seq, h0=None):
        """Differentiable drape (T, V, 3) and final hidden state, for tests and fine-tuning."""
        betas = self._sequence_betas(seq)
        delta, h = self.net(self.sequence_inputs(seq), h0)
        return self.skinned(delta, betas, seq), h

    def untrained_drape(self, seq) -> torch.Tensor:
        """(T, V, 3) m: the skinning alone (network output zero, where training starts) on ``seq``; needs the
        garment's constants (:meth:`_setup` or a :meth:`drape` of the garment)."""
        with torch.no_grad():
            zero = torch.zeros(1, seq.n_frames, 3 * self.template.shape[0], dtype=self.body.dtype, device=self.body.device)
            return self.skinned(zero, self._sequence_betas(seq), seq)

    def skinned(self, delta: torch.Tensor, betas: torch.Tensor, seq) -> torch.Tensor:
        """The drape (T, V, 3) m of canonical displacements delta (1, T, 3V) m on ``seq`` with shape betas (1, S)."""
        return lbs(self._canonical(delta, betas)[0], self.weights, seq.transforms(self.body))

    # ------------------------------------------------------------------ state
    def state_dict(self) -> dict:
        if self.net is None:
            return {}
        return {"net": self.net.state_dict(), "weights": self.weights.detach().clone(), "input_mean": self.input_mean,
                "input_std": self.input_std, "params": dict(self.p), "garment_key": self.garment_key,
                "n_in": self.n_in, "n_out": self.net.n_out}  # fmt: skip

    def settings_key(self) -> dict:
        """The resolved parameters (code defaults included; :meth:`_model_key`) and, with ``canonical: relaxed``, the
        relaxation's cache version: a changed default or relaxation retrains instead of loading a checkpoint trained
        with the old one."""
        p = self._model_key()
        return {**p, "relaxation": RELAXED.version} if self.p["canonical"] == "relaxed" else p

    def _model_key(self) -> dict:
        """The parameters as a checkpoint's key holds them: with the dense output (the paper's), without the
        output basis's keys, which it does not read, so that checkpoints trained before those keys still load."""
        if self.p["output_basis"] != "dense":
            return self.p
        return {k: v for k, v in self.p.items() if k not in BASIS_KEYS}

    def load_state_dict(self, state) -> None:
        if not state:
            return
        model = {k: v for k, v in self.p.items() if k != "train"}  # training settings do not change what is loaded
        trained = {**ADDED_KEYS, **{k: v for k, v in state["params"].items() if k != "train"}}  # a key added later: its default
        if trained != model:
            raise ValueError(f"gaps checkpoint was trained with {trained}, not {model}")
        if self.net is None:
            basis = None if self.p["output_basis"] == "dense" else torch.zeros(state["n_out"] // 3, self.p["basis_modes"])  # filled by the state
            self.net = GapsNet(state["n_in"], state["n_out"], self.p["hidden"], self.p["layers"], self.p["zero_init_output"], basis)
        self.net.load_state_dict(state["net"])
        dtype = state["weights"].dtype if self.body is None else self.body.dtype  # a float32 model runs in a float64 scene
        device = state["weights"].device if self.body is None else self.body.device  # a checkpoint is read onto the CPU
        self.net.to(device, dtype)
        self.weights = torch.nn.Parameter(state["weights"].clone().to(device, dtype), requires_grad=self.p["trainable_weights"])
        self.input_mean, self.input_std = state["input_mean"].to(device), state["input_std"].to(device)
        self.garment_key = state["garment_key"]
