"""The repository is self-contained: no file points outside it, and every docs/ page it names exists."""

import re
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _tracked_text_files() -> list[Path]:
    out = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=True).stdout.split()
    return [ROOT / f for f in out if f.endswith((".py", ".md", ".yaml", ".toml", ".cfg", ".txt")) or f in ("Makefile",)]


def test_nothing_cites_a_file_outside_the_repository():
    outside = re.compile(r"\.\./shared|shared/(notes|papers|design)/|\bDESIGN\.md")
    bad = [str(p.relative_to(ROOT)) for p in _tracked_text_files() if p.name != "test_docs.py" and outside.search(p.read_text(errors="ignore"))]
    assert not bad, f"files cite documents outside the repository: {bad}; point them at docs/ instead"


def test_every_cited_docs_page_exists():
    cited = re.compile(r"docs/([A-Za-z0-9_\-]+\.(?:md|png))")
    missing = sorted({(str(p.relative_to(ROOT)), m) for p in _tracked_text_files() for m in cited.findall(p.read_text(errors="ignore"))
                      if not (ROOT / "docs" / m).exists()})  # fmt: skip
    assert not missing, f"cited docs pages that do not exist: {missing}"


REPORTS_INDEX_WORDS = 1500  # reports/README.md is an index; measurement logs go to reports/history.md


def test_the_reports_index_stays_an_index_and_links_every_table():
    index = (ROOT / "reports" / "README.md").read_text()
    assert len(index.split()) <= REPORTS_INDEX_WORDS, (
        f"reports/README.md is {len(index.split())} words (at most {REPORTS_INDEX_WORDS}): move measurement logs to reports/history.md")
    links = set(re.findall(r"\]\(([^)#]+)\)", index))
    assert not [link for link in links if not (ROOT / "reports" / link).exists()], "reports/README.md links a file that does not exist"
    tables = {p.name for p in (ROOT / "reports").glob("*.md")} - {"README.md", "history.md"}
    assert not tables - links, f"tables not in the reports index: {sorted(tables - links)}"
