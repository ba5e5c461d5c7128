"""Print what GAPS's training loss sees: on a batch of training windows, every weighted term, its value and
its gradient per vertex (N), at the untrained skinning (network output zero); or, with ``--run``, the terms
of a trained run's drape beside its untrained skinning's and those of the parts of its network's output (the
static part, the part that varies with the motion, the output smoothed over each 1-ring), with the output's
size and roughness and how saturated its GRU trunk is, on the run's test sequence (or, with
``--training-motion``, on the first training sequence of that motion, at the run's body shape; with
``--optimum``, beside the drape of a ``gaps_optimum`` run of the same scene); or, with ``--pinned`` and a
``gaps_optimum`` run, how far from the run's reference its untrained skinning, its optimum and the optimum
with the garment's pins held where the reference holds them are, at the pins and elsewhere (whether a pin
term would close the gap); or, with ``--losses``, a training run's gradient norms and how often its clip binds.

    python -m methods.gaps.diagnose --garment tshirt --body anny_lowres             # train=cpu's GAPS keys
    python -m methods.gaps.diagnose --garment tshirt --budget paper --epoch 100 --windows 16
    python -m methods.gaps.diagnose --run multirun/<date>/<sweep>/<run> [--training-motion dance | --optimum <gaps_optimum run>]
    python -m methods.gaps.diagnose --run multirun/<date>/<sweep>/<gaps_optimum run> --pinned [--frames 40]
    python -m methods.gaps.diagnose --losses <run>/losses.csv --clip 20       # gradient norms, the clip's binding rate
"""

from __future__ import annotations

import argparse

import numpy as np
import pandas as pd
import torch
from omegaconf import OmegaConf

import methods
from drapebench.body import load_body
from drapebench.body.dataset import build_dataset
from drapebench.body.lbs import lbs
from drapebench.cache import PROJECT_ROOT
from drapebench.data import H5Sequences, TrainData
from drapebench.diagnose import term_table
from drapebench.geometry.ops import ring_mean
from drapebench.garments import make_garment
from drapebench.physics import Material
from drapebench.train.trainer import Step


def budget_params(budget: str) -> dict:
    """GAPS's ``method.params`` under a training preset: conf/method/gaps.yaml's params with the preset's
    conf/method/gaps_budget/<budget>.yaml (if any) as its ``train`` keys (the rest: GapsTrain's defaults)."""
    base = OmegaConf.to_container(OmegaConf.load(PROJECT_ROOT / "conf/method/gaps.yaml"))["params"]
    path = PROJECT_ROOT / f"conf/method/gaps_budget/{budget}.yaml"
    if path.exists():
        base.setdefault("train", {}).update(OmegaConf.to_container(OmegaConf.load(path)))
    return base


def diagnose(garment: str, body: str, budget: str = "cpu", epoch: int | None = None, windows: int = 8, seed: int = 0) -> pd.DataFrame:
    """The term table (:func:`drapebench.diagnose.term_table`) of GAPS's loss on ``windows`` random training
    windows of the budget's dataset (random shapes as in training) at the untrained skinning, k_ext at ``epoch``
    (None: the end of the budget's ramp), and each term's gradient on the network's parameter groups there
    (:func:`parameter_gradients`)."""
    params = budget_params(budget)
    params.setdefault("train", {})["schedule"] = {}  # no step is taken: the budget's rates and epochs do not matter
    m = methods.get("gaps")(params)
    b = load_body(body)
    g = make_garment(garment, b)
    dataset = OmegaConf.load(PROJECT_ROOT / f"conf/train/{budget}.yaml").dataset
    data = TrainData(body=b, material=Material(), garment=g, load_train=lambda: H5Sequences(build_dataset(dataset)))
    m.fit(data, {"epochs": 0, "seed": seed, "dataset": dataset})  # the model's constants and training windows, no step
    at = Step(0, m.p["train"]["kext_ramp_epochs"] if epoch is None else epoch, np.random.default_rng(seed))
    betas, pose, vel, tr, out, normals = m._batch(at.rng.choice(len(m._windows), windows, replace=False), at)
    W = m.p["train"]["window"]
    with torch.no_grad():
        delta = torch.zeros(len(betas), W, 3 * g.n_vertices, dtype=b.dtype)
        x = lbs(m._canonical(delta, betas).reshape(len(betas) * W, -1, 3), m.weights, out.transforms)
    return term_table(lambda y: m._terms(y, out.vertices, normals, at.epoch), x), parameter_gradients(m, (betas, pose, vel, tr, out, normals), at)


def parameter_gradients(m, batch, at) -> pd.DataFrame:
    """Per weighted loss term of GAPS (and their sum) on ``batch`` at the network's current weights: the norm of its
    gradient on each parameter group the trainer clips together (``trunk``: the GRU, ``output``: the output layer)
    and on both, the global norm ``train.grad_clip`` is compared with (units: the term's, J, per unit weight)."""
    groups = {"trunk": list(m.net.gru.parameters()), "output": list(m.net.out.parameters())}
    terms = m._loss_terms(batch, at)
    rows = []
    for name, value in {**terms, "total": sum(terms.values())}.items():
        grads = torch.autograd.grad(value, [q for g in groups.values() for q in g], retain_graph=True, allow_unused=True)
        norms, i = {}, 0
        for g, params in groups.items():
            gs = [x for x in grads[i : i + len(params)] if x is not None]
            norms[g] = float(torch.linalg.vector_norm(torch.stack([x.norm() for x in gs]))) if gs else 0.0
            i += len(params)
        rows.append({"term": name, "value": float(value.detach()), **{f"|d/d {g}|": v for g, v in norms.items()},
                     "|d/d all|": float(np.hypot(*norms.values()))})  # fmt: skip
    return pd.DataFrame(rows)


CLIP_COLUMNS = ("grad_norm", "grad_norm_trunk", "grad_norm_output")  # drapebench.train's per-step norms before clipping


def clip_table(losses_csv, clip: float | None) -> pd.DataFrame:
    """The global gradient norm of every training step in a run's ``losses.csv`` and its two groups' (before
    clipping): quantiles over the steps and, for the global norm, the share of steps a clip at ``clip`` scales down
    (its binding rate). A clip set from these quantiles (e.g. the 90th percentile of an unclipped run) binds on a
    minority of steps."""
    df = pd.read_csv(losses_csv)
    rows = []
    for col in (c for c in CLIP_COLUMNS if c in df):
        q = df[col].quantile([0.1, 0.5, 0.9, 0.99])
        binding = float((df[col] > clip).mean()) if clip and col == "grad_norm" else float("nan")
        rows.append({"norm": col, "p10": q[0.1], "p50": q[0.5], "p90": q[0.9], "p99": q[0.99], "max": df[col].max(), "clipped share": binding})
    return pd.DataFrame(rows)


SMOOTHING_ROUNDS = 3  # rounds of averaging the output with its 1-ring in the "smoothed" drape


def output_parts(m, seq) -> tuple[dict, dict]:
    """The trained network's canonical displacements D (T, V, 3) on ``seq`` taken apart, over the frames after
    the transition: statistics in mm (mean |D|; |S| of its time mean S, the static part; |D - S|, the part
    that varies with the motion; roughness |D - ring mean of D|, what a vertex does apart from its 1-ring) and
    drapes (T, V, 3) m of the static part alone, the varying part alone and D averaged with its 1-ring
    ``SMOOTHING_ROUNDS`` times (each round x <- (x + ring mean of x) / 2)."""
    T, start = seq.n_frames, int(seq.n_transition)
    delta = m.displacements(seq)[0].reshape(T, -1, 3)
    static = delta[start:].mean(0, keepdim=True).expand_as(delta)
    smooth = delta
    for _ in range(SMOOTHING_ROUNDS):
        smooth = 0.5 * (smooth + ring_mean(smooth, m.topology))
    mm = lambda d: 1e3 * float(d[start:].norm(dim=-1).mean())  # noqa: E731
    stats = {"mean |D| (mm)": mm(delta), "static |S| (mm)": mm(static), "varying |D - S| (mm)": mm(delta - static),
             "roughness (mm)": mm(delta - ring_mean(delta, m.topology))}  # fmt: skip
    betas = m._sequence_betas(seq)
    parts = {"static part": static, "varying part": delta - static, f"smoothed x{SMOOTHING_ROUNDS}": smooth}
    with torch.no_grad():
        return stats, {name: m.skinned(d.reshape(1, T, -1), betas, seq) for name, d in parts.items()}


def canonical_offsets(m, seq, x: torch.Tensor) -> torch.Tensor:
    """(T, V, 3) m: the canonical displacements D whose skinning on ``seq`` is the drape x (T, V, 3) m, i.e.
    ``m.skinned(D) == x``: x minus the untrained skinning, mapped back through each vertex's blended rotation
    (T, V, 3, 3) (skinning is affine in the canonical point). Raises ValueError where a blended rotation is
    singular (a skinning weight row far from a partition of unity)."""
    rot = torch.einsum("vj,tjab->tvab", m.weights.detach().to(x.dtype), seq.transforms(m.body)[..., :3, :3].to(x.dtype))
    d, info = torch.linalg.solve_ex(rot, (x - m.untrained_drape(seq).to(x.dtype))[..., None])
    if bool((info != 0).any()):
        raise ValueError("a vertex's blended skinning rotation is singular: the drape cannot be mapped back to canonical space")
    return d[..., 0]


def static_and_varying(m, seq, x: torch.Tensor) -> dict:
    """Drape x (T, V, 3) m taken apart in canonical space (:func:`canonical_offsets`) into its time mean over
    the frames after the transition (a correction that depends on the body shape only, as a network could learn
    it from other motions) and the rest (what depends on this motion): {"static part": drape, "varying part":
    drape}, each the untrained skinning plus that part."""
    d = canonical_offsets(m, seq, x)
    static = d[int(seq.n_transition) :].mean(0, keepdim=True).expand_as(d)
    betas, T = m._sequence_betas(seq), seq.n_frames
    with torch.no_grad():
        return {name: m.skinned(part.reshape(1, T, -1), betas, seq) for name, part in (("static part", static), ("varying part", d - static))}


SATURATED = 0.99  # a GRU output unit with |y| above this is saturated (tanh's slope below 0.02)


def trunk_state(m, seq) -> dict:
    """What the output layer sees on ``seq``: the last GRU layer's outputs y (T, H) over the frames after the
    transition (GRU state zero, as at inference): mean |y|, the fraction of saturated units (|y| >
    ``SATURATED``), y's std over the frames (mean over units) and the std over the frames of the output
    layer's W y in mm (mean over coordinates). A saturated trunk feeds the output layer a near-constant
    vector, so the network's output hardly varies with the motion or the body shape."""
    with torch.no_grad():
        y = m.net.gru(m.sequence_inputs(seq))[0][0, int(seq.n_transition) :]
        wy = m.net.displacements(y)  # the output layer's W y (and its bias, constant over the frames)
    return {"mean |y|": float(y.abs().mean()), "saturated": float((y.abs() > SATURATED).to(y.dtype).mean()),
            "std over frames of y": float(y.std(0).mean()), "std over frames of W y (mm)": 1e3 * float(wy.std(0).mean())}  # fmt: skip


def pinned_optimum(run_dir, n_frames: int | None = None, weight: float = 1e5) -> pd.DataFrame:
    """Distance (mm) to the reference of a ``gaps_optimum`` run's untrained skinning, of its optimum (read from
    the run's prediction.h5) and of GAPS's loss minimised with the garment's pins held at the reference's pin
    positions (a penalty ``weight`` x |x_pin - reference_pin|^2, J per m^2), over the run's first ``n_frames``
    frames (None: all) after the transition: one row each, the mean over all vertices, the pins and the rest."""
    from drapebench.optimum import optimise_sequence
    from drapebench.results import read_prediction
    from drapebench.trained_run import load_run

    run = load_run(run_dir)
    m, g, seq = run.method, run.garment, run.seq
    if m.name != "gaps_optimum":
        raise ValueError(f"--pinned reads a gaps_optimum run, not a {m.name} run ({run_dir})")
    reference = run.reference()
    if reference is None:
        raise ValueError(f"{run_dir} has no reference drape (reference=none); rerun it with reference=vbd")
    T = seq.n_frames if n_frames is None else min(int(n_frames), seq.n_frames)
    m._setup(g)
    start = m.untrained_drape(seq)[:T]
    reference = reference[:T].to(start.dtype)
    optimum = torch.as_tensor(read_prediction(f"{run_dir}/prediction.h5")[0][:T]).to(start.dtype)
    pins = g.pins.long()
    base = m.window_loss(seq, m.kext_epoch())

    def pinned_loss(t: int, window: torch.Tensor):
        value, terms = base(t, window)
        pin = weight * (window[-1, pins] - reference[t, pins]).pow(2).sum()
        return value + pin, {**terms, "pin": pin}

    o = m.o
    pinned = optimise_sequence(pinned_loss, start, m.p["train"]["window"], o["solver"], o["iterations"], o["lr"], o["history"]).vertices
    free = torch.ones(g.n_vertices, dtype=torch.bool)
    free[pins] = False
    first = min(int(seq.n_transition), T - 1)
    rows = []
    for name, x in (("untrained", start), ("optimum", optimum), ("optimum, pins at the reference's", pinned)):
        d = (x[first:] - reference[first:]).norm(dim=-1) * 1e3
        rows.append({"drape": name, "all (mm)": float(d.mean()), "pins (mm)": float(d[:, pins].mean()), "rest (mm)": float(d[:, free].mean())})
    return pd.DataFrame(rows)


def run_terms(run_dir, training_motion: str | None = None, optimum_run=None) -> tuple[pd.DataFrame, dict, dict]:
    """GAPS's loss terms (its weights and normalisation, k_ext at the end of the ramp; mean per frame over the
    frames after the transition) of a gaps run's trained drape, of its untrained skinning and of the parts of
    the network's output (:func:`output_parts`), one row each, on the run's test sequence or, with
    ``training_motion``, on the first ``train_small`` sequence of that motion with the run's body shape, with
    rows for the drape of ``optimum_run`` (a ``gaps_optimum`` run of the same scene) if given and for its
    static and varying parts (:func:`static_and_varying`); on the test sequence, each drape's distance to the
    run's reference (``error (mm)``, mean over the frames after the transition, as the vertex error); the output's
    statistics; and :func:`trunk_state`. A trained drape whose total is above the untrained one's is worse by
    GAPS's own objective."""
    import dataclasses

    from drapebench.optimum import sequence_terms
    from drapebench.results import read_prediction
    from drapebench.trained_run import load_run

    run = load_run(run_dir)
    m, seq = run.method, run.seq
    if training_motion is not None:
        dataset = list(H5Sequences(build_dataset("train_small")))
        train = [s for s in dataset if s.motion == training_motion]
        if not train:
            raise ValueError(f"train_small has no {training_motion!r} sequence; its motions: {sorted({s.motion for s in dataset})}")
        seq = dataclasses.replace(train[0], betas=seq.betas, _cache={})
    drapes = {"trained": m.drape(run.garment, seq).vertices, "untrained": m.untrained_drape(seq)}
    if optimum_run is not None:
        if training_motion is not None:
            raise ValueError("--optimum scores the run's own test sequence; leave out --training-motion")
        optimum = torch.as_tensor(read_prediction(f"{optimum_run}/prediction.h5")[0]).to(drapes["trained"].dtype)
        if optimum.shape != drapes["trained"].shape:
            raise ValueError(f"{optimum_run}'s drape {tuple(optimum.shape)} is not of {run_dir}'s scene {tuple(drapes['trained'].shape)}")
        drapes["loss optimum"] = optimum
        drapes.update({f"loss optimum, {k}": v for k, v in static_and_varying(m, seq, optimum).items()})
    stats, parts = output_parts(m, seq)
    drapes.update(parts)
    loss, start = m.window_loss(seq, m.p["train"]["kext_ramp_epochs"]), int(seq.n_transition)
    reference = run.reference() if training_motion is None else None
    rows = []
    for name, x in drapes.items():
        terms = pd.DataFrame(sequence_terms(loss, x, m.p["train"]["window"])[start:]).mean()
        error = {} if reference is None else {"error (mm)": 1e3 * float((x[start:] - reference[start:].to(x.dtype)).norm(dim=-1).mean())}
        rows.append({"drape": name, "sequence": seq.name, **error, "total": terms.sum(), **terms.to_dict()})
    return pd.DataFrame(rows), stats, trunk_state(m, seq)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0], formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    ap.add_argument("--garment", default="tshirt")
    ap.add_argument("--body", default="anny_lowres")
    ap.add_argument("--budget", default="cpu", help="training preset whose GAPS keys apply (conf/method/gaps_budget/)")
    ap.add_argument("--epoch", type=int, default=None, help="epoch of k_ext (default: the end of the ramp)")
    ap.add_argument("--windows", type=int, default=8, help="training windows in the batch")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--run", help="a gaps run folder: its trained drape's terms beside its untrained skinning's")
    ap.add_argument("--training-motion", help="with --run: score the first train_small sequence of this motion instead")
    ap.add_argument("--optimum", help="with --run: a gaps_optimum run of the same scene, whose drape's terms are added")
    ap.add_argument("--pinned", action="store_true", help="with a gaps_optimum --run: its optimum with the pins held at the reference's")
    ap.add_argument("--frames", type=int, default=None, help="with --pinned: the first N frames only (default: all)")
    ap.add_argument("--losses", help="a run's losses.csv: its gradient norms' quantiles and the clip's binding rate")
    ap.add_argument("--clip", type=float, default=None, help="with --losses: the global clip whose binding rate is printed")
    a = ap.parse_args(argv)
    torch.set_num_threads(1)
    if a.run and a.pinned:
        print("Distance to the reference (mm) over the frames after the transition: all vertices, the pins, the rest")
        print(pinned_optimum(a.run, a.frames).to_string(index=False, float_format=lambda v: f"{v:.2f}"))
        return
    if a.run:
        table, stats, trunk = run_terms(a.run, a.training_motion, a.optimum)
        print("GAPS loss terms per frame (J per frame as the training normalises them), k_ext at the end of the ramp")
        print(table.to_string(index=False, float_format=lambda v: f"{v:.4g}"))
        print("The network's canonical displacements D: " + ", ".join(f"{k} {v:.2f}" for k, v in stats.items()))
        print("Its last GRU layer's outputs y: " + ", ".join(f"{k} {v:.3g}" for k, v in trunk.items()))
        return
    if a.losses:
        print(f"Gradient norms over the steps of {a.losses} (before clipping) and the share of steps a clip at {a.clip} scales down")
        print(clip_table(a.losses, a.clip).to_string(index=False, float_format=lambda v: f"{v:.4g}"))
        return
    table, grads = diagnose(a.garment, a.body, a.budget, a.epoch, a.windows, a.seed)
    print(f"GAPS loss terms on {a.windows} training windows, {a.garment} on {a.body}, budget {a.budget}, untrained skinning")
    print("value: per the budget's normalisation (the code: J per frame; collision and inertia per window); grad_*: norm of d term / d x per vertex and frame drape, N")
    print(table.to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    print("Each term's gradient on the network's weights (what train.grad_clip bounds), at its initial weights")
    print(grads.to_string(index=False, float_format=lambda v: f"{v:.4g}"))


if __name__ == "__main__":
    main()
