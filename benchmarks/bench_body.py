"""Body forward, sequence generation and h5 I/O timings (CPU, float32). Run: python benchmarks/bench_body.py"""

import tempfile
from pathlib import Path

import torch
from timing import best

from drapebench.body import BodySequence, load_body, make_sequence


def main():
    print(f"torch {torch.__version__}, threads {torch.get_num_threads()}")
    seq = make_sequence("walk", n_frames=285, seed=0, betas=torch.randn(10))
    print(f"sequence generation (walk, {seq.n_frames} frames): {best(lambda: make_sequence('walk', 285, seed=0)) * 1e3:.1f} ms")
    for name in ("anny", "anny_lowres"):
        body = load_body(name)
        b = seq.betas[None]
        with torch.no_grad():
            t = best(lambda: body.forward(b, seq.poses, seq.trans))
        print(f"body forward {name:12s} V={body.n_vertices:6d}: {seq.n_frames} frames in {t * 1e3:7.1f} ms ({t / seq.n_frames * 1e3:.3f} ms/frame)")
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "s.h5"
        tw = best(lambda: seq.save(path))
        tr = best(lambda: BodySequence.load(path))
        print(f"h5 write {tw * 1e3:.1f} ms, read {tr * 1e3:.1f} ms ({path.stat().st_size / 1e3:.0f} kB)")


if __name__ == "__main__":
    main()
