"""GenSim's loss balance on real frames: every weighted Eq. 9 term, its gradient per vertex and what network
imprecision costs, under the configured reading of the paper and under the reading as printed.

Run: python -m methods.gensim.diagnose [--garment skirt] [--motion random] [--checkpoint PATH] [--set key=value ...]
     python -m methods.gensim.diagnose --compare <gensim_arap run> <gensim run>

Per term (SI units: m, kg, J; each term per frame, as the training loss weighs it): its value, and the
median / p99 over vertices of |d term / d x_i| (per m) at the ARAP result, so the pull of each term on one
vertex can be compared (gravity's is gamma_4 m_i g). ``noise`` is the change of the whole loss when smooth
random noise of RMS 0.3 mm is added to the ARAP result (what a network's imprecision costs), ``drop`` its
change when every free vertex drops 10 mm (what gravity offers). With ``--checkpoint`` (a trained gensim
checkpoint of the same parameters) the terms are also printed at PEN's output, with where eps_e changes
(:func:`strain_change`) and without PEN's move along the body normal on vertices farther than
:data:`FAR_FROM_BODY` from the body; before that, the roughness of PEN's node inputs under both ``body_query`` readings
(:func:`input_roughness`). ``--compare ARAP_RUN PEN_RUN`` instead prints where eps_e changes between two
finished runs of one scene, by edge strain class, and eps_e of each part of the displacement between them
(:func:`displacement_parts`: along the normals, tangential, and as an even offset), and the move along the
normals by the first run's signed body distance (:func:`normal_push_by_distance`).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch

from drapebench.diagnose import term_table
from drapebench.geometry.sdf import signed_distance
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
    from methods.gensim.method import garment_graph

    body = method.body
    graph = garment_graph(garment, body, method.material)
    betas = torch.zeros(body.n_betas, dtype=body.dtype)
    given = seq.betas[: body.n_betas]
    betas[: len(given)] = given.to(body.dtype)
    G, H, *_ = method.arap_stage(graph, betas, seq.poses.to(body.dtype))
    G, H = G[seq.n_transition :].double(), H[seq.n_transition :]
    topo, edges = graph.topology, graph.topology.edges
    strain = edge_strain(G, topo)
    both = H[:, edges[:, 0]] & H[:, edges[:, 1]]
    T = graph.template.double()[None]
    spike = ((G - ring_mean(G, topo)) - (T - ring_mean(T, topo))).norm(dim=-1) * 1e3
    move = (G[1:] - G[:-1]).norm(dim=-1) * 1e3
    return {"strain_mean_pct": strain.mean().item(), "strain_max_pct": strain.max().item(),
            "handle_edge_strain_max_pct": strain[both].max().item() if both.any() else 0.0,
            "spike_max_mm": spike.max().item(), "frame_move_max_mm": move.max().item() if len(move) else 0.0}  # fmt: skip


STRAIN_CLASSES = (0.0, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0, float("inf"))  # edge strain classes (%) of strain_change


def edge_strain(x: torch.Tensor, topology) -> torch.Tensor:
    """|l / l0 - 1| (%) of every edge of drapes x (..., V, 3) m, in float64: (..., E)."""
    from drapebench.geometry.ops import edge_lengths

    return (edge_lengths(x.double(), topology.edges) / topology.rest_edge_lengths.double() - 1.0).abs() * 100


def strain_change(before: torch.Tensor, after: torch.Tensor, topology, classes=STRAIN_CLASSES) -> list[dict[str, float]]:
    """Where eps_e changes between two drapes (T, V, 3) m of one garment (e.g. the ARAP stage and PEN's output),
    by the edges' strain class in ``before`` (%, [lo, hi)): per class the share of edge samples, the mean change
    of their strain (points) and its contribution to the change of eps_e (points; the rows sum to it)."""
    s0, s1 = edge_strain(before, topology), edge_strain(after, topology)
    rows = []
    for lo, hi in zip(classes[:-1], classes[1:]):
        m = (s0 >= lo) & (s0 < hi)
        change = (s1 - s0)[m]
        rows.append({"lo": lo, "hi": hi, "share": m.double().mean().item(), "mean_change": change.mean().item() if m.any() else 0.0,
                     "eps_e_change": (change.sum() / s0.numel()).item()})  # fmt: skip
    return rows


def displacement_parts(before: torch.Tensor, after: torch.Tensor, topology) -> dict[str, float]:
    """eps_e (%) of two drapes (T, V, 3) m of one garment and of ``before`` moved by each part of the displacement
    ``after - before``: along ``before``'s vertex normals (``normal``), the tangential rest (``tangential``),
    and the per-frame mean of the normal part applied uniformly (``uniform_normal``: the strain an even offset
    of the surface alone adds); ``normal_mm`` is the mean signed normal part (mm, > 0 along the normals)."""
    from drapebench.geometry.ops import vertex_normals

    x0, x1 = before.double(), after.double()
    n = vertex_normals(x0, topology.faces)
    d = x1 - x0
    dn = (d * n).sum(-1, keepdim=True)

    def eps(x):
        return edge_strain(x, topology).mean().item()

    return {"before": eps(x0), "after": eps(x1), "normal": eps(x0 + dn * n), "tangential": eps(x1 - dn * n),
            "uniform_normal": eps(x0 + dn.mean(-2, keepdim=True) * n), "normal_mm": dn.mean().item() * 1e3}  # fmt: skip


FAR_FROM_BODY = 0.01  # m: beyond it Eq. 8's collision term (3 mm margin) does not act on a vertex
DISTANCE_CLASSES_MM = (float("-inf"), 0.0, 3.0, 10.0, 20.0, float("inf"))  # body distance classes (mm) of normal_push_by_distance


def normal_push_by_distance(before: torch.Tensor, after: torch.Tensor, topology, distance_mm: torch.Tensor,
                            classes=DISTANCE_CLASSES_MM) -> list[dict[str, float]]:  # fmt: skip
    """The displacement ``after - before`` (T, V, 3) m along ``before``'s vertex normals, by the class of
    ``before``'s signed body distance ``distance_mm`` (T, V) (lo < d <= hi, mm): per class ``share`` (of
    vertex-frames) and ``normal_mm`` (mean, > 0 outward; NaN for an empty class)."""
    from drapebench.geometry.ops import vertex_normals

    x0 = before.double()
    dn = ((after.double() - x0) * vertex_normals(x0, topology.faces)).sum(-1) * 1e3
    rows = []
    for lo, hi in zip(classes[:-1], classes[1:]):
        mask = (distance_mm > lo) & (distance_mm <= hi)
        rows.append({"lo": lo, "hi": hi, "share": mask.double().mean().item(),
                     "normal_mm": dn[mask].mean().item() if mask.any() else float("nan")})  # fmt: skip
    return rows


FEATURE_GROUPS = {"u": slice(0, 3), "v (x - body point)": slice(3, 6), "d": slice(6, 9), "normal": slice(9, 12)}


def input_roughness(method, graph, G: torch.Tensor, d: torch.Tensor, body_vertices, body_normals) -> dict[str, float]:
    """How much PEN's 3-vector node inputs jump along the garment's edges, for ARAP results G (B, V, 3):
    per group of :data:`FEATURE_GROUPS`, the mean |f_i - f_j| over edges divided by the norm of the feature's
    std over vertices and frames (a smooth field: about the edge length over the garment's size)."""
    node, _, _ = method.features(graph, G, d, body_vertices, body_normals)
    i, j = graph.topology.edges[:, 0], graph.topology.edges[:, 1]
    return {name: ((node[:, i, s] - node[:, j, s]).norm(dim=-1).mean() / node[..., s].reshape(-1, 3).std(0).norm()).item()
            for name, s in FEATURE_GROUPS.items()}  # fmt: skip


def compare_runs(arap_dir: str, pen_dir: str) -> str:
    """:func:`strain_change` and :func:`displacement_parts` from the run ``arap_dir`` (gensim_arap) to the run
    ``pen_dir`` (gensim) of the same garment and motion, over the frames after the transition, as text."""
    from omegaconf import OmegaConf

    from drapebench.results import read_prediction
    from drapebench.scene import Scene

    run = Scene.from_config(OmegaConf.load(Path(arap_dir) / "config.yaml"))  # the scene (garment, motion) of both runs
    n0 = run.seq.n_transition
    before, after = (torch.from_numpy(read_prediction(Path(d) / "prediction.h5")[0][n0:]) for d in (arap_dir, pen_dir))
    parts = displacement_parts(before, after, run.garment.topology)
    body_vertices, _ = run.seq.posed_frames(run.body, n0, run.seq.n_frames, local=True)
    local = before.double() - run.seq.trans[n0:, None].double()
    distance = signed_distance(local.to(body_vertices.dtype), body_vertices, run.body.faces, outer_faces=run.body.outer_faces) * 1e3
    by_distance = normal_push_by_distance(before, after, run.garment.topology, distance)
    return "\n".join([strain_change_text(strain_change(before, after, run.garment.topology), f"eps_e change from {arap_dir} to {pen_dir}"),
                      f"eps_e by part of the displacement (%): before {parts['before']:.3f}, after {parts['after']:.3f}; "
                      f"before + its normal part {parts['normal']:.3f} (mean {parts['normal_mm']:+.2f} mm along the normals; "
                      f"as an even offset {parts['uniform_normal']:.3f}), + its tangential part {parts['tangential']:.3f}",
                      "mean move along the normals (mm) by the first run's body distance: "
                      + ", ".join(f"({r['lo']:g}, {r['hi']:g}] mm {r['share'] * 100:.0f} % of vertices {r['normal_mm']:+.2f}" for r in by_distance)])  # fmt: skip


def strain_change_text(rows: list[dict[str, float]], label: str) -> str:
    """The rows of :func:`strain_change` as a text table under ``label``."""
    lines = [f"{label}, by the first drape's edge strain (%):", f"  {'strain class':<14}{'share':>8}{'mean change':>13}{'eps_e change':>14}"]
    lines += [f"  {r['lo']:>5.0f} - {r['hi']:<6.0f}{r['share']:>8.3f}{r['mean_change']:>+13.3f}{r['eps_e_change']:>+14.3f}" for r in rows]
    lines.append(f"  total eps_e change {sum(r['eps_e_change'] for r in rows):+.3f} points")
    return "\n".join(lines)


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
    ap.add_argument("--compare", nargs=2, metavar=("ARAP_RUN", "PEN_RUN"),
                    help="instead: where eps_e changes from a gensim_arap run to a gensim run of the same scene (run folders)")
    ap.add_argument("--set", nargs="*", default=[], help="method parameters key=value (YAML values), e.g. decoder=eq1")
    args = ap.parse_args(argv)
    if args.compare:
        print(compare_runs(*args.compare))
        return
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
    for query in ("vertex", "surface"):
        reading = methods.get("gensim")({**cfg, "body_query": query})
        reading.bind(body, Material())
        rough = input_roughness(reading, graph, G, d, verts, normals)
        print(f"PEN's input roughness (mean jump along an edge / std), body_query {query}: " + ", ".join(f"{k} {v:.3f}" for k, v in rough.items()))
    if state is not None:
        configured.load_state_dict(state)
        with torch.no_grad():
            x, delta = configured.pen(graph, G, d, verts, normals, torch.zeros(len(G), body.n_betas, dtype=body.dtype))
        moved = delta.norm(dim=-1).flatten() * 1e3
        print(report(configured, graph, x, G, verts, normals, f"at PEN's output (|delta| mean {moved.mean():.2f} mm, p99 {moved.quantile(0.99):.2f} mm)"))
        print(strain_change_text(strain_change(G, x, graph.topology), "eps_e change from the ARAP stage to PEN's output"))
        far = signed_distance(G, verts, body.faces, outer_faces=body.outer_faces) > FAR_FROM_BODY
        _, _, normal = configured.features(graph, G, d, verts, normals)
        along = (delta * normal).sum(-1, keepdim=True)
        kept = x - torch.where(far[..., None], along, torch.zeros_like(along)) * normal
        print(report(configured, graph, kept, G, verts, normals, f"at PEN's output without its move along the body normal on the {far.double().mean() * 100:.0f} % of "
                     f"vertices farther than {FAR_FROM_BODY * 1e3:g} mm from the body (mean {along[far].mean() * 1e3:+.2f} mm there)"))  # fmt: skip


if __name__ == "__main__":
    main()
