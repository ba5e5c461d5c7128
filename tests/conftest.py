"""Shared fixtures: a temporary data directory for the whole session; baked bodies are loaded once per session."""

import os

import pytest
import torch

from drapebench.cache import PROJECT_ROOT

os.environ.setdefault("DRAPEBENCH_PROGRESS", "0")
# Third-party build caches (compiled warp kernels, anny's assets) stay where the Makefile puts them, so
# the temporary data directory below does not make every session recompile or download them.
os.environ.setdefault("WARP_CACHE_PATH", str(PROJECT_ROOT / "data" / "cache" / "warp"))
os.environ.setdefault("ANNY_CACHE_DIR", str(PROJECT_ROOT / "data" / "cache" / "anny"))


@pytest.fixture(scope="session", autouse=True)
def _data_dir(tmp_path_factory):
    """Point DRAPEBENCH_DATA at a temporary folder: tests never read or write the project's data/cache
    (the shipped bodies in data/bodies are found next to the package, not through it)."""
    old = os.environ.get("DRAPEBENCH_DATA")
    os.environ["DRAPEBENCH_DATA"] = str(tmp_path_factory.mktemp("data"))
    yield
    if old is None:
        os.environ.pop("DRAPEBENCH_DATA", None)
    else:
        os.environ["DRAPEBENCH_DATA"] = old


@pytest.fixture(scope="session")
def body_lowres():
    from drapebench.body import load_body

    return load_body("anny_lowres")


@pytest.fixture(scope="session")
def body_full():
    from drapebench.body import load_body

    return load_body("anny")


@pytest.fixture(autouse=True)
def _deterministic():
    torch.manual_seed(0)
