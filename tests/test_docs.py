"""The repository is self-contained: no file points outside it, and every docs/ page it names exists."""

import re
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _tracked_text_files() -> list[Path]:
    out = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=True).stdout.split()
    return [ROOT / f for f in out if f.endswith((".py", ".md", ".yaml", ".toml", ".cfg", ".txt", ".json", ".csv")) or f in ("Makefile",)]


def test_nothing_cites_a_file_outside_the_repository():
    outside = re.compile(r"\.\./shared|shared/(notes|papers|design)/|\bDESIGN\.md|(?<![\w.])/(work|home)/")  # a machine's folders too
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


METHOD_README_WORDS = 2600  # a method README is a map: paper to code, the open choices, links to the tables
COMMIT_HASH = re.compile(r"\b(?=[0-9a-f]*[a-f])(?=[0-9a-f]*[0-9])[0-9a-f]{7,40}\b")


def test_method_readmes_are_maps_without_commit_hashes():
    readmes = sorted((ROOT / "methods").glob("*/README.md"))
    assert readmes, "no method README found"
    for readme in readmes:
        text = readme.read_text()
        name = str(readme.relative_to(ROOT))
        assert len(text.split()) <= METHOD_README_WORDS, (
            f"{name} is {len(text.split())} words (at most {METHOD_README_WORDS}): move measurement history to reports/history.md")
        assert not COMMIT_HASH.findall(text), f"{name} names commit hashes {COMMIT_HASH.findall(text)}: history goes to reports/history.md"
        links = re.findall(r"\]\(([^)#]+)\)", text)
        assert not [link for link in links if not (readme.parent / link).exists()], f"{name} links a file that does not exist"


def test_the_commit_hash_rule_catches_a_hash():
    assert COMMIT_HASH.findall("measured at 494abcf and c14cf29") == ["494abcf", "c14cf29"]
    assert not COMMIT_HASH.findall("1e-4, 0.28 M parameters, decoded 2,880 poses")


def _table_names_in(text: str, tables: set[str]) -> set[str]:
    """The table names (reports/<name>.md stems) that `text` mentions as whole words."""
    return {name for name in tables if re.search(rf"(?<![\w]){re.escape(name)}(?![\w])", text)}


def _stale_tables(index: str, claims: str, tables: set[str]) -> tuple[set[str], set[str]]:
    """(tables the index header calls stale, tables claims.md lists with stale rows)."""
    header = re.search(r"stale: (.*?)\*\*", index, re.S)
    assert header, "reports/README.md's header has no 'stale: ...' sentence (write 'stale: none' when none is)"
    section = claims.split("Tables with stale rows", 1)
    listed = re.findall(r"^- (\w+):", section[1], re.M) if len(section) == 2 else []
    return _table_names_in(header.group(1), tables), set(listed)


def test_the_reports_index_names_the_same_stale_tables_as_claims():
    reports = ROOT / "reports"
    tables = {p.stem for p in reports.glob("*.md")} - {"README", "history", "claims"}
    in_index, in_claims = _stale_tables((reports / "README.md").read_text(), (reports / "claims.md").read_text(), tables)
    assert in_index == in_claims, (
        f"reports/README.md's header calls {sorted(in_index)} stale, claims.md lists {sorted(in_claims)}: "
        "make the header's 'stale:' sentence name claims.md's 'Tables with stale rows'")


def test_the_stale_list_rule_catches_a_divergence():
    tables = {"gensim_table1", "vae_table2", "vae_table2_gpu"}
    claims = "Tables with stale rows (...):\n- vae_table2_gpu: dress.\n"
    assert _stale_tables("**x; stale: vae_table2_gpu (needs a GPU).**", claims, tables) == ({"vae_table2_gpu"}, {"vae_table2_gpu"})
    in_index, in_claims = _stale_tables("**stale: vae_table2 (old).**", claims, tables)
    assert in_index != in_claims
