"""GenSim inference cost per frame on the CPU, by stage: motion-aware ARAP (handles, 10 ARAP steps with the
collision push) and PEN, for a ~3k-vertex skirt on the full anny body (the paper: about 600 ms ARAP + 300 ms
PEN for a 3000-vertex skirt; target here: at most 300 ms for both on 2 CPU cores). Timing does not depend on
trained values (PEN is freshly initialised).

Run: python benchmarks/bench_gensim.py
"""

import torch

import methods
from drapebench.body import load_body, make_sequence
from drapebench.garments import make_garment
from drapebench.physics import Material


def main():
    body = load_body("anny")
    g = make_garment("skirt", body)  # ~2.8k vertices at the default 15 mm resolution
    m = methods.get("gensim")({})
    m.bind(body, Material())
    torch.manual_seed(0)
    m.fabric, m.net = {"mean": 4.4e-4, "std": 8.1e-4}, m._new_net()
    seq = make_sequence("kick", 30, seed=0)
    m.drape(g, seq)  # warm-up: libigl, KD-trees, torch kernels
    runs = [m.drape(g, make_sequence("kick", 30, seed=0)) for _ in range(3)]
    per = {k: min(r.timings_ms[k] for r in runs) / seq.n_frames for k in runs[0].timings_ms}
    print(f"gensim skirt ({g.n_vertices} vertices) on anny, {seq.n_frames} frames of kick, cpu, {torch.get_num_threads()} threads: "
          f"{sum(per.values()):.0f} ms/frame ({', '.join(f'{k} {v:.1f}' for k, v in per.items())} ms/frame; best of 3 runs per stage)")  # fmt: skip


if __name__ == "__main__":
    main()
