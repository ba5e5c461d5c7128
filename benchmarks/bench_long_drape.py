"""Peak memory (RSS) and the longest silence of long lbs drapes: ``run.py method=lbs motion=random`` with a tshirt
(2,796 vertices) on anny_lowres, ``reference=none viz=none tracker=none``, walking in place (``motion.params.speed=0``:
at its 1.2 m/s a 100,000-frame random walk can roam past the 1 km that float32 positions are measured to, and the
run is refused), each in a fresh process whose output is a
pipe (so its progress goes to the log, a line at most every 5 s), on a random motion of a new seed (so that no cached
evaluation is reused). Prints per length the child's peak RSS, the
drape's size (what prediction.h5 holds, float32), the longest time between two lines of output (from the first to
the process's end) and the line after that gap, and the run's total time.

Run: python benchmarks/bench_long_drape.py [n_frames ...]     (default 1000 10000; nice -n 10 on a shared machine)
"""

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SCENE = ["method=lbs", "motion=random", "body=anny_lowres", "garment=tshirt", "reference=none", "viz=none", "tracker=none",
         "+motion.params.speed=0.0"]


def one(n_frames: int, extra: list[str]) -> dict:
    """Run the scene for ``n_frames`` frames in a child process; its peak RSS (bytes), drape size (bytes), longest
    silence (s) with the line that ended it, and the run's metrics record."""
    env = {k: v for k, v in os.environ.items() if k not in ("CI", "DRAPEBENCH_PROGRESS")}  # progress lines in the log
    with tempfile.TemporaryDirectory() as tmp:
        seed = int.from_bytes(os.urandom(3), "little")  # a motion never scored before: no cached evaluation
        cmd = [sys.executable, str(ROOT / "run.py"), *SCENE, f"motion.n_frames={n_frames}", f"motion.seed={seed}", *extra, f"hydra.run.dir={tmp}/run"]
        child = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        last, gap, after = None, 0.0, ""
        for line in child.stdout:
            now = time.monotonic()
            if last is not None and now - last > gap:
                gap, after = now - last, line.strip()
            last = now
        if time.monotonic() - last > gap:
            gap, after = time.monotonic() - last, "(the end of the process)"
        _, status, usage = os.wait4(child.pid, 0)
        if status != 0:
            raise SystemExit(f"{n_frames} frames: run.py failed (status {status}); last line: {after}")
        record = json.loads((Path(tmp) / "run" / "metrics.json").read_text())
    drape = record["n_frames"] * record["n_vertices"] * 3 * 4
    return {"peak_rss": usage.ru_maxrss * 1024, "drape": drape, "gap_s": gap, "after": after, "record": record}


def main(frames: list[int], extra: list[str]) -> None:
    print(f"lbs tshirt on anny_lowres, motion=random {' '.join(extra)}")
    for n in frames:
        r = one(n, extra)
        rec = r["record"]
        print(f"{n:>7} frames: peak RSS {r['peak_rss'] / 1e9:.3f} GB, drape {r['drape'] / 1e9:.3f} GB; longest silence "
              f"{r['gap_s']:.1f} s (before: {r['after'][:100]}); total {rec['total_s']:.0f} s (drape {rec['ms_per_frame']:.2f} "
              f"ms/frame, metrics {rec['eval_s']:.0f} s), eps_e {rec['eps_e']:.4f}", flush=True)  # fmt: skip


if __name__ == "__main__":
    args = sys.argv[1:]
    main([int(a) for a in args if a.isdigit()] or [1000, 10000], [a for a in args if not a.isdigit()])
