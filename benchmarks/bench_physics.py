"""Energy forward+backward, topology build/load, proximity with and without culling, evaluate() per frame.

Run: python benchmarks/bench_physics.py  (CPU, float32, 2 threads)
"""


import torch
from timing import best

from drapebench.body import load_body, make_sequence
from drapebench.garments import make_garment
from drapebench.geometry import topology as topo_mod
from drapebench.geometry.proximity import culled_body_vertices, nearest_body_vertex
from drapebench.geometry.sdf import signed_distance
from drapebench.geometry.topology import build_topology_arrays, get_topology
from drapebench.metrics import evaluate
from drapebench.physics import (
    Material,
    bending_energy,
    collision_energy,
    gravity_energy,
    hinge_collision_energy,
    inertia_energy,
    inextensibility_energy,
    laplacian_smoothness,
    pin_energy,
    restrain_energy,
    stvk_energy,
)


def energies(topo, mat, prev, nn_point, nn_normal, blend, pins):
    """Every energy as name -> f(x) (B,)."""
    return {
        "stvk": lambda x: stvk_energy(x, topo, mat),
        "bending (gaps blend)": lambda x: bending_energy(x, topo, mat, blend=blend),
        "gravity": lambda x: gravity_energy(x, topo, mat),
        "inertia": lambda x: inertia_energy(x, prev, torch.zeros_like(prev), topo, mat),
        "collision (cubic)": lambda x: collision_energy(x, nn_point, nn_normal),
        "collision (hinge)": lambda x: hinge_collision_energy(x, nn_point, nn_normal),
        "inextensibility": lambda x: inextensibility_energy(x, topo, 1.0),
        "restrain": lambda x: restrain_energy(x, topo, 1e-3, 2e-3),
        "pin": lambda x: pin_energy(x, prev[:, pins], pins),
        "smoothness": lambda x: laplacian_smoothness(x, topo),
    }


def main():
    torch.set_num_threads(2)
    body = load_body("anny")
    g = make_garment("dress", body)  # ~5.8k vertices
    V, F = g.vertices.numpy(), g.faces.numpy()
    print(f"garment: dress, {g.n_vertices} vertices, {len(F)} faces, float32, {torch.get_num_threads()} threads")
    print(f"topology build {best(lambda: build_topology_arrays(V, F), 3) * 1e3:.1f} ms", end="; ")
    get_topology(V, F)

    def cached():
        topo_mod._MEMORY.clear()
        get_topology(V, F)

    print(f"cached load from disk {best(cached) * 1e3:.1f} ms; in memory {best(lambda: get_topology(V, F), 20) * 1e6:.0f} us")
    mat, topo = Material(), g.topology
    blend = torch.rand(topo.hinge_edges.shape[0])
    pins = g.pins if len(g.pins) else torch.arange(10)
    for B in (1, 16):
        x = (g.vertices[None] + 0.001 * torch.randn(B, g.n_vertices, 3)).requires_grad_(True)
        prev = g.vertices[None].expand(B, -1, -1)
        nn_normal = torch.nn.functional.normalize(torch.randn(B, g.n_vertices, 3), dim=-1)
        nn_point = prev - 0.002 * nn_normal * torch.rand(B, g.n_vertices, 1)
        fns = energies(topo, mat, prev, nn_point, nn_normal, blend, pins)

        def step(fs):
            x.grad = None
            sum(f(x).sum() for f in fs).backward()

        per = {name: best(lambda f=f: step([f])) for name, f in fns.items()}
        total = best(lambda: step(list(fns.values())))
        print(f"batch {B:2d} forward+backward: all energies {total * 1e3:.1f} ms ("
              + ", ".join(f"{k} {v * 1e3:.2f}" for k, v in per.items()) + " ms)")  # fmt: skip
    seq = make_sequence("walk", 30, seed=0)
    bv, bn = seq.vertices(body), seq.vertex_normals(body)
    for kind in ("dress", "skirt", "shorts"):
        gk = make_garment(kind, body)
        xk = gk.vertices[None] + seq.trans[:, None]
        cand = culled_body_vertices(gk.vertices, body.v_template, body.weights)
        t_all = best(lambda: nearest_body_vertex(xk, bv, bn), 3) / seq.n_frames
        t_cull = best(lambda: nearest_body_vertex(xk, bv, bn, cand), 3) / seq.n_frames
        print(f"nearest body vertex per frame, {kind}: all {body.n_vertices} body vertices {t_all * 1e3:.2f} ms, "
              f"culled to {len(cand)} {t_cull * 1e3:.2f} ms ({t_all / t_cull:.1f}x)")  # fmt: skip
    x = g.vertices[None] + seq.trans[:, None]
    print(f"exact signed distance per frame: {best(lambda: signed_distance(x[:5], bv[:5], body.faces), 2) / 5 * 1e3:.1f} ms")
    pred = x
    print(f"evaluate() per frame: {best(lambda: evaluate(g, seq, body, pred), 2) / seq.n_frames * 1e3:.1f} ms")


if __name__ == "__main__":
    main()
