"""GenSim's loss balance on real frames: every weighted Eq. 9 term, its gradient per vertex and what network
imprecision costs, under the configured reading of the paper and under the reading as printed.

Run: python -m methods.gensim.diagnose [--garment skirt] [--motion random] [--checkpoint PATH] [--set key=value ...]

Per term (SI units: m, kg, J; each term per frame, as the training loss weighs it): its value, and the
median / p99 over vertices of |d term / d x_i| (per m) at the ARAP result, so the pull of each term on one
vertex can be compared (gravity's is gamma_4 m_i g). ``noise`` is the change of the whole loss when smooth
random noise of RMS 0.3 mm is added to the ARAP result (what a network's imprecision costs), ``drop`` its
change when every free vertex drops 10 mm (what gravity offers). With ``--checkpoint`` (a trained gensim
checkpoint of the same parameters) the terms are also printed at PEN's output.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch

from drapebench.diagnose import term_table
from drapebench.geometry.ops import ring_mean

CONF = Path(__file__).resolve().parents[2] / "conf" / "method" / "gensim.yaml"  # its fitted mu_fabric, sigma_fabric
PRINTED = {"restrain_reduction": "sum", "restrain_offset": "printed", "restrain_huber": None}  # Eq. 3 as printed


def term_balance(method, graph, x: torch.Tensor, G: torch.Tensor, body_vertices, body_normals) -> dict[str, dict[str, float]]:
    """{term: {"value", "grad_median", "grad_p99"}} of ``method``'s weighted loss terms at positions x (B, V, 3) m
    for ARAP results G (B, V, 3): the value per frame and |d term / d x_i| per vertex (per m), median and p99
    over the vertices of every frame (:func:`drapebench.diagnose.term_table`)."""
    table = term_table(lambda y: method.terms(graph, y, G, body_vertices, body_normals), x).set_index("term").drop("total")
    # the terms are frame means: x B gives per-frame gradients
    return {name: {"value": float(row.value), "grad_median": float(row.grad_median) * len(x), "grad_p99": float(row.grad_p99) * len(x)}
            for name, row in table.iterrows()}  # fmt: skip


def smooth_noise(topology, shape, rms: float, rounds: int = 10, seed: int = 0) -> torch.Tensor:
    """Random displacements (B, V, 3) m of RMS ``rms`` m, averaged ``rounds`` times over each vertex's 1-ring."""
    gen = torch.Generator().manual_seed(seed)
    noise = torch.randn(shape, generator=gen)
    edges = topology.edges
    count = torch.zeros(shape[1]).index_add_(0, edges.flatten(), torch.ones(edges.numel())) + 1.0
    for _ in range(rounds):
        total = noise.clone().index_add_(1, edges[:, 0], noise[:, edges[:, 1]]).index_add_(1, edges[:, 1], noise[:, edges[:, 0]])
        noise = total / count[None, :, None]
    return noise * (rms / noise.pow(2).sum(-1).mean().sqrt())


def loss_changes(method, graph, G: torch.Tensor, body_vertices, body_normals, rms: float = 3e-4, drop: float = 0.01) -> dict[str, float]:
    """Change of the whole weighted loss (per frame) from the ARAP result G (B, V, 3) when smooth noise of RMS
    ``rms`` m is added ("noise") and when every non-pin vertex moves ``drop`` m down ("drop")."""
    with torch.no_grad():
        base = sum(method.terms(graph, G, G, body_vertices, body_normals).values())
        noisy = sum(method.terms(graph, G + smooth_noise(graph.topology, G.shape, rms).to(G.dtype), G, body_vertices, body_normals).values())
        down = G.clone()
        down[:, ~graph.pin_mask, 2] -= drop
        dropped = sum(method.terms(graph, down, G, body_vertices, body_normals).values())
    return {"noise": (noisy - base).item(), "drop": (dropped - base).item()}


def training_frames(method, garment_kind: str, motion: str, n_frames: int, seed: int, resolution: float):
    """A training-like batch: the ARAP stage of ``n_frames`` frames (as fit() samples them) of ``motion`` for a
    ``garment_kind`` meshed at ``resolution`` m on the method's body. Returns (graph, G, d, bodies, normals)."""
    from drapebench.body import make_sequence
    from drapebench.garments import make_garment
    from methods.gensim.method import garment_graph

    body = method.body
    garment = make_garment(garment_kind, body, seed=1, resolution=resolution)
    graph = garment_graph(garment, body, method.material)
    seq = make_sequence(motion, 60, seed=seed)
    frames = np.linspace(seq.n_transition, seq.n_frames - 1, n_frames).round().astype(int)
    betas = torch.zeros(body.n_betas, dtype=body.dtype)
    G, _, d, verts, normals, _ = method.arap_stage(graph, betas, seq.poses[frames].to(body.dtype))
    return graph, G, d, verts, normals


def arap_health(method, garment, seq) -> dict[str, float]:
    """The ARAP stage of ``method`` on ``garment`` over ``seq`` (its transition frames left out): mean and largest
    edge strain (%), the largest strain of an edge between two handles (%: their targets, which ARAP keeps),
    the largest spike (mm: a vertex's offset from its 1-ring mean, against the template's, as a single
    pushed-out vertex makes) and the largest frame-to-frame move of a vertex (mm)."""
    from drapebench.geometry.ops import edge_lengths
    from methods.gensim.method import garment_graph

    body = method.body
    graph = garment_graph(garment, body, method.material)
    betas = torch.zeros(body.n_betas, dtype=body.dtype)
    given = seq.betas[: body.n_betas]
    betas[: len(given)] = given.to(body.dtype)
    G, H, *_ = method.arap_stage(graph, betas, seq.poses.to(body.dtype))
    G, H = G[seq.n_transition :].double(), H[seq.n_transition :]
    topo, edges = graph.topology, graph.topology.edges
    strain = (edge_lengths(G, edges) / topo.rest_edge_lengths.double() - 1.0).abs() * 100
    both = H[:, edges[:, 0]] & H[:, edges[:, 1]]
    T = graph.template.double()[None]
    spike = ((G - ring_mean(G, topo)) - (T - ring_mean(T, topo))).norm(dim=-1) * 1e3
    move = (G[1:] - G[:-1]).norm(dim=-1) * 1e3
    return {"strain_mean_pct": strain.mean().item(), "strain_max_pct": strain.max().item(),
            "handle_edge_strain_max_pct": strain[both].max().item() if both.any() else 0.0,
            "spike_max_mm": spike.max().item(), "frame_move_max_mm": move.max().item() if len(move) else 0.0}  # fmt: skip


def report(method, graph, x, G, verts, normals, label: str) -> str:
    """The term table of :func:`term_balance` (and :func:`loss_changes` at the ARAP result) as text."""
    rows = term_balance(method, graph, x, G, verts, normals)
    lines = [f"{label}", f"  {'term':<11}{'value/frame':>13}{'|g| median':>13}{'|g| p99':>13}  (|g|: per vertex, per m)"]
    lines += [f"  {n:<11}{r['value']:>13.4g}{r['grad_median']:>13.4g}{r['grad_p99']:>13.4g}" for n, r in rows.items()]
    if x is G:
        ch = loss_changes(method, graph, G, verts, normals)
        lines.append(f"  loss change: smooth noise 0.3 mm {ch['noise']:+.4g}, free vertices 10 mm down {ch['drop']:+.4g}")
    return "\n".join(lines)


def main(argv=None) -> None:
    """Print the term balance (see the module docstring)."""
    import methods
    from drapebench.body import load_body
    from drapebench.physics import Material

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--garment", default="skirt")
    ap.add_argument("--motion", default="random")
    ap.add_argument("--frames", type=int, default=4)
    ap.add_argument("--seed", type=int, default=3)
    ap.add_argument("--resolution", type=float, default=0.02)
    ap.add_argument("--body", default="anny_lowres")
    ap.add_argument("--checkpoint", help="a trained gensim checkpoint (.pt); its parameters replace --set")
    ap.add_argument("--arap", action="store_true", help="instead: the ARAP stage's strain and jumps on a held-out motion (--motion, e.g. kick)")
    ap.add_argument("--set", nargs="*", default=[], help="method parameters key=value (YAML values), e.g. decoder=eq1")
    args = ap.parse_args(argv)
    import yaml

    fitted = yaml.safe_load(CONF.read_text())["params"]
    cfg = {"fabric_mean": fitted["fabric_mean"], "fabric_std": fitted["fabric_std"]}
    cfg.update({k: yaml.safe_load(v) for k, v in (s.split("=", 1) for s in args.set)})
    state = torch.load(args.checkpoint, map_location="cpu", weights_only=False)["method"] if args.checkpoint else None
    if state is not None:  # the checkpoint's own parameters (its reading of the losses included)
        cfg = state["params"]
    torch.set_num_threads(1)
    body = load_body(args.body)
    configured = methods.get("gensim")(cfg)
    configured.bind(body, Material())
    configured.fabric = configured._fabric()
    if args.arap:
        from drapebench.body import make_sequence
        from drapebench.garments import make_garment

        seq = make_sequence(args.motion, 90, seed=args.seed, transition=15)
        garment = make_garment(args.garment, body)
        health = arap_health(configured, garment, seq)
        print(f"gensim ARAP stage: {args.garment} ({garment.n_vertices} vertices) on {args.body}, {args.motion} seed {args.seed} (90 frames): "
              + ", ".join(f"{k} {v:.2f}" for k, v in health.items()))  # fmt: skip
        return
    graph, G, d, verts, normals = training_frames(configured, args.garment, args.motion, args.frames, args.seed, args.resolution)
    print(f"gensim loss balance: {args.garment} ({len(graph.template)} vertices, {len(graph.topology.edges)} edges) on {args.body}, "
          f"{args.frames} frames of {args.motion} seed {args.seed}; mu {configured.fabric['mean']:.3g} m, sigma {configured.fabric['std']:.3g} m")  # fmt: skip
    printed = methods.get("gensim")({**cfg, **PRINTED})
    printed.bind(body, Material())
    printed.fabric = configured.fabric
    print(report(printed, graph, G, G, verts, normals, "at the ARAP result, Eq. 3 as printed (sum over edges, no dead zone, no Huber)"))
    print(report(configured, graph, G, G, verts, normals, f"at the ARAP result, as configured ({', '.join(f'{k}={configured.p[k]}' for k in PRINTED)})"))
    if state is not None:
        configured.load_state_dict(state)
        with torch.no_grad():
            x, delta = configured.pen(graph, G, d, verts, normals, torch.zeros(len(G), body.n_betas, dtype=body.dtype))
        moved = delta.norm(dim=-1).flatten() * 1e3
        print(report(configured, graph, x, G, verts, normals, f"at PEN's output (|delta| mean {moved.mean():.2f} mm, p99 {moved.quantile(0.99):.2f} mm)"))


if __name__ == "__main__":
    main()
