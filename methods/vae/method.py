"""The VAE collision model (Santesteban et al., CVPR 2021): reference drapes projected to a canonical
(unposed, deshaped) space, a VAE of canonical garments trained with a self-supervised collision term, and
a GRU regressing its latent code from the motion; inference decodes the code and poses it with the
diffused body model. One model per garment, supervised by physics-based reference drapes. See
``methods/vae/README.md`` for the paper-to-code map and every choice the paper leaves open."""

from __future__ import annotations

import copy
import logging
import math
import time

import torch

from drapebench.cache import Cache, body_key, content_hash
from drapebench.train import Objective, combined_stop, train, train_config, write_logs
from methods.base import DrapeResult, DrapingMethod, FitReport
from methods.vae import losses
from methods.vae.config import vae_params
from methods.vae.descriptor import generated_poses, motion_descriptor, pose_rotations
from methods.vae.garment_model import pose_garments
from methods.vae.network import GarmentVAE, PoseDescriptor, Regressor
from methods.vae.projection import Projection, project_sequences

log = logging.getLogger("drapebench")
VAE_CACHE = Cache("vae", 1)  # canonical projections of the reference drapes ("projection_*") and trained VAEs ("vae_*")
POSE_CHUNK = 4  # frames posed per garment_model call in drape(): 135 frames at once run 2x slower per frame (7.7 vs 3.6 ms, tshirt)
POSE_SCHEDULE = dict(batch_size=256, lr=1.0e-3, lr_after=None, lr_switch_epoch=None, grad_clip=None, ema_decay=None,
                     lr_decay_fraction=0.3, checkpoint_every=500)  # fmt: skip


def _timed(timings: dict, name: str, fn, *args):
    t = time.perf_counter()
    out = fn(*args)
    if isinstance(out, torch.Tensor) and out.is_cuda:  # a GPU stage's time is its kernels', not their launch
        torch.cuda.synchronize(out.device)
    timings[name] = timings.get(name, 0.0) + (time.perf_counter() - t) * 1e3
    return out


class VAEModel(DrapingMethod):
    """The VAE collision model and its ablations (see the module docstring)."""

    name = "vae"
    generic = False
    needs_reference = True
    learns = True

    def __init__(self, cfg=None):
        super().__init__(cfg)
        self.p = vae_params(self.cfg)
        self.vae = self.regressor = self.pose = None
        self.diffused = self.sdf = None
        self.template = None
        self.evaluations: list[dict] = []
        self.regressor_stopped: list[str] = []  # how the pose descriptor's and the regressor's trainings stopped
        self.projection_stats: dict = {}

    # ------------------------------------------------------------------ shared pieces
    def settings_key(self) -> dict:
        """The resolved parameters and body-field settings (their code defaults included) the trained model depends on."""
        from drapebench.body import BODY_SDF_DEFAULTS, DIFFUSED_DEFAULTS

        return {**self.p, "diffused": {**DIFFUSED_DEFAULTS, **self.p["diffused"]}, "sdf": {**BODY_SDF_DEFAULTS, **self.p["sdf"]}}
    def _body_fields(self) -> None:
        """The diffused body model and the canonical body's learned SDF (fitted once per body, cached), on the
        body's device; fields already set are kept."""
        if self.diffused is None:
            from drapebench.body import fit_diffused_body

            self.diffused = fit_diffused_body(self.body, self.p["diffused"] or None).to(self.body.device)
        if self.sdf is None:
            from drapebench.body import fit_body_sdf

            self.sdf = fit_body_sdf(self.body, self.p["sdf"] or None).to(self.body.device)

    def _canonical_template(self, garment) -> torch.Tensor:
        """The garment template (V, 3) m moved to the mean body shape (the canonical space's), on the body's device."""
        X = garment.vertices.to(self.body.device, self.body.dtype)
        betas = self.body.full_betas(garment.betas)
        if bool((betas != 0).any()):
            with torch.no_grad():
                X = X - self.diffused.shape_offsets(X, betas[None].expand(len(X), -1))
        return X

    def _new_vae(self, n_vertices: int) -> GarmentVAE:
        v = self.p["vae"]
        return GarmentVAE(n_vertices, int(v["latent"]), v["hidden"], v["logvar_init"]).to(self.body.device, self.body.dtype)

    def _new_regressor(self, n_in: int) -> Regressor:
        r = self.p["regressor"]
        return Regressor(n_in, self.vae.latent, int(r["hidden"]), int(r["layers"]), float(r["dropout"])).to(self.body.device, self.body.dtype)

    def _pose_code(self):
        return None if self.pose is None else self.pose.code

    def _descriptor(self, seq) -> torch.Tensor:
        with torch.no_grad():
            r = self.p["regressor"]
            betas = self.body.full_betas(seq.betas)[: int(r["betas"])]
            return motion_descriptor(seq, betas, self._pose_code(), r["root"]).to(self.body.dtype)

    # ------------------------------------------------------------------ training
    def fit(self, data, train_cfg=None) -> FitReport:
        """Project the reference drapes of ``data`` (TrainData with references) to the canonical space, train
        the VAE on them, then the pose descriptor and the regressor; ``train_cfg`` is the shared budget
        (its ``log_dir`` gets ``vae/`` and ``regressor/``, each with ``losses.csv`` and ``evaluations.csv``)."""
        t0 = time.perf_counter()
        self.bind(data.body, data.material)
        garment = data.garment
        train_cfg = dict(train_cfg or {})
        log_dir = train_cfg.pop("log_dir", None)
        train_cfg.pop("dataset", None)  # the VAE trains on reference drapes (the data group), not a body dataset
        self._body_fields()
        self.topology = garment.topology.to(device=self.body.device)
        self.template = self._canonical_template(garment)
        seqs, X = self.training_garments(garment, data)
        train_idx, val_idx = self.validation_split(seqs)
        res = self._train_vae(X[train_idx].flatten(0, 1), X[val_idx].flatten(0, 1), train_cfg, log_dir)
        self.evaluations = res.evaluations
        history = [{"stage": "vae", **h} for h in res.history] + self.fit_regressor(seqs, X, train_cfg, log_dir)
        final = {k: v for k, v in history[-1].items() if k != "stage"} if history and history[-1]["stage"] == "regressor" else {}
        return FitReport(train_s=time.perf_counter() - t0, n_steps=len(history), final_losses=final, history=history,
                         evaluations=self.evaluations, stopped=combined_stop(res.stopped, *self.regressor_stopped))  # fmt: skip

    def validation_split(self, seqs) -> tuple[list[int], list[int]]:
        """Positions of the training and the validation sequences among ``seqs``: ``val_sequences`` of them held
        out, spread over the motion kinds (the last sequence of each kind in turn, then the second last...)."""
        n_val = int(self.p["val_sequences"])
        if not 1 <= n_val < len(seqs):
            raise ValueError(f"vae: val_sequences must be in [1, {len(seqs) - 1}] for {len(seqs)} reference sequences, got {n_val}")
        by_kind: dict[str, list[int]] = {}
        for i, seq in enumerate(seqs):
            by_kind.setdefault(seq.motion, []).append(i)
        turns = [positions[-k] for k in range(1, len(seqs) + 1) for positions in by_kind.values() if k <= len(positions)]
        val = sorted(turns[:n_val])
        return [i for i in range(len(seqs)) if i not in val], val

    def training_garments(self, garment, data) -> tuple[list, torch.Tensor]:
        """The training sequences of ``data`` that have a reference drape of ``garment`` and their canonical
        projections X (N, T, V, 3) m (cached by content); :meth:`validation_split` picks the validation set.
        Raises ValueError with fewer than 2."""
        seqs = [s for s in data.train_sequences if data.reference(garment, s) is not None]
        if len(seqs) < 2:
            raise ValueError(f"vae: {len(seqs)} reference drapes of {garment.name}; it needs at least 2 (one for validation): "
                             "build more with a larger data preset (data=cpu, data=paper)")  # fmt: skip
        return seqs, self._project(garment, seqs, [data.reference(garment, s) for s in seqs]).X

    def fit_regressor(self, seqs, X: torch.Tensor, train_cfg: dict, log_dir=None) -> list[dict]:
        """Train the pose descriptor (if learned) and the regressor on the trained VAE's posterior means of the
        canonical garments X (N, T, V, 3) m of ``seqs``, the :meth:`validation_split`'s sequences held out for
        validation; nothing with ``regressor.predict: mean_code``. Returns the training records, each with its
        ``stage`` (pose, regressor); ``regressor_stopped`` holds how each stage's training stopped ("time": cut
        by its budget's max_minutes)."""
        train_idx, val_idx = self.validation_split(seqs)
        self.regressor_stopped = []
        if self.p["regressor"]["predict"] == "mean_code":  # the control: nothing to train
            self.pose = self.regressor = None
            self._n_in = 0
            return []
        with torch.no_grad():  # (N - n_val, T, latent): the posterior means
            codes = torch.stack([self.vae.encode(X[i])[0] for i in train_idx])
        train_seqs = [seqs[i] for i in train_idx]
        history = []
        if self.p["regressor"]["pose"] == "learned":
            pose = self._train_pose(train_seqs, train_cfg)
            history += [{"stage": "pose", **h} for h in pose.history]
            self.regressor_stopped.append(pose.stopped)
        res = self._train_regressor(train_seqs, codes, train_cfg, log_dir, ([seqs[i] for i in val_idx], X[val_idx]))
        self.regressor_stopped.append(res.stopped)
        return history + [{"stage": "regressor", **h} for h in res.history]

    def _project(self, garment, seqs, drapes) -> Projection:
        """Canonical projections of the reference drapes (cached by content), sequences of one length at a time."""
        body, cfg = self.body, self.p["projection"]
        fields = self.settings_key()
        path = VAE_CACHE.path(cfg, fields["diffused"], fields["sdf"], body_key(body), garment.vertices, garment.faces,
                                [(s.betas, s.poses, s.trans, s.fps) for s in seqs], drapes, prefix="projection", suffix=".pt")  # fmt: skip
        hit = VAE_CACHE.load(path, lambda p: torch.load(p, map_location="cpu", weights_only=False))
        if hit is None:
            hit = [None] * len(seqs)
            for T in sorted({s.n_frames for s in seqs}):
                idx = [i for i, s in enumerate(seqs) if s.n_frames == T]
                with torch.no_grad():
                    A = torch.stack([seqs[i].transforms(body).to(body.dtype) for i in idx])
                betas = torch.stack([self.body.full_betas(seqs[i].betas) for i in idx])
                frames = torch.stack([drapes[i].to(body.device, body.dtype) for i in idx])  # reference drapes, read on the CPU
                p = project_sequences(self.diffused, self.sdf, garment.topology.to(device=body.device), self.template, frames, betas, A, cfg,
                                      desc=f"vae projection ({len(idx)} sequences)")  # fmt: skip
                for j, i in enumerate(idx):
                    hit[i] = Projection(p.X[j].cpu(), p.residual_mm[j].cpu(), p.colliding[j].cpu())
            VAE_CACHE.store(path, lambda tmp: torch.save(hit, tmp))  # on the CPU: a cache any device reads
        lengths = {p.X.shape[0] for p in hit}
        if len(lengths) > 1:
            raise ValueError(f"vae: reference sequences of different lengths {sorted(lengths)}; use one n_frames in the data preset")
        proj = Projection(torch.stack([p.X for p in hit]).to(body.device), torch.stack([p.residual_mm for p in hit]), torch.stack([p.colliding for p in hit]))
        self.projection_stats = {"residual_mm": float(proj.residual_mm.mean()), "residual_mm_max": float(proj.residual_mm.max()),
                                 "canonical_colliding_pct": 100 * float(proj.colliding.mean()),
                                 "canonical_colliding_max_pct": 100 * float(proj.colliding.max())}  # fmt: skip
        log.info("vae: projected %d frames: residual %.2f mm (max %.2f), %.3f %% of vertices inside the canonical body (max %.3f)",
                 proj.X.shape[0] * proj.X.shape[1], *self.projection_stats.values())  # fmt: skip
        return proj

    def _budget(self, train_cfg: dict, schedule: dict, steps=None):
        cfg = {**train_cfg, **schedule}
        if steps is not None:
            cfg["steps"] = int(steps)
        return train_config(cfg)

    def _train_vae(self, X: torch.Tensor, X_val: torch.Tensor, train_cfg: dict, log_dir):
        """Train the VAE (Eq. 13) on canonical garments X (N, V, 3); the per-epoch evaluation is Fig. 4's
        (the % of vertices of the validation reconstructions and of decoded latent samples inside the canonical
        body, :meth:`_latent_evaluation`) with the latent statistics. Sets the VAE's ``code_mean``, ``code_std``."""
        v, eps = self.p["vae"], self.p["projection"]["eps"]
        budget = self._budget(train_cfg, v["schedule"], v["steps"])
        torch.manual_seed(budget.seed)
        self.vae = self._new_vae(X.shape[1])
        with torch.no_grad():
            self.vae.mean.copy_(X.mean(0))
            self.vae.scale.copy_((X - X.mean(0)).std().clamp_min(1e-4))
        gen = torch.Generator().manual_seed(budget.seed)
        total = budget.steps if budget.steps is not None else -(-len(X) // budget.batch_size) * int(budget.epochs)
        warmup = float(v["kl_warmup"]) * total

        def terms(b, at):
            kl_factor = min(1.0, at.step / warmup) if warmup > 0 else 1.0
            return losses.vae_terms(self.vae, self.sdf, self.topology, b, v, eps, gen, kl_factor)

        key = content_hash(self.p["vae"], eps, budget, X, self.template, "vae")
        fields = self.settings_key()  # the collision terms' SDF is the body's, fitted with these settings
        path = VAE_CACHE.path(key, X_val, fields["sdf"], body_key(self.body), prefix="vae", suffix=".pt")  # shared by the variants that differ after it
        hit = VAE_CACHE.load(path, lambda q: torch.load(q, map_location="cpu", weights_only=False))
        if hit is not None:
            self.vae.load_state_dict(hit["state"])
            log.info("vae: the trained VAE loaded from %s (its settings, budget and data are this run's)", path)
            if log_dir is not None:
                write_logs(f"{log_dir}/vae", hit["result"].history, hit["result"].evaluations)
            return hit["result"]
        objective = Objective("vae", [{"params": list(self.vae.parameters()), "lr_factor": 1.0}], len(X),
                              lambda idx, at: X[torch.as_tensor(idx, device=X.device)], terms, key,
                              lambda: self._latent_evaluation(X, X_val))  # fmt: skip
        res = train(objective, budget, log_dir=None if log_dir is None else f"{log_dir}/vae")
        with torch.no_grad():
            mu = self.vae.encode(X)[0]
            self.vae.code_mean.copy_(mu.mean(0))
            self.vae.code_std.copy_(mu.std(0))
        state = {k: v.cpu() for k, v in self.vae.state_dict().items()}
        VAE_CACHE.store(path, lambda tmp: torch.save({"state": state, "result": res}, tmp))
        return res

    def _latent_evaluation(self, X: torch.Tensor, X_val: torch.Tensor) -> dict:
        """Per-epoch record of the VAE on training garments X and validation garments X_val (N, V, 3):
        validation reconstruction error (mm) and % of its vertices inside the canonical body (learned SDF < 0);
        the % for 256 decoded codes z ~ N(0, I) and z ~ N(m, diag(s^2)) with m, s the training codes' mean and
        std per dimension; median posterior sigma, mean per-dimension std s and mean norm of the training codes,
        and KL per training garment (nats)."""
        with torch.no_grad():
            mu, logvar = self.vae.encode(X)
            Y = self.vae.decode(self.vae.encode(X_val)[0])
            noise = losses.normal_noise((256, self.vae.latent), X, torch.Generator().manual_seed(1))
            spread = mu.mean(0) + mu.std(0) * noise

            def inside_pct(G):
                return 100 * float((self.sdf(G) < 0).to(X.dtype).mean())

            return {"val_colliding_pct": inside_pct(Y), "val_error_mm": 1e3 * float((Y - X_val).norm(dim=-1).mean()),
                    "sampled_colliding_pct": inside_pct(self.vae.decode(noise)),
                    "sampled_codes_colliding_pct": inside_pct(self.vae.decode(spread)),
                    "posterior_sigma": float(torch.exp(0.5 * logvar).median()), "code_std": float(mu.std(0).mean()),
                    "code_norm": float(mu.norm(dim=-1).mean()), "kl_per_sample": float(losses.kl_divergence(mu, logvar).mean())}  # fmt: skip

    def _train_pose(self, seqs, train_cfg: dict):
        """Train the learned pose descriptor (an autoencoder of the non-root rotations of the training poses and of
        ``regressor.pose_sequences`` generated sequences per motion kind of the training sequences)."""
        r = self.p["regressor"]
        budget = self._budget(train_cfg, POSE_SCHEDULE, r["pose_steps"])
        torch.manual_seed(budget.seed)
        self.pose = PoseDescriptor(self.body.n_joints, int(r["pose_code"])).to(self.body.device, self.body.dtype)
        first = seqs[0]
        generated = generated_poses([s.motion for s in seqs], int(r["pose_sequences"]), len(first.poses) - int(first.n_transition),
                                    int(first.n_transition), float(first.fps))  # fmt: skip
        R = pose_rotations(torch.cat([*(s.poses for s in seqs), generated]).to(self.body.device, self.body.dtype))  # moved once
        key = content_hash(r["pose_code"], budget, R, "pose")

        def terms(b, at):
            return {"reconstruction": (self.pose(b) - b.flatten(-3)).square().mean()}

        objective = Objective("vae_pose", [{"params": list(self.pose.parameters()), "lr_factor": 1.0}], len(R),
                              lambda idx, at: R[torch.as_tensor(idx, device=R.device)], terms, key)  # fmt: skip
        res = train(objective, budget)
        for q in self.pose.parameters():
            q.requires_grad_(False)
        return res

    def _train_regressor(self, seqs, codes: torch.Tensor, train_cfg: dict, log_dir, validation=None):
        """Train the GRU regressor (Eq. 18) on windows of the training sequences' descriptors and latent codes
        (N, T, latent). ``validation`` (sequences, their canonical reference garments (M, T, V, 3) m) is scored
        after every epoch: the mean vertex distance (mm) of the decoded regressed codes to those garments
        (``regressor/evaluations.csv``); with ``regressor.select: validation`` the weights of the epoch that
        scored lowest are kept, else the last epoch's."""
        r = self.p["regressor"]
        budget = self._budget(train_cfg, r["schedule"])
        desc = torch.stack([self._descriptor(s) for s in seqs])  # (N, T, D)
        self._n_in = desc.shape[-1]
        torch.manual_seed(budget.seed)
        self.regressor = self._new_regressor(self._n_in)
        with torch.no_grad():
            flat = desc.flatten(0, 1)
            self.regressor.input_mean.copy_(flat.mean(0))
            self.regressor.input_std.copy_(flat.std(0).clamp_min(1e-6))
        T, W = desc.shape[1], min(int(r["window"]), desc.shape[1])
        starts = [(n, s) for n in range(len(seqs)) for s in range(0, T - W + 1, int(r["window_stride"]))]

        def batch(idx, at):
            rows = [starts[i] for i in idx]
            return (torch.stack([desc[n, s : s + W] for n, s in rows]), torch.stack([codes[n, s : s + W] for n, s in rows]))

        evaluate, best = None, {"error": math.inf, "state": None, "epoch": None}
        if validation is not None and len(validation[0]):
            val_desc = [self._descriptor(s)[None] for s in validation[0]]

            def evaluate():
                decoded = [self.vae.decode(self.regressor.eval()(d)[0][0]) for d in val_desc]
                error = 1e3 * float(torch.stack([(x - X).norm(dim=-1).mean() for x, X in zip(decoded, validation[1])]).mean())
                if error < best["error"]:
                    best.update(error=error, state=copy.deepcopy(self.regressor.state_dict()), epoch=len(best.get("errors", [])))
                best.setdefault("errors", []).append(error)
                return {"val_error_mm": error}

        key = content_hash(r, budget, desc, codes, None if validation is None else validation[1], "regressor")
        group = {"params": list(self.regressor.parameters()), "lr_factor": 1.0, "weight_decay": float(r["weight_decay"])}
        objective = Objective("vae_regressor", [group], len(starts),
                              batch, lambda b, at: losses.regressor_terms(self.regressor.train()(b[0])[0], b[1], r), key, evaluate)  # fmt: skip
        res = train(objective, budget, log_dir=None if log_dir is None else f"{log_dir}/regressor")
        self.regressor.eval()  # dropout off from here on
        if r["select"] == "validation" and best["state"] is not None:
            self.regressor.load_state_dict(best["state"])
            log.info("vae regressor: kept epoch %d of %d (validation garments %.2f mm from the decoded codes; last epoch %.2f mm)", best["epoch"] + 1,
                     len(best["errors"]), best["error"], best["errors"][-1])  # fmt: skip
        return res

    # ------------------------------------------------------------------ inference
    def drape(self, garment, seq) -> DrapeResult:
        """Regress the latent code per frame (``regressor.predict: mean_code``: the training codes' mean), decode it
        to the canonical garment and pose it with the diffused body."""
        self._require_bound()
        mean_code = self.p["regressor"]["predict"] == "mean_code"
        if self.vae is None or (self.regressor is None and not mean_code):
            raise RuntimeError("vae: call fit(data) or load_state_dict(...) before drape()")
        if garment.n_vertices != self.template.shape[0]:
            raise ValueError(f"vae model was trained for a garment of {self.template.shape[0]} vertices, "
                             f"got {garment.name} with {garment.n_vertices}; train one per garment")  # fmt: skip
        timings: dict[str, float] = {}
        body = self.body
        with torch.no_grad():
            if mean_code:
                z = self.vae.code_mean.expand(len(seq.poses), -1)
            else:
                desc = _timed(timings, "descriptor", self._descriptor, seq)
                z = _timed(timings, "regressor", lambda: self.regressor(desc[None])[0][0])
            X = _timed(timings, "decoder", self.vae.decode, z)
            A = _timed(timings, "body", lambda: seq.transforms(body).to(body.dtype))
            betas = self.body.full_betas(seq.betas)
            x = _timed(timings, "projection", lambda: torch.cat([pose_garments(self.diffused, X[i : i + POSE_CHUNK], betas, A[i : i + POSE_CHUNK])
                                                                 for i in range(0, len(X), POSE_CHUNK)]))  # fmt: skip
        return DrapeResult(x, timings, {"canonical": X})

    def diagnostics(self, garment, seq, result: DrapeResult) -> dict:
        """Collisions in the canonical space, apart from posing: ``eps_c_canonical`` (and ``_std`` over frames), the
        % of the drape's decoded canonical garments' vertices inside the canonical body (the mean shape in the rest
        pose; mesh winding number; over the frames after the transition, as eps_c); ``sampled_prior_pct``, ``sampled_prior3_pct`` and
        ``sampled_codes_pct``, the same for 256 decoded codes z ~ N(0, I), N(0, 9 I) and N(m, diag(s^2)) (m, s the
        training codes' mean and std per dimension), fixed draws."""
        from drapebench.geometry.sdf import inside_body

        body = self.body.shaped()[0][0][None]

        def inside_pct(G: torch.Tensor) -> torch.Tensor:
            return 100 * inside_body(G.reshape(1, -1, 3), body, self.body.faces).reshape(G.shape[:2]).to(G.dtype).mean(-1)

        out = {}
        with torch.no_grad():
            if "canonical" in result.extras:
                per_frame = inside_pct(result.extras["canonical"][int(seq.n_transition) :])
                out = {"eps_c_canonical": float(per_frame.mean()), "eps_c_canonical_std": float(per_frame.std(unbiased=False))}
            noise = losses.normal_noise((256, self.vae.latent), self.vae.code_mean, torch.Generator().manual_seed(1))
            codes = {"prior": noise, "prior3": 3 * noise, "codes": self.vae.code_mean + self.vae.code_std * noise}
            out.update({f"sampled_{k}_pct": float(inside_pct(self.vae.decode(z)).mean()) for k, z in codes.items()})
        return out

    # ------------------------------------------------------------------ state
    def state_dict(self) -> dict:
        return {"vae": self.vae.state_dict(), "regressor": None if self.regressor is None else self.regressor.state_dict(),
                "pose": None if self.pose is None else self.pose.state_dict(),
                "n_vertices": self.template.shape[0], "n_in": self._n_in, "template": self.template,
                "evaluations": self.evaluations, "projection_stats": self.projection_stats}  # fmt: skip

    def load_state_dict(self, state) -> None:
        self._require_bound()
        self._body_fields()
        self.template = state["template"].to(self.body.device, self.body.dtype)
        self.vae = self._new_vae(int(state["n_vertices"]))
        self.vae.load_state_dict(state["vae"])
        r = self.p["regressor"]
        self.pose = None
        if state["pose"] is not None:
            self.pose = PoseDescriptor(self.body.n_joints, int(r["pose_code"])).to(self.body.device, self.body.dtype)
            self.pose.load_state_dict(state["pose"])
        self._n_in = int(state["n_in"])
        self.regressor = None
        if state["regressor"] is not None:
            self.regressor = self._new_regressor(self._n_in).eval()
            self.regressor.load_state_dict(state["regressor"])
        self.evaluations, self.projection_stats = list(state["evaluations"]), dict(state["projection_stats"])
