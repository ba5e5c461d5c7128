"""Garment factory time (cold, i.e. no cached garment, and cached) for a ~5k-vertex garment.

Run: python benchmarks/bench_garments.py
"""

import time

from drapebench.body import load_body
from drapebench.garments import make_garment


def main():
    body = load_body("anny")
    make_garment("tshirt", body)  # warms the body's SDF grid cache (computed once per body shape)
    for kind, res in (("dress", 0.015), ("pants", 0.013), ("tshirt", 0.012)):
        t = time.perf_counter()
        g = make_garment(kind, body, resolution=res, cache=False)
        cold = time.perf_counter() - t
        make_garment(kind, body, resolution=res)
        t = time.perf_counter()
        make_garment(kind, body, resolution=res)
        warm = time.perf_counter() - t
        print(f"{kind:7s} {g.n_vertices:5d} vertices: factory {cold:.1f} s (SDF grid cached), cached garment {warm * 1e3:.0f} ms")


if __name__ == "__main__":
    main()
