"""GAPS inference cost per frame on the CPU, end to end without file writing:
body joint transforms, GRU + output layer, skinning. Timing does not depend on trained values.

Run: python benchmarks/bench_gaps.py
"""

import torch
from timing import best

import methods
from drapebench.body import load_body, make_sequence
from drapebench.garments import make_garment
from drapebench.physics import Material


def main():
    body = load_body("anny")
    g = make_garment("tshirt", body, resolution=0.013)  # ~4k vertices, the target size
    m = methods.get("gaps")({})
    m.bind(body, Material())
    torch.manual_seed(0)
    m._setup(g)
    seq = make_sequence("walk", 285, seed=0)

    def drape():
        s = make_sequence("walk", 285, seed=0)  # fresh sequence: no cached body transforms
        return m.drape(g, s)

    t = best(drape, 3)
    per = {k: v / seq.n_frames for k, v in drape().timings_ms.items()}
    print(f"gaps tshirt ({g.n_vertices} vertices), {seq.n_frames} frames on cpu, {torch.get_num_threads()} threads: "
          f"{t / seq.n_frames * 1e3:.2f} ms/frame (one run's stages: {', '.join(f'{k} {v:.2f}' for k, v in per.items())} ms/frame)")  # fmt: skip


if __name__ == "__main__":
    main()
