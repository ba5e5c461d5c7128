"""GenSim inference cost per frame on the CPU, by stage: motion-aware ARAP (handles, 10 ARAP steps with the
collision push) and PEN, for a ~3k-vertex skirt on the full anny body (the paper: about 600 ms ARAP + 300 ms
PEN for a 3000-vertex skirt on a GPU; the target here: at most 50 ms for both on 2 CPU cores, which
methods/gensim/README.md compares with the bound below). Timing does not depend on trained values (PEN is
freshly initialised).

Prints the time per frame with torch's threads as set (every core), then with one thread: the work per frame
in core-milliseconds. That work divided by the number of cores bounds the time per frame on those cores from
below, however the frames and stages were spread over them.

Run: python benchmarks/bench_gensim.py
"""

import torch

import methods
from drapebench.body import load_body, make_sequence
from drapebench.garments import make_garment
from drapebench.physics import Material


def per_frame_ms(m, g, runs: int = 3) -> dict:
    """Best of ``runs`` drapes of 45 frames of kick, per stage, in ms per frame."""
    out = [m.drape(g, make_sequence("kick", 30, seed=0)) for _ in range(runs)]
    n_frames = out[0].vertices.shape[0]
    return {k: min(r.timings_ms[k] for r in out) / n_frames for k in out[0].timings_ms}


def main():
    body = load_body("anny")
    g = make_garment("skirt", body)  # ~2.8k vertices at the default 15 mm resolution
    m = methods.get("gensim")({})
    m.bind(body, Material())
    torch.manual_seed(0)
    m.fabric, m.net = {"mean": 4.4e-4, "std": 8.1e-4}, m._new_net()
    seq = make_sequence("kick", 30, seed=0)
    m.drape(g, seq)  # warm-up: libigl, KD-trees, torch kernels
    cores = torch.get_num_threads()
    per = per_frame_ms(m, g)
    print(f"gensim skirt ({g.n_vertices} vertices) on anny, {seq.n_frames} frames of kick, cpu, {cores} threads: "
          f"{sum(per.values()):.0f} ms/frame ({', '.join(f'{k} {v:.1f}' for k, v in per.items())} ms/frame; best of 3 runs per stage)")  # fmt: skip
    torch.set_num_threads(1)
    one = per_frame_ms(m, g)
    work = sum(one.values())
    print(f"one thread: {work:.0f} core-ms/frame ({', '.join(f'{k} {v:.1f}' for k, v in one.items())}); "
          f"shared over {cores} cores at best {work / cores:.0f} ms/frame")  # fmt: skip


if __name__ == "__main__":
    main()
