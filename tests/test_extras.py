"""The core install: drapebench imports, trains a method and evaluates it with the heavy extras (warp, Newton,
rerun, pymeshlab, usd-core) unimportable; a missing extra is named with the install that brings it."""

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest

from drapebench.extras import EXTRAS, MissingExtra, require

ROOT = Path(__file__).resolve().parents[1]
HEAVY = ("warp", "newton", "rerun", "pymeshlab", "pxr")


def _without_extras() -> dict:
    """The environment of a subprocess in which the HEAVY packages do not import (tests/fixtures/no_extras)."""
    path = os.pathsep.join([str(ROOT / "tests" / "fixtures" / "no_extras"), str(ROOT), os.environ.get("PYTHONPATH", "")])
    return dict(os.environ, PYTHONPATH=path, DRAPEBENCH_BLOCK=",".join(HEAVY), DRAPEBENCH_PROGRESS="0", HYDRA_FULL_ERROR="1")


def test_every_heavy_package_has_an_extra():
    assert set(HEAVY) <= set(EXTRAS)


def test_a_missing_extra_is_named_with_its_install(monkeypatch):
    from drapebench.viz import require_rerun

    for name in ("rerun", "rerun.blueprint"):  # rerun-sdk not installed (an earlier test may have imported both)
        monkeypatch.setitem(sys.modules, name, None)
    with pytest.raises(MissingExtra, match=r"^viz=rerun .* needs rerun-sdk, which is not installed: pip install 'drapebench\[viz\]'"):
        require_rerun("rerun.blueprint")
    monkeypatch.setitem(sys.modules, "pymeshlab", None)
    with pytest.raises(MissingExtra, match=r"drapebench\[mesh\]"):
        require("pymeshlab", "making a garment")


def test_an_installed_package_that_fails_to_import_keeps_its_own_error(tmp_path, monkeypatch):
    pkg = tmp_path / "pymeshlab"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("import a_library_pymeshlab_links_against\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, "pymeshlab", raising=False)
    with pytest.raises(ModuleNotFoundError, match="a_library_pymeshlab_links_against") as err:
        require("pymeshlab", "making a garment")
    assert not isinstance(err.value, MissingExtra)


def test_the_package_imports_and_gaps_trains_and_is_evaluated_without_the_extras(tmp_path, body_lowres):
    from drapebench.garments import make_garment

    make_garment("tshirt", body_lowres)  # made with pymeshlab (the mesh extra) once, then read from the data cache
    env = _without_extras()
    probe = ("import sys, drapebench, drapebench.experiment, drapebench.metrics, methods.gaps, methods.gensim, methods.vae; "
             f"print(sorted(m for m in sys.modules if m.split('.')[0] in {HEAVY!r}))")  # fmt: skip
    p = subprocess.run([sys.executable, "-c", probe], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr[-3000:]
    assert p.stdout.strip() == "[]"
    out = tmp_path / "gaps"
    scene = ["method=gaps", "method.params.canonical=template", "train.steps=2", "body=anny_lowres", "motion.n_frames=4",
             "motion.transition=1", "viz=none"]  # fmt: skip
    p = subprocess.run([sys.executable, str(ROOT / "run.py"), *scene, f"hydra.run.dir={out}"], cwd=tmp_path, env=env,
                       capture_output=True, text=True, timeout=600)  # fmt: skip
    assert p.returncode == 0, p.stderr[-3000:]
    rec = json.loads((out / "metrics.json").read_text())
    assert rec["method"] == "gaps" and rec["train_s"] > 0 and all(math.isfinite(rec[k]) for k in ("eps_e", "eps_c", "penetration_mm"))
    assert "take the exact libigl path" in (out / "run.log").read_text()  # eps_c without warp's BVH
    assert (out / "losses.csv").read_text().strip().count("\n") == 2  # train.steps=2 as typed: not GAPS's own schedule
    settings = json.loads((out / "settings.json").read_text())  # the parameters resolved: gaps.yaml leaves most to GapsParams
    assert settings["train"]["window"] == 3 and settings["rbf_k"] == 0.25 and settings["canonical"] == "template"
    assert "hidden_init_std" not in (out / "config.yaml").read_text() and settings["train"]["hidden_init_std"] == 0.1
    p = subprocess.run([sys.executable, str(ROOT / "run.py"), *scene[:1], "viz=rerun", f"hydra.run.dir={tmp_path / 'viz'}"],
                       cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)  # fmt: skip
    assert p.returncode != 0 and "pip install 'drapebench[viz]'" in p.stderr
    assert not (tmp_path / "viz" / "losses.csv").exists()  # refused before training
