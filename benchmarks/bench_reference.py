"""Reference simulator cost: seconds per frame for each solver on a ~4k-vertex tshirt and a ~5k-vertex skirt
on the full Anny body (walk, default solver settings), CPU and, when warp finds CUDA, GPU.

Run: python benchmarks/bench_reference.py [--frames 6] [--body anny]
The first simulation of a process also pays warp's one-time kernel compilation (cached in data/cache/warp);
each scene is run once as a warm-up and the sequence frames of a second, uncached run are timed
(setup = model build, reported separately; settling excluded).
"""

import argparse

from drapebench.body import load_body, make_sequence
from drapebench.garments import make_garment
from drapebench.physics import Material
from drapebench.reference import SOLVERS, SimSettings, simulate_record

GARMENTS = {"tshirt": 0.013, "skirt": 0.0118}  # resolution (m) giving ~4k / ~5k vertices on Anny


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=6, help="timed sequence frames per scene")
    ap.add_argument("--body", default="anny")
    args = ap.parse_args()
    from drapebench.reference import scene  # noqa: F401  (puts warp's kernel cache in data/cache/warp before warp starts)
    import warp as wp  # only to ask for CUDA

    devices = ["cpu"] + (["cuda:0"] if wp.is_cuda_available() else [])
    body = load_body(args.body)
    seq = make_sequence("walk", args.frames, transition=2, seed=1000)
    print(f"body {args.body} ({body.n_vertices} vertices), walk {seq.n_frames} frames at {seq.fps:g} fps")
    print(f"{'solver':8} {'device':7} {'garment':7} {'V':>6} {'substeps x it':>13} {'s/frame':>8} {'frames/s':>8} {'setup s':>8}")
    for solver in SOLVERS:
        cfg = SimSettings.for_solver(solver)
        for device in devices:
            for kind, res in GARMENTS.items():
                g = make_garment(kind, body, resolution=res)
                run = lambda: simulate_record(g, seq, body, Material(), solver, cache=False, progress=False,  # noqa: E731
                                              settle_frames=1, device=device)
                run()  # warm-up: kernel compilation / loading
                rec = run()
                spf = rec.timings_s["sequence"] / seq.n_frames
                print(f"{solver:8} {device:7} {kind:7} {g.n_vertices:6d} {f'{cfg.substeps} x {cfg.iterations}':>13} "
                      f"{spf:8.3f} {1 / spf:8.2f} {rec.timings_s['setup']:8.2f}", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
