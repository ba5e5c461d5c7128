"""What each skip saves: the work a scene does not need, timed with and without it.

Scene: the tshirt (about 3k vertices) on the full Anny body (13.7k vertices), skinned to the default walk
(105 frames, transition included), one torch thread. Rows:

- held pose: a static scene's body posed once per held pose (``BodySequence.held_frames``) against
  posing every frame;
- body culling: the nearest-body-vertex query of GAPS's collision term in training (scipy's KD-tree)
  over the body vertices near the garment against the whole body (``evaluate()`` searches the whole
  body, in the pass that finds the signed distance);
- cached topology: ``get_topology`` from the content-hash cache against building it;
- cached garment: ``make_garment`` from the cache against building it (body distance grid, remeshing,
  validation; inside ``forcing()``, which rewrites the same cache entries);
- energies off: ``evaluate(..., energies=False)`` (``eval.energies=false``) against the default;
- recording off: ``viz=none`` against writing the rerun recording (``record_drape``, with its inside test).

Run: python benchmarks/bench_skips.py   (prints a markdown table; the README quotes it)
"""

import os
import sys
import tempfile
import time
from pathlib import Path

import torch
from scipy.spatial import cKDTree
from timing import best

from drapebench.body import load_body, make_sequence
from drapebench.body.lbs import lbs
from drapebench.cache import forcing
from drapebench.garments import make_garment
from drapebench.geometry.proximity import culled_body_vertices, nearest_body_vertex
from drapebench.geometry.sdf import inside_body
from drapebench.geometry.topology import get_topology
from drapebench.metrics import evaluate
from drapebench.viz import record_drape


def _row(name: str, with_skip_s: float, without_s: float, unit: str) -> str:
    """A table row: times without and with the skip (ms), the time saved and the speed-up."""
    ratio = f"{without_s / with_skip_s:.1f}x" if with_skip_s > 0 else "all"
    return f"| {name} | {unit} | {1e3 * without_s:.1f} | {1e3 * with_skip_s:.1f} | {1e3 * (without_s - with_skip_s):.1f} ({ratio}) |"


def main() -> None:
    torch.set_num_threads(1)
    print(f"torch threads 1, load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    body = load_body("anny")
    g = make_garment("tshirt", body)
    seq = make_sequence("walk", 90, seed=0)
    near = cKDTree(body.v_template.numpy()).query(g.vertices.numpy())[1]
    x = lbs(g.vertices, body.weights[torch.as_tensor(near)], seq.transforms(body))
    rows = ["| skip | per | without it (ms) | with it (ms) | saved (ms) |", "|---|---|---|---|---|"]

    static = make_sequence("static", 90, seed=0)
    betas = body.full_betas(static.betas)[None]
    held = best(lambda: make_sequence("static", 90, seed=0).vertices(body), 3)
    every = best(lambda: body.forward(betas, static.poses, static.trans), 3)
    rows.append(_row(f"held pose (static, {static.n_frames} frames, {len(torch.unique(static.held_frames()))} distinct)", held, every, "sequence"))

    bv, bn = seq.vertices(body), seq.vertex_normals(body)
    cand = culled_body_vertices(g.vertices, body.v_template, body.weights)  # the mean-shape garment on the mean body, as GAPS culls
    culled = best(lambda: nearest_body_vertex(x, bv, bn, cand), 3)
    whole = best(lambda: nearest_body_vertex(x, bv, bn), 3)
    rows.append(_row(f"body culling ({len(cand)} of {body.n_vertices} body vertices)", culled / seq.n_frames, whole / seq.n_frames, "frame"))

    V, F = g.vertices.numpy(), g.faces.numpy()
    cached = best(lambda: get_topology(V, F), 3)
    built = best(lambda: get_topology(V, F, cache=False), 3)
    rows.append(_row("cached topology", cached, built, "garment"))

    cached = best(lambda: make_garment("tshirt", body), 3)
    with forcing():  # every cache entry the build asks for is rebuilt once (and rewritten, the same content)
        t = time.perf_counter()
        make_garment("tshirt", body)
        built = time.perf_counter() - t
    rows.append(_row("cached garment (body distance grid, remeshing, checks)", cached, built, "garment"))

    plain = best(lambda: evaluate(g, seq, body, x, energies=False), 3)
    full = best(lambda: evaluate(g, seq, body, x), 3)
    rows.append(_row("energies off (eval.energies=false)", plain / seq.n_frames, full / seq.n_frames, "frame"))

    with tempfile.TemporaryDirectory() as tmp:
        frames = evaluate(g, seq, body, x)[1]

        def record():
            inside = inside_body(x, bv, body.faces)
            record_drape(Path(tmp) / "drape.rrd", bv, body.faces, x, g.topology, seq.fps, penetrating=inside, metrics=frames, in_place=seq.trans)

        recording = best(record, 1)
    rows.append(_row(f"recording off (viz=none, {seq.n_frames} frames)", 0.0, recording, "run"))
    print("\n".join(rows))
    sys.stdout.flush()


if __name__ == "__main__":
    main()
