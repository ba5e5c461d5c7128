"""Where a VAE run's distance from the reference comes from, on its own test scene.

Run: python -m methods.vae.diagnose <run directory of a vae run> [...]

Per run (its config.yaml and checkpoint), the mean vertex distance to the reference drape (mm, frames after the
transition) of: ``regressed``, the drape (regressor -> decoder -> posing); ``oracle code``, the decoder's output for
the encoder's posterior mean of the reference's own canonical projection, posed (the best drape the regressor
could ask of this decoder); ``mean code``, the training codes' mean decoded and posed at every frame (the
regressor's control, run as ``method=vae_mean_code``); ``canonical``, the reference's canonical projection posed
again (what the canonical space itself costs). ``code gap`` is the distance between the regressed and the oracle codes in units of the
training codes' std per dimension (RMS over dimensions, mean over frames): a large gap with a small oracle error
puts the error in the regressor. A second line gives each drape's strain, eps_e (%, the mean relative edge-length
change against the template, frames after the transition, as the metrics compute it), beside the reference's own:
where the regressed drape's strain comes from (the data, the canonical space, the decoder or the regressor).

With ``--terms N``: Eq. 13's weighted terms on N projected training garments and each term's gradient norm over the
VAE's weights (which term drives the decoder). With ``--retrain '<json of regressor keys>' --seeds 100,101``: the run's pose descriptor and regressor trained
again (its VAE and data kept) with those ``method.params.regressor`` keys and each training seed, and the
regressed drape's distance printed per seed (the measurements of reports/history.md, "Regressor training").
"""

from __future__ import annotations

import argparse
from pathlib import Path

import torch

from drapebench.geometry.ops import edge_lengths
from drapebench.trained_run import load_run
from methods.vae.garment_model import pose_garments
from methods.vae.method import POSE_CHUNK


def _posed(method, X: torch.Tensor, seq) -> torch.Tensor:
    """Canonical garments X (T, V, 3) posed on ``seq`` (T, V, 3), m."""
    A = seq.transforms(method.body).to(method.body.dtype)
    betas = method.body.full_betas(seq.betas)
    return torch.cat([pose_garments(method.diffused, X[i : i + POSE_CHUNK], betas, A[i : i + POSE_CHUNK]) for i in range(0, len(X), POSE_CHUNK)])


def diagnose(run_dir: Path) -> dict[str, dict[str, float]]:
    """The numbers of the module docstring for the vae run in ``run_dir`` (its checkpoint must still be in the cache):
    {"error": {row: mm, "code gap": std}, "eps_e": {row: %, "reference": %}}."""
    run = load_run(run_dir)
    m, seq = run.method, run.seq
    reference = run.reference()
    if reference is None:
        raise ValueError(f"{run_dir}: the run has no reference drape (reference.solver is null)")
    start = int(seq.n_transition)
    topo = run.garment.topology
    error = lambda x: float((x[start:] - reference[start:]).norm(dim=-1).mean() * 1e3)  # noqa: E731
    strain = lambda x: float(((edge_lengths(x[start:], topo.edges) - topo.rest_edge_lengths).abs() / topo.rest_edge_lengths).mean() * 100)  # noqa: E731
    X = m._project(run.garment, [seq], [reference]).X[0]  # an optimisation per frame (cached by content)
    with torch.no_grad():
        oracle, _ = m.vae.encode(X)
        regressed = m.regressor(m._descriptor(seq)[None])[0][0]
        gap = ((regressed - oracle) / m.vae.code_std).pow(2).mean(-1).sqrt()[start:].mean()
        mean_code = m.vae.decode(m.vae.code_mean.expand(len(X), -1))
        drapes = {"regressed": m.drape(run.garment, seq).vertices, "oracle code": _posed(m, m.vae.decode(oracle), seq),
                  "mean code": _posed(m, mean_code, seq), "canonical": _posed(m, X, seq)}  # fmt: skip
    return {"error": {**{k: error(x) for k, x in drapes.items()}, "code gap": float(gap)},
            "eps_e": {**{k: strain(x) for k, x in drapes.items()}, "reference": strain(reference)}}


def retrained_error(run_dir: Path, regressor: dict, seed: int) -> float:
    """The mean vertex distance (mm, frames after the transition) of the vae run's drape to its reference after
    its pose descriptor and regressor are trained again with the ``regressor`` keys and training seed ``seed``
    (the run's VAE and training data kept)."""
    from omegaconf import OmegaConf

    run = load_run(run_dir)
    m, seq, garment = run.method, run.seq, run.garment
    m.p["regressor"] = {**m.p["regressor"], **regressor}
    seqs, X = m.training_garments(garment, run.train_data(m))
    train_cfg = {k: v for k, v in OmegaConf.to_container(run.cfg.train, resolve=True).items() if k not in ("dataset", "log_dir")}
    m.fit_regressor(seqs, X, {**train_cfg, "seed": int(seed)})
    reference, start = run.reference(), int(seq.n_transition)
    return float((m.drape(garment, seq).vertices[start:] - reference[start:]).norm(dim=-1).mean() * 1e3)


def loss_terms(run_dir: Path, n_garments: int = 64) -> dict[str, tuple[float, str, float]]:
    """Eq. 13's weighted terms of the vae run's trained VAE on ``n_garments`` of its projected training garments (the
    first of each training sequence's frames in turn): {term: (value, unit, norm of the term's gradient over the
    VAE's weights)}; units mm (reconstruction, Laplacian, collisions) and nats (KL per garment)."""
    from methods.vae import losses

    run = load_run(run_dir)
    m = run.method
    seqs, X = m.training_garments(run.garment, run.train_data(m))
    train_idx, _ = m.validation_split(seqs)
    batch = X[train_idx].transpose(0, 1).flatten(0, 1)[:n_garments]
    terms = losses.vae_terms(m.vae, m.sdf, run.garment.topology.to(device=m.body.device), batch, m.p["vae"], m.p["projection"]["eps"], torch.Generator().manual_seed(0))
    weights = [w for w in m.vae.parameters() if w.requires_grad]
    out = {}
    for name, value in terms.items():
        grads = torch.autograd.grad(value, weights, retain_graph=True, allow_unused=True)
        norm = float(torch.sqrt(sum(g.square().sum() for g in grads if g is not None)))
        out[name] = (float(value.detach()), "nats" if name == "kl" else "mm", norm)
    return out


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("runs", nargs="+", type=Path, help="run directories of vae runs (with config.yaml and metrics.json)")
    parser.add_argument("--retrain", help="JSON of regressor keys: train the pose descriptor and regressor again with them")
    parser.add_argument("--seeds", default="0", help="with --retrain: comma-separated training seeds")
    parser.add_argument("--terms", type=int, default=0, help="also print Eq. 13's weighted terms and gradients on this many training garments")
    args = parser.parse_args(argv)
    if args.retrain:
        import json

        keys = json.loads(args.retrain)
        torch.set_num_threads(1)  # the measurements' setting: the regressor's training is chaotic in the float order
        print(f"run | seed | regressed (mm), regressor keys {keys}")
        for run in args.runs:
            for seed in map(int, args.seeds.split(",")):
                print(f"{run.name} | {seed} | {retrained_error(run, keys, seed):.2f}", flush=True)
        return
    print("run | regressed (mm) | oracle code (mm) | mean code (mm) | canonical (mm) | code gap (std)")
    results = {run: diagnose(run) for run in args.runs}
    for run, d in results.items():
        e = d["error"]
        print(f"{run.name} | {e['regressed']:.2f} | {e['oracle code']:.2f} | {e['mean code']:.2f} | {e['canonical']:.2f} | {e['code gap']:.2f}")
    print("run | eps_e (%): regressed | oracle code | mean code | canonical | reference")
    for run, d in results.items():
        s = d["eps_e"]
        print(f"{run.name} | {s['regressed']:.2f} | {s['oracle code']:.2f} | {s['mean code']:.2f} | {s['canonical']:.2f} | {s['reference']:.2f}")
    if args.terms:
        for run in args.runs:
            print(f"{run.name}: Eq. 13's terms on {args.terms} training garments (value, norm of its gradient over the VAE's weights)")
            for name, (value, unit, grad) in loss_terms(run, args.terms).items():
                print(f"  {name:18s} {value:12.5g} {unit:6s} |grad| {grad:.4g} {unit}/weight")


if __name__ == "__main__":
    main()
