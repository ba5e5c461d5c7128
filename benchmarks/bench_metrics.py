"""evaluate() frames per second, default signed distance (warp BVH, ray-crossing winding number)
against ``exact=True`` (libigl), and the largest difference between the two paths on a walk and a
squat (where the body intersects itself): signed distance (mm), eps_c (%), penetration_mm. Then the
collision term of training (GAPS/SNUG: nearest body vertex among those near the garment, KD-tree, and
the cubic penalty, forward and backward) in frames per second.

Run: python benchmarks/bench_metrics.py  (CPU, float32; garments skinned to the motion; the body is
posed before timing, as after a method's drape)
"""

import os
import sys

import torch
from scipy.spatial import cKDTree
from timing import best

from drapebench.body import load_body, make_sequence
from drapebench.body.lbs import lbs
from drapebench.garments import make_garment
from drapebench.geometry.proximity import culled_body_vertices, nearest_body_vertex
from drapebench.geometry.sdf import signed_distance
from drapebench.metrics import evaluate
from drapebench.physics import collision_energy


def _scene(body, kind: str, motion: str, n_frames: int):
    seq = make_sequence(motion, n_frames, seed=0, transition=0)
    g = make_garment(kind, body)
    near = cKDTree(body.v_template.numpy()).query(g.vertices.numpy())[1]
    x = lbs(g.vertices, body.weights[torch.as_tensor(near)], seq.transforms(body))
    seq.vertices(body), seq.vertex_normals(body)  # posed once, as the experiment does for the recording
    return g, seq, x


def main(n_frames: int = 40, n_exact: int = 8) -> None:
    print(f"torch threads {torch.get_num_threads()}, load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    for body_name in ("anny", "anny_lowres"):
        body = load_body(body_name)
        for kind in ("tshirt", "dress"):
            g, seq, x = _scene(body, kind, "walk", n_frames)
            fast = n_frames / best(lambda: evaluate(g, seq, body, x), 3)
            plain = n_frames / best(lambda: evaluate(g, seq, body, x, energies=False), 3)
            short = seq.slice(0, n_exact)
            exact = n_exact / best(lambda: evaluate(g, short, body, x[:n_exact], exact=True), 1)
            print(f"evaluate() {kind} ({g.n_vertices} vertices) on {body_name} ({body.n_vertices} vertices): {fast:.0f} frames/s "
                  f"({plain:.0f} without energies); exact=True {exact:.1f} frames/s")  # fmt: skip
            for motion in ("walk", "squat"):
                g, seq, x = _scene(body, kind, motion, 60)
                x, seq = x[-n_exact:], seq.slice(60 - n_exact)  # the deepest squat frames
                bv = seq.vertices(body)
                sd = signed_distance(x, bv, body.faces, outer_faces=body.outer_faces)
                sd_exact = signed_distance(x, bv, body.faces, exact=True, outer_faces=body.outer_faces)
                a, b = evaluate(g, seq, body, x, energies=False)[1], evaluate(g, seq, body, x, energies=False, exact=True)[1]
                print(f"  {motion}: max |sd - exact| {float((sd - sd_exact).abs().max()) * 1e3:.2g} mm, sign differs at "
                      f"{int(((sd < 0) != (sd_exact < 0)).sum())} of {sd.numel()} points; max |eps_c diff| "
                      f"{(a['eps_c'] - b['eps_c']).abs().max():.2g} %, max |penetration_mm diff| "
                      f"{(a['penetration_mm'] - b['penetration_mm']).abs().max():.2g} mm")  # fmt: skip
        sys.stdout.flush()
        _training_collision(body, n_frames)


def _training_collision(body, n_frames: int) -> None:
    """Frames per second of the training collision term for the tshirt on a walk."""
    g, seq, x = _scene(body, "tshirt", "walk", n_frames)
    bv, bn = seq.vertices(body), seq.vertex_normals(body)
    cand = culled_body_vertices(g.vertices, body.v_template, body.weights)
    x = x.clone().requires_grad_(True)

    def step():
        nn = nearest_body_vertex(x, bv, bn, cand)
        collision_energy(x, nn.point, nn.normal).sum().backward()

    print(f"training collision term, tshirt on {body.name} ({len(cand)} of {body.n_vertices} body vertices searched): "
          f"{n_frames / best(step, 3):.0f} frames/s (nearest vertex, penalty, gradient)")  # fmt: skip


if __name__ == "__main__":
    main()
