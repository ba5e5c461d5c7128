"""Body sequence figures (CPU, float32): generation per motion, posing 300 frames (full and lowres),
h5 write/read, dataset build. Run: python benchmarks/bench_sequences.py"""

import tempfile
import time
from pathlib import Path

import torch
from timing import best

from drapebench.body import MOTIONS, BodySequence, load_body, make_sequence
from drapebench.body.dataset import DATASETS, build_dataset, load_dataset

T = 300  # frames, transition included


def main():
    print(f"torch {torch.__version__}, threads {torch.get_num_threads()}")
    make_sequence("walk", 10)  # load the canonical body used for ground contact once
    for motion in MOTIONS:
        t = best(lambda m=motion: make_sequence(m, T - 15, seed=0), repeat=3)
        print(f"generate {motion:10s} {T} frames: {t * 1e3:6.1f} ms")
    seq = make_sequence("walk", T - 15, seed=0, betas=torch.randn(10))
    for name in ("anny", "anny_lowres"):
        body = load_body(name)

        rep = 1 if body.n_vertices > 5000 else 3
        tv = best(lambda b=body: BodySequence(**_fields(seq)).vertices(b), repeat=rep)
        tn = best(lambda b=body: BodySequence(**_fields(seq)).vertex_normals(b), repeat=rep)
        tt = best(lambda b=body: BodySequence(**_fields(seq)).transforms(b), repeat=3)
        print(f"pose {name:12s} V={body.n_vertices:6d}, {T} frames: vertices {tv * 1e3:7.1f} ms ({tv / T * 1e3:.3f} ms/frame), "
              f"+normals {tn * 1e3:7.1f} ms, transforms only {tt * 1e3:5.1f} ms")  # fmt: skip
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "s.h5"
        tw, tr = best(lambda: seq.save(path)), best(lambda: BodySequence.load(path))
        print(f"h5 sequence ({T} frames): write {tw * 1e3:.1f} ms, read {tr * 1e3:.1f} ms ({path.stat().st_size / 1e3:.0f} kB)")
        spec = DATASETS["train_small"]
        t0 = time.perf_counter()
        dpath = build_dataset(spec, path=Path(d) / "train_small.h5")
        t1 = time.perf_counter()
        build_dataset(spec, path=dpath)
        t2 = time.perf_counter()
        seqs = load_dataset(dpath)
        t3 = time.perf_counter()
        print(f"dataset train_small ({len(seqs)} sequences x {seqs[0].n_frames} frames, {dpath.stat().st_size / 1e3:.0f} kB): "
              f"build {t1 - t0:.2f} s, up-to-date check {(t2 - t1) * 1e3:.1f} ms, load {(t3 - t2) * 1e3:.1f} ms")  # fmt: skip


def _fields(seq):
    """Constructor arguments of a sequence (a fresh object has an empty posing cache)."""
    return dict(name=seq.name, motion=seq.motion, betas=seq.betas, poses=seq.poses, trans=seq.trans, fps=seq.fps,
                seed=seq.seed, split=seq.split, n_transition=seq.n_transition, params=seq.params)  # fmt: skip


if __name__ == "__main__":
    main()
