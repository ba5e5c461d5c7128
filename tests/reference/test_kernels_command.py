"""``python -m drapebench.reference.kernels`` (make test's compile step) answers --help instead of compiling."""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_help_prints_the_usage_and_compiles_nothing():
    done = subprocess.run([sys.executable, "-m", "drapebench.reference.kernels", "--help"], cwd=ROOT, capture_output=True,
                          text=True, timeout=120)  # fmt: skip
    assert done.returncode == 0 and done.stdout.startswith("usage:") and "compiling" not in done.stdout
    wrong = subprocess.run([sys.executable, "-m", "drapebench.reference.kernels", "--jobs", "2"], cwd=ROOT, capture_output=True,
                           text=True, timeout=120)  # fmt: skip
    assert wrong.returncode == 2 and "unrecognized arguments: --jobs 2" in wrong.stderr and "compiling" not in wrong.stdout
