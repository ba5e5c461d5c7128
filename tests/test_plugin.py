"""A method is one folder and one config file: a toy method written into a temporary folder (its package, with the
declaration of its diagnostic, and its ``conf/method/<name>.yaml``, nothing in this repository changed) runs
through run.py and into a report table, which reads its diagnostic's declaration."""

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

TOY = '''
"""The template lifted by ``lift`` m, moved with the root translation: a method of one file."""
import torch

from methods.base import DrapeResult, DrapingMethod, FitReport


class Lifted(DrapingMethod):
    name = "toy"
    generic = True

    def __init__(self, cfg=None):
        super().__init__(cfg)
        self.lift = float(self.cfg.get("lift", 0.0))

    def fit(self, data, train_cfg=None):
        self.bind(data.body, data.material)
        return FitReport()

    def drape(self, garment, seq):
        self._require_bound()
        x = garment.vertices.to(self.body.dtype) + torch.tensor([0.0, 0.0, self.lift], dtype=self.body.dtype)
        return DrapeResult(x[None] + seq.trans[:, None].to(x.dtype), {"copy": 0.0})

    def diagnostics(self, garment, seq, result):
        return {"toy_lift_mm": 1e3 * self.lift}
'''

TOY_METRICS = '''
"""What the toy's diagnostic means."""
from drapebench.metric_info import MetricInfo

METRICS = {"toy_lift_mm": MetricInfo("lift (mm)", "mm", "neither", "how far the toy lifts the template")}
'''

TOY_TABLES = '''
"""The toy's committed table: its lift and the edge strain beside the skinning zero point."""
from drapebench.table_specs import Sweep, TableSpec

TABLES = [TableSpec("toy_lift", "the toy's lift", ("toy_lift_mm", "eps_e"), sweeps=(Sweep("baseline", ("method=toy",)),))]
'''

READ_BACK = """
from drapebench.report import collect
from drapebench.results import legend, metric_label
collect([{out!r}])
from drapebench.table_specs import spec
print(metric_label("toy_lift_mm"), "|", legend(["toy_lift_mm"]), "|", spec("toy_lift").command())
"""


def test_a_method_from_a_folder_of_its_own_runs_through_run_py_and_the_report(tmp_path):
    (tmp_path / "toymethod").mkdir()
    (tmp_path / "toymethod" / "__init__.py").write_text(textwrap.dedent(TOY))
    (tmp_path / "toymethod" / "metrics.py").write_text(textwrap.dedent(TOY_METRICS))
    (tmp_path / "toymethod" / "tables.py").write_text(textwrap.dedent(TOY_TABLES))
    (tmp_path / "conf" / "method").mkdir(parents=True)
    (tmp_path / "conf" / "method" / "toy.yaml").write_text("name: toy\nimpl: toymethod:Lifted\nparams: {lift: 0.01}\n")
    env = dict(os.environ, DRAPEBENCH_PROGRESS="0", HYDRA_FULL_ERROR="1", CI="1",
               PYTHONPATH=os.pathsep.join([str(tmp_path), str(ROOT), os.environ.get("PYTHONPATH", "")]))  # fmt: skip
    out = tmp_path / "run"
    p = subprocess.run([sys.executable, str(ROOT / "run.py"), "method=toy", f"hydra.searchpath=[file://{tmp_path / 'conf'}]",
                        "body=anny_lowres", "motion.n_frames=4", "motion.transition=1", "viz=none", f"hydra.run.dir={out}"],
                       cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)  # fmt: skip
    assert p.returncode == 0, p.stderr[-3000:]
    record = json.loads((out / "metrics.json").read_text())
    assert record["method"] == "toy" and record["toy_lift_mm"] == pytest.approx(10.0)
    assert record["eps_e"] == pytest.approx(0.0, abs=1e-4)  # the template moved rigidly: no edge changes length
    p = subprocess.run([sys.executable, "-m", "drapebench.report", str(out), "--table", "baseline", "--out", str(tmp_path / "table")],
                       cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)  # fmt: skip
    assert p.returncode == 0, p.stderr[-3000:]
    rows = [line for line in (tmp_path / "table.md").read_text().splitlines() if line.startswith("| toy")]
    assert len(rows) == 1, (tmp_path / "table.md").read_text()
    p = subprocess.run([sys.executable, "-m", "drapebench.report", str(out), "--table", "toy_lift", "--out", str(tmp_path / "toy")],
                       cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)  # the table the toy's tables.py declares  # fmt: skip
    assert p.returncode == 0, p.stderr[-3000:]
    text = (tmp_path / "toy.md").read_text()
    assert "lift (mm)" in text and "| toy" in text and "10" in text.split("| toy")[1].split("\n")[0], text
    p = subprocess.run([sys.executable, "-c", READ_BACK.format(out=str(out))], cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr[-3000:]
    assert p.stdout.strip() == ("lift (mm) | Legend: toy_lift_mm: how far the toy lifts the template (mm, neither). Definitions: docs/metrics.md."
                                " | python -m drapebench.reproduce --tables toy_lift")


def test_an_import_path_that_is_not_a_method_is_refused_naming_it():
    import methods

    with pytest.raises(ImportError, match="method.impl='nowhere.at_all:Thing'"):
        methods.get("nowhere.at_all:Thing")
    with pytest.raises(TypeError, match="not a methods.base.DrapingMethod subclass"):
        methods.get("methods.base:DrapeResult")
    assert methods.get("methods.lbs:LBSMethod") is methods.get("lbs")


# (files, the word a hit is part of): the only places the library may spell a registered method's name, each because
# the word is not the method there
NAME_ALLOWED = {
    # linear blend skinning, the body model's posing (drapebench/body/lbs.py) that bodies, motions and the reference
    # simulator call: the technique the skinning baseline method is named after, not the method
    ("drapebench/body/*", "lbs"), ("drapebench/body/*", "inverse_lbs"), ("drapebench/body/*", "lbs_chunk"),
    ("drapebench/reference/simulator.py", "lbs"),
    # a training dataset's name, which the committed runs' configs and checkpoint keys carry (renaming it retrains)
    ("drapebench/body/dataset.py", "train_gaps"),
    # the scoreboard's rules, which reports/claims.md carries verbatim, name the skinning row as an example control
    ("drapebench/claims.py", "lbs"),
}


def method_name_hits(root: Path = ROOT) -> list[str]:
    """``path:line: word`` of every word in ``drapebench/`` that holds a registered method's name (underscores and
    dots count as word boundaries: ``gaps_loss`` holds ``gaps``; any case), except :data:`NAME_ALLOWED`."""
    import fnmatch
    import re

    import methods

    names = sorted(methods.available(), key=len, reverse=True)
    pattern = re.compile(rf"(?<![a-z0-9])(?:{'|'.join(map(re.escape, names))})(?![a-z0-9])", re.I)
    hits = []
    for path in sorted((root / "drapebench").rglob("*.py")):
        rel = path.relative_to(root).as_posix()
        for n, line in enumerate(path.read_text().splitlines(), 1):
            for m in pattern.finditer(line):
                a, b = m.start(), m.end()
                while a > 0 and (line[a - 1].isalnum() or line[a - 1] == "_"):
                    a -= 1
                while b < len(line) and (line[b].isalnum() or line[b] == "_"):
                    b += 1
                word = line[a:b].lower()
                if not any(fnmatch.fnmatch(rel, f) and word == w for f, w in NAME_ALLOWED):
                    hits.append(f"{rel}:{n}: {line[a:b]}")
    return hits


def test_the_library_names_no_method():
    hits = method_name_hits()
    assert not hits, "drapebench/ names a method (its declarations belong in methods/<name>/, a paper is cited by its authors):\n" + "\n".join(hits)


def test_the_method_name_finder_finds_a_name(tmp_path):
    (tmp_path / "drapebench" / "body").mkdir(parents=True)
    (tmp_path / "drapebench" / "a.py").write_text('x = "GenSim\'s PEN"\ny = metrics["gaps_loss"]\nz = lbs(p)\n')
    (tmp_path / "drapebench" / "body" / "b.py").write_text("z = lbs(p)  # the skinning, allowed here\n")
    assert method_name_hits(tmp_path) == ["drapebench/a.py:1: GenSim", "drapebench/a.py:2: gaps_loss", "drapebench/a.py:3: lbs"]


def test_a_run_of_a_method_that_does_not_import_here_is_read_without_its_declarations(caplog):
    import methods
    from drapebench.plugins import known_impl

    known_impl("elsewhere", "nowhere.at_all:Thing")
    assert "elsewhere" not in methods.available() and "method.impl='nowhere.at_all:Thing'" in caplog.text
