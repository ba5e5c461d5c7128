"""Scaling laws: drape ms/frame and the run's peak memory against the garment's vertex count and the
sequence length, with a fitted exponent per method (ms/frame ~ n^k, peak RSS ~ n^k).

Each point runs in a fresh process (its peak RSS is the process's): the tshirt on anny_lowres, the default
walk; the method drapes once on 5 frames (one-off set-up), then the whole sequence is draped, evaluated
(chunked, energies on) and written to an h5 file, as a run does. Methods: lbs, gaps and gensim with
untrained weights (inference costs the same as with trained ones; no training in the benchmark). Garment
vertex counts come from the garment resolution (2.5 cm to 0.65 cm: about 1k to 16k vertices); sequence lengths
100 to 10,000 frames (gensim, about 0.3 s per frame, to 1,000). The reference simulation is not swept (its
cost per frame is in benchmarks/bench_reference.py).

Run: python benchmarks/bench_scaling.py [--out reports/scaling]   (about 13 min on 2 idle cores; writes
<out>.md, <out>.csv and <out>.png)
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

RESOLUTIONS = (0.025, 0.018, 0.013, 0.009, 0.0065)  # m: garment vertex counts from about 1k to 16k
LENGTHS = {"lbs": (100, 1000, 10000), "gaps": (100, 1000, 10000), "gensim": (100, 300, 1000)}
DEFAULT_RESOLUTION = 0.015


def _method(name: str, body, garment):
    """An untrained method bound to ``body`` and set up for ``garment`` (inference costs as a trained one)."""
    import methods
    from drapebench.data import TrainData
    from drapebench.physics import Material

    m = methods.get(name)({})
    if name == "lbs":
        m.fit(TrainData(body=body, material=Material(), garment=garment, load_train=None, test_sequences=[]))
    else:
        m.bind(body, Material())
        if name == "gaps":
            m._setup(garment)
        else:
            m.net = m._new_net()
    return m


def _one(method: str, resolution: float, n_frames: int) -> None:
    """One point, in this process (the child): prints a JSON line."""
    import torch

    from drapebench.body import load_body, make_sequence
    from drapebench.garments import make_garment
    from drapebench.metrics import evaluate
    from drapebench.results import write_prediction

    torch.set_num_threads(1)
    body = load_body("anny_lowres")
    garment = make_garment("tshirt", body, resolution=resolution)
    seq = make_sequence("walk", n_frames, seed=0, transition=0)
    m = _method(method, body, garment)
    m.drape(garment, seq.slice(0, 5))  # one-off set-up (binding, caches)
    t = time.perf_counter()
    result = m.drape(garment, seq)
    drape_s = time.perf_counter() - t
    evaluate(garment, seq, body, result.vertices)
    with tempfile.TemporaryDirectory() as tmp:
        write_prediction(os.path.join(tmp, "prediction.h5"), result.vertices, garment.faces)
    print(json.dumps({"method": method, "n_vertices": garment.n_vertices, "n_frames": n_frames, "ms_per_frame": 1e3 * drape_s / n_frames}))


def _point(method: str, resolution: float, n_frames: int) -> dict:
    child = subprocess.Popen([sys.executable, __file__, "--one", method, str(resolution), str(n_frames)], stdout=subprocess.PIPE, text=True)
    out = child.stdout.read().strip().splitlines()
    _, status, usage = os.wait4(child.pid, 0)
    if status != 0:
        raise SystemExit(f"{method} at resolution {resolution}, {n_frames} frames: the child failed with status {status}")
    from drapebench.results import git_commit

    rec = {**json.loads(out[-1]), "peak_rss_gb": usage.ru_maxrss / 2**20, "resolution": resolution, "commit": git_commit()}
    print(f"{rec['method']:7s} {rec['n_vertices']:6d} vertices {n_frames:6d} frames: {rec['ms_per_frame']:9.3f} ms/frame, "
          f"peak RSS {rec['peak_rss_gb']:.2f} GB", flush=True)  # fmt: skip
    return rec


def exponent(x, y) -> float:
    """Least-squares slope k of log y = k log x + c."""
    return float(np.polyfit(np.log(np.asarray(x, float)), np.log(np.asarray(y, float)), 1)[0])


def _write(points, out: Path) -> None:
    import pandas as pd

    from drapebench.cache import atomic_write
    from drapebench.table_file import write_csv
    from drapebench.report import save_figure
    from drapebench.results import git_commit

    df = pd.DataFrame(points)
    by_v = df[df["sweep"] == "vertices"]
    by_t = df[df["sweep"] == "frames"]
    rows = []
    for m in dict.fromkeys(df["method"]):
        v, t = by_v[by_v["method"] == m], by_t[by_t["method"] == m]
        rows.append({"method": m,
                     "ms/frame ~ V^k": f"{exponent(v['n_vertices'], v['ms_per_frame']):.2f}",
                     "peak RSS ~ V^k": f"{exponent(v['n_vertices'], v['peak_rss_gb']):.2f}",
                     "ms/frame ~ T^k": f"{exponent(t['n_frames'], t['ms_per_frame']):.2f}",
                     "peak RSS ~ T^k": f"{exponent(t['n_frames'], t['peak_rss_gb']):.2f}",
                     "ms/frame at V = " + ", ".join(f"{int(n)}" for n in v["n_vertices"]): " / ".join(f"{x:,.0f}" if x >= 100 else f"{x:.3g}" for x in v["ms_per_frame"]),
                     "peak RSS (GB) at T frames": ", ".join(f"{x:.2f} ({int(n)})" for n, x in zip(t["n_frames"], t["peak_rss_gb"]))})  # fmt: skip
    commit = df["commit"].iloc[0] if "commit" in df else git_commit()
    scene = "Scene: garment tshirt; body anny_lowres; motion walk; one torch thread; no reference."
    produced = f"Produced by `python benchmarks/bench_scaling.py --out {out}` from runs at commit(s) {commit}"
    text = (f"# Scaling: drape time and peak memory against garment size and sequence length\n\nDrape time per frame and the run's peak memory (drape, chunked evaluation, h5 output; one fresh process "
            f"per point) against the garment's vertex count V (tshirt at {', '.join(f'{r * 100:g}' for r in RESOLUTIONS)} cm "
            f"resolution, 100 frames) and the sequence length T (tshirt at {DEFAULT_RESOLUTION * 100:g} cm). k: the fitted exponent "
            f"(1: linear; lower is better). Untrained weights (the same cost as trained ones).\n\n"
            f"{pd.DataFrame(rows).set_index('method').to_markdown()}\n\n"
            f"{scene}\n\n{produced} on {os.cpu_count()} CPU cores, nothing else running; `--redraw {out}.csv` redraws "
            f"this table and the plot from the measured points.\n")  # fmt: skip
    with atomic_write(out.with_suffix(".md"), "w") as f:
        f.write(text)
    write_csv(out.with_suffix(".csv"), [produced, scene], df, index=False)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 4, figsize=(17, 4))
    for ax, (sweep, x, y, xl, yl) in zip(axes, [("vertices", "n_vertices", "ms_per_frame", "garment vertices V", "drape time (ms/frame)"),
                                                ("vertices", "n_vertices", "peak_rss_gb", "garment vertices V", "peak RSS (GB)"),
                                                ("frames", "n_frames", "ms_per_frame", "sequence length T (frames)", "drape time (ms/frame)"),
                                                ("frames", "n_frames", "peak_rss_gb", "sequence length T (frames)", "peak RSS (GB)")]):  # fmt: skip
        part = df[df["sweep"] == sweep]
        for m in dict.fromkeys(part["method"]):
            g = part[part["method"] == m]
            ax.plot(g[x], g[y], "o-", label=f"{m} (k = {exponent(g[x], g[y]):.2f})")
        ax.set(xscale="log", yscale="log", xlabel=xl, ylabel=yl)
        ax.legend(fontsize=7)
        ax.grid(True, which="both", alpha=0.3)
    fig.suptitle("Scaling: tshirt on anny_lowres, walk (log-log; k = fitted exponent)")
    fig.tight_layout()
    save_figure(fig, out.with_suffix(".png"))


def main(out: Path) -> None:
    points = []
    for method in ("lbs", "gaps", "gensim"):
        points += [{**_point(method, r, 100), "sweep": "vertices"} for r in RESOLUTIONS]
        points += [{**_point(method, DEFAULT_RESOLUTION, n), "sweep": "frames"} for n in LENGTHS[method]]
    _write(points, out)
    print(out.with_suffix(".md").read_text())


if __name__ == "__main__":
    if sys.argv[1:2] == ["--one"]:
        _one(sys.argv[2], float(sys.argv[3]), int(sys.argv[4]))
    else:
        parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
        parser.add_argument("--out", type=Path, default=Path("outputs/scaling"), help="output path without suffix (reports/scaling to replace the committed one)")
        parser.add_argument("--redraw", type=Path, help="a CSV written by an earlier run: rewrite the table and plot from it, measure nothing")
        args = parser.parse_args()
        if args.redraw:
            import pandas as pd

            _write(pd.read_csv(args.redraw, comment="#").to_dict("records"), args.out)
        else:
            main(args.out)
