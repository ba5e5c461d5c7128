"""warp, set up once for the whole package: its kernel cache in ``data/cache/warp`` (kernels compile once
per machine), quiet logs, and ``wp.init()`` without the CUDA-driver warning a CPU-only machine would print.

``from drapebench.warp_env import wp`` instead of ``import warp``.
"""

from __future__ import annotations

import os
import sys

from drapebench.cache import cache_dir
from drapebench.extras import require

os.environ.setdefault("WARP_CACHE_PATH", str(cache_dir("warp")))

wp = require("warp", "the reference simulator (and the warp BVH path of the signed distance)")

wp.config.quiet = True
wp.config.log_level = wp.LOG_WARNING  # no per-module load/compile timing lines in run logs
if wp.config.kernel_cache_dir is None:  # warp imported elsewhere first: still keep its cache in the project
    wp.config.kernel_cache_dir = os.environ["WARP_CACHE_PATH"]


def cuda_driver_present() -> bool:
    """True when the NVIDIA driver library loads (what warp's native init looks for)."""
    import ctypes

    names = ("nvcuda.dll",) if sys.platform == "win32" else ("libcuda.so", "libcuda.so.1")
    for name in names:
        try:
            ctypes.CDLL(name)
            return True
        except OSError:
            continue
    return False


def init_warp() -> None:
    """``wp.init()``. Without a CUDA driver (a CPU-only machine) warp's native library prints a "could not
    find or load the NVIDIA CUDA driver" warning to stderr; it says nothing useful there, so it is dropped
    (only then: with a driver every message of warp's init is kept)."""
    if cuda_driver_present():
        wp.init()
        return
    sys.stderr.flush()
    saved = os.dup(2)
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), 2)
            wp.init()
    finally:
        os.dup2(saved, 2)


init_warp()

__all__ = ["cuda_driver_present", "init_warp", "wp"]
