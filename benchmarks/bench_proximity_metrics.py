"""Body proximity and metrics against the full Anny body: nearest body vertex per frame by KD-tree with
and without vertex culling, the signed distance (drapebench.geometry.sdf: default warp BVH with the
winding number by ray crossings; exact=True libigl with per-frame face culling), its inside test alone
and, with the whole body's nearest vertex in the same BVH pass, body_proximity; evaluate() per frame.

Run: python benchmarks/bench_proximity_metrics.py  (CPU, float32; garments skinned to a walk)
"""

import os

import igl
import numpy as np
import torch
from scipy.spatial import cKDTree
from timing import best

from drapebench.body import load_body, make_sequence
from drapebench.body.lbs import lbs
from drapebench.garments import make_garment
from drapebench.geometry.proximity import culled_body_faces, culled_body_vertices, nearest_body_vertex
from drapebench.geometry.sdf import body_proximity, inside_body, signed_distance
from drapebench.metrics import evaluate


def main(n_frames: int = 10) -> None:
    body = load_body("anny")
    seq = make_sequence("walk", n_frames, seed=0, transition=0)
    bv, bn, faces = seq.vertices(body), seq.vertex_normals(body), body.faces
    near = cKDTree(body.v_template.numpy())
    print(f"body: {body.n_vertices} vertices, {faces.shape[0]} faces; {n_frames} frames; "
          f"torch threads {torch.get_num_threads()}, load average {os.getloadavg()[0]:.1f}")  # fmt: skip
    for kind in ("tshirt", "skirt", "pants", "dress"):
        g = make_garment(kind, body)
        x = lbs(g.vertices, body.weights[torch.as_tensor(near.query(g.vertices.numpy())[1])], seq.transforms(body))
        cand = culled_body_vertices(g.vertices, body.v_template, body.weights)
        n_faces = len(culled_body_faces(faces, cand))
        t_nn = best(lambda: nearest_body_vertex(x, bv, bn), 3) / n_frames
        t_nn_c = best(lambda: nearest_body_vertex(x, bv, bn, cand), 3) / n_frames
        t_sd = best(lambda: signed_distance(x, bv, faces), 2) / n_frames
        t_both = best(lambda: body_proximity(x, bv, bn, faces), 2) / n_frames
        t_in = best(lambda: inside_body(x, bv, faces), 2) / n_frames
        t_exact = best(lambda: signed_distance(x, bv, faces, exact=True), 1) / n_frames
        print(f"{kind} ({g.n_vertices} vertices): culled to {len(cand)} body vertices / {n_faces} faces\n"
              f"  nearest body vertex per frame: KD-tree all {t_nn * 1e3:.2f} ms, culled {t_nn_c * 1e3:.2f} ms ({t_nn / t_nn_c:.1f}x)\n"
              f"  signed distance per frame: {t_sd * 1e3:.1f} ms (inside test alone {t_in * 1e3:.1f} ms; with the whole body's nearest "
              f"vertex in the same pass {t_both * 1e3:.1f} ms); exact=True {t_exact * 1e3:.1f} ms")  # fmt: skip
    P, V, F = x[0].double().numpy(), bv[0].double().numpy(), faces.numpy().astype(np.int64)
    fwn = igl.SIGNED_DISTANCE_TYPE_FAST_WINDING_NUMBER
    t_igl = best(lambda: igl.signed_distance(P, V, F, sign_type=fwn), 2)
    print(f"for comparison, libigl signed_distance (fast winding number sign), dress, one frame: {t_igl * 1e3:.1f} ms")
    for kind in ("tshirt", "dress"):
        g = make_garment(kind, body)
        x = lbs(g.vertices, body.weights[torch.as_tensor(near.query(g.vertices.numpy())[1])], seq.transforms(body))
        t_eval = best(lambda: evaluate(g, seq, body, x), 2) / n_frames
        t_plain = best(lambda: evaluate(g, seq, body, x, energies=False), 2) / n_frames
        print(f"evaluate() per frame, {kind}: {t_eval * 1e3:.1f} ms ({t_plain * 1e3:.1f} ms without the energy breakdown)")


if __name__ == "__main__":
    main()
