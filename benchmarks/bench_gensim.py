"""GenSim inference cost per frame on the CPU, by stage: motion-aware ARAP (handles, 10 ARAP steps with the
collision push) and PEN (8 message-passing steps), for a ~2.8k-vertex skirt on the full anny body, 30 frames of
kick (the paper: about 600 ms ARAP + 300 ms PEN for a 3000-vertex skirt on a GPU; the target here: at most
50 ms per frame on 2 idle CPU cores). Timing does not depend on trained values (PEN is freshly initialised).

Every configuration runs in a process of its own (its warm-up, torch.compile included, outside the timing),
the configurations in turn for ``--rounds`` rounds, and each prints its best round:

- ``ms/frame``: wall time per frame with ``--threads`` torch threads (0: every core) and the configuration's
  ``workers``;
- ``core-ms/frame``: the process's CPU time per frame in the same runs (every thread together: the work, which
  depends less than the wall time on other jobs sharing the cores);
- the stages' shares of the frame (setup, arap, pen, pose).

``--baseline REV`` adds the code of a git revision (exported to a temporary directory, run on the same data
directory) as the first row of each thread count, so old and new are measured side by side (ratios against it); ``--configs`` picks the configurations
(``method.params`` as JSON). The machine's load average is printed before and after: on shared cores, compare
rows of one run, not numbers across runs.

Run: python benchmarks/bench_gensim.py --baseline be4c961
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CONFIGS = {  # name: method.params of the configuration
    "default": {},
    "two workers": {"workers": 2},
    "vertex contact": {"contact": "vertex"},
    "compiled": {"pen_compile": True},
    "compiled bf16": {"pen_compile": True, "pen_precision": "bf16"},
    "compiled, two workers": {"pen_compile": True, "workers": 2},
    "compiled bf16, two workers": {"pen_compile": True, "pen_precision": "bf16", "workers": 2},
}


def measure(params: dict, runs: int, n_frames: int, threads: int | None = None) -> dict:
    """Best of ``runs`` drapes of the bench skirt on ``n_frames`` frames of kick (after a warm-up drape) on
    ``threads`` torch threads (None: torch's default): wall ms per frame by stage and in all, and CPU ms per frame."""
    import torch

    if threads is not None:
        torch.set_num_threads(threads)
    import methods
    from drapebench.body import load_body, make_sequence
    from drapebench.garments import make_garment
    from drapebench.physics import Material

    body = load_body("anny")
    g = make_garment("skirt", body)  # ~2.8k vertices at the default 15 mm resolution
    m = methods.get("gensim")(params)
    m.bind(body, Material())
    torch.manual_seed(0)
    m.fabric, m.net = {"mean": 4.4e-4, "std": 8.1e-4}, m._new_net()
    seq = make_sequence("kick", n_frames, seed=0)
    m.drape(g, seq)  # warm-up: KD-trees, warp, torch kernels, torch.compile
    best = None
    for _ in range(runs):
        w0, c0 = time.perf_counter(), time.process_time()
        r = m.drape(g, seq)
        wall, cpu = time.perf_counter() - w0, time.process_time() - c0
        if best is None or wall < best["wall"]:
            best = {"wall": wall, "cpu": cpu, "stages": dict(r.timings_ms), "n": r.vertices.shape[0]}
    n = best["n"]
    return {"vertices": g.n_vertices, "frames": n, "ms": best["wall"] * 1e3 / n,
            "core_ms": best["cpu"] * 1e3 / n, "stages": {k: v / n for k, v in best["stages"].items()}}  # fmt: skip


def run_config(tree: Path, params: dict, runs: int, n_frames: int, threads: int | None) -> dict:
    """:func:`measure` in a fresh process importing the code of ``tree`` (on this repository's data directory)."""
    env = {**os.environ, "PYTHONPATH": str(tree), "DRAPEBENCH_DATA": os.environ.get("DRAPEBENCH_DATA", str(ROOT / "data"))}
    code = (f"import json, sys; sys.path.insert(0, {str(tree)!r}); sys.path.insert(0, {str(ROOT / 'benchmarks')!r}); import bench_gensim; "
            f"print('RESULT', json.dumps(bench_gensim.measure(json.loads({json.dumps(json.dumps(params))}), {runs}, {n_frames}, {threads})))")  # fmt: skip
    out = subprocess.run([sys.executable, "-c", code], cwd=tree, env=env, capture_output=True, text=True)
    lines = [line for line in out.stdout.splitlines() if line.startswith("RESULT ")]
    if out.returncode != 0 or not lines:
        raise RuntimeError(f"bench_gensim: the run in {tree} with {params} failed:\n{out.stderr[-3000:]}")
    return json.loads(lines[-1][len("RESULT ") :])


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--baseline", help="a git revision measured beside this code (e.g. be4c961)")
    parser.add_argument("--configs", nargs="*", default=list(CONFIGS), help=f"configurations of this code: {', '.join(CONFIGS)}")
    parser.add_argument("--rounds", type=int, default=2, help="rounds over the configurations (each prints its best)")
    parser.add_argument("--runs", type=int, default=2, help="timed drapes per configuration and round")
    parser.add_argument("--frames", type=int, default=30, help="frames of kick after the transition")
    parser.add_argument("--threads", type=int, nargs="*", default=[0, 1], help="torch threads of each configuration's runs (0: torch's default, "
                        "every core; 1: one thread, with workers 1 the work per frame alone)")  # fmt: skip
    args = parser.parse_args()
    unknown = sorted(set(args.configs) - set(CONFIGS))
    if unknown:
        parser.error(f"unknown --configs {unknown}; valid: {sorted(CONFIGS)}")
    rows = [(name, ROOT, CONFIGS[name]) for name in args.configs]
    rows = [(f"{name}, {t or 'all'} thr", tree, params, t or None) for t in args.threads for name, tree, params in rows]
    with tempfile.TemporaryDirectory(prefix="bench_gensim_") as tmp:
        if args.baseline:
            archive = subprocess.run(["git", "-C", str(ROOT), "archive", args.baseline], capture_output=True, check=True).stdout
            subprocess.run(["tar", "-x", "-C", tmp], input=archive, check=True)
            for i, t in enumerate(args.threads):
                rows.insert(i * (len(args.configs) + 1), (f"{args.baseline}, {t or 'all'} thr", Path(tmp), {}, t or None))
        print(f"load average before: {os.getloadavg()[0]:.2f} (1 min), {os.cpu_count()} cores", flush=True)
        best: dict[str, dict] = {}
        for _ in range(args.rounds):
            for name, tree, params, threads in rows:
                r = run_config(tree, params, args.runs, args.frames, threads)
                print(f"  ({name}: {r['ms']:.1f} ms/frame, {r['core_ms']:.1f} core-ms/frame, load {os.getloadavg()[0]:.1f})", flush=True)
                if name not in best or r["ms"] < best[name]["ms"]:
                    best[name] = r
        print(f"load average after: {os.getloadavg()[0]:.2f} (1 min)")
    first = next(iter(best.values()))
    print(f"gensim skirt ({first['vertices']} vertices) on anny, {first['frames']} frames of kick, cpu; "
          f"best of {args.rounds} rounds x {args.runs} drapes")  # fmt: skip
    for i, (name, _, params, _) in enumerate(rows):
        r = best[name]
        ref = best[rows[i - i % (len(rows) // len(args.threads))][0]]  # the first row of the same thread count
        shares = ", ".join(f"{k} {100 * v / max(sum(r['stages'].values()), 1e-9):.0f} %" for k, v in r["stages"].items())
        print(f"  {name:<22} {r['ms']:7.1f} ms/frame ({r['ms'] / ref['ms']:.2f}x)  {r['core_ms']:7.1f} core-ms/frame "
              f"({r['core_ms'] / ref['core_ms']:.2f}x)  [{shares}]  {json.dumps(params)}")  # fmt: skip


if __name__ == "__main__":
    main()
