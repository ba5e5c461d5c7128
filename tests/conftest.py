"""Shared fixtures: baked bodies are loaded once per session."""

import os

import pytest
import torch

os.environ.setdefault("DRAPEBENCH_PROGRESS", "0")


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
