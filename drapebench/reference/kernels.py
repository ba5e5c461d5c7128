"""Compile the warp kernels of a vbd reference simulation (they include the body distance queries of the
metrics), once per machine, into the kernel cache (``$WARP_CACHE_PATH``, by default ``data/cache/warp``).

warp compiles a kernel module the first time one of its kernels runs: about a minute on 2 CPU cores
for what a vbd simulation launches, after which every process loads the binaries in milliseconds.
``make test`` runs ``python -m drapebench.reference.kernels`` once per installed environment, before the
first test session, so that minute is paid at set-up rather than inside whichever test simulates first.
The simulation is the smallest real one: two frames of a coarse skirt on the low-res body, with its
garment, topology and result kept in a temporary folder (the data cache is left as it was).
"""

from __future__ import annotations

import os
import tempfile
import time

import drapebench.warp_env  # noqa: F401  fixes the kernel cache folder before the data folder is redirected below


def compile_kernels() -> float:
    """Run a two-frame vbd simulation so that every warp module it uses is compiled into the kernel
    cache. Returns the seconds taken: about 60-90 on 2 CPU cores with an empty kernel cache, a few
    seconds with a full one."""
    from drapebench.body import load_body, make_sequence
    from drapebench.garments import make_garment
    from drapebench.reference import simulate

    t0 = time.perf_counter()
    saved = os.environ.get("DRAPEBENCH_DATA")
    with tempfile.TemporaryDirectory(prefix="drapebench-kernels-") as tmp:
        os.environ["DRAPEBENCH_DATA"] = tmp
        try:
            body = load_body("anny_lowres")
            garment = make_garment("skirt", body, resolution=0.03)
            seq = make_sequence("walk", 2, transition=1)
            simulate(garment, seq, body, solver="vbd", settle_frames=1, substeps=2, iterations=3, retry_substeps=[],
                     progress=False)  # fmt: skip
        finally:
            if saved is None:
                os.environ.pop("DRAPEBENCH_DATA", None)
            else:
                os.environ["DRAPEBENCH_DATA"] = saved
    return time.perf_counter() - t0


if __name__ == "__main__":
    import argparse

    argparse.ArgumentParser(description="Compile the reference simulator's warp kernels once per environment "
                            "(about a minute on 2 cores; cached in data/cache/warp). Takes no arguments.").parse_args()  # fmt: skip
    print("== compiling the warp kernels of the reference simulator (once per environment, about a minute "
          "on 2 cores; cached in data/cache/warp)", flush=True)  # fmt: skip
    print(f"== kernels ready in {compile_kernels():.0f} s", flush=True)
