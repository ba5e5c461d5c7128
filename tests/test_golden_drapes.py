"""Every method drapes the small scene of tests/golden_drapes.py as it did when tests/fixtures/golden_drapes.npz was
made (the commit is recorded inside it): a guard for changes that are meant to leave the methods' output alone
(refactors of the configuration, the pipeline, the structure). lbs, pbs, gaps, gaps_optimum, gensim, gensim_optimum and
the VAE are built from the runs' own composed configs, shrunk (see tests/golden_drapes.py); the VAE with stand-in body
fields, as fitting the real diffused body and SDF takes minutes.

When a method's output is MEANT to change (a new default, a fixed bug), regenerate the file deliberately, from the
repository root, and say why in the commit:

    python -m tests.golden_drapes
"""

import numpy as np
import pytest

from tests.golden_drapes import GOLDEN, SHRUNK, drapes

TOLERANCE_M = 1e-5  # float32 noise on a drape of about 1 m
# Two methods amplify float32 noise: pbs's simulation over its frames, and the VAE's projection (3 Adam steps a frame,
# which turn the noise of near-zero gradients into whole steps; without them it moves 3e-8 m, but then its drape is
# lbs's). The same code on another CPU type moved pbs by 0.094 mm at most (1.9e-7 m on average) and the VAE by 0.40 mm
# (3.5e-5 m on average); MKL's AVX2 path instead of its AVX-512 one on one machine, by 0.015 / 0.42 mm (measured
# 2026-11-29). Their (mean, max) tolerances are about 4x that noise. pbs's still catches a change of its solver
# (iterations or substeps: 9e-3 / 1.5e-2 m on average); the VAE's only changes above its noise (its drape departs from
# lbs's by 4.0e-4 m on average; a doubled Laplacian or no collision term in its loss moves this scene's VAE by 2.6e-6 m
# at most, measured without the projection steps).
NOISY_M = {"pbs": (1e-6, 5e-4), "vae": (1.5e-4, 2e-3)}


@pytest.fixture(scope="module")
def golden():
    return np.load(GOLDEN)


@pytest.fixture(scope="module")
def current():
    return drapes()


def test_the_file_holds_every_method_and_its_commit(golden):
    assert set(golden.files) == {"commit", *SHRUNK}
    assert len(str(golden["commit"])) >= 40


@pytest.mark.parametrize("name", list(SHRUNK))
def test_each_method_drapes_as_before(name, golden, current):
    x, before = current[name], golden[name]
    assert x.shape == before.shape and np.isfinite(x).all()
    mean_tol, max_tol = NOISY_M.get(name, (TOLERANCE_M, TOLERANCE_M))
    moved = np.abs(x - before)
    assert moved.mean() < mean_tol and moved.max() < max_tol, (
        f"{name}'s drape moved by up to {moved.max() * 1e3:.4f} mm ({moved.mean() * 1e3:.5f} mm on average) since {golden['commit']} "
        f"(meant? regenerate: python -m tests.golden_drapes)")  # fmt: skip


def test_the_drapes_are_the_methods_own(golden):
    """Each method's stored drape differs from the skinning's (lbs), so comparing it tests that method's code."""
    for name in SHRUNK:
        if name != "lbs":
            assert np.abs(golden[name] - golden["lbs"]).max() > 1e-4, name
