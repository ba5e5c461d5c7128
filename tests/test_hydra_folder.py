"""The copy of an earlier run's ``.hydra/`` that a single run keeps, puts back when it does not take the folder, and
drops when it does (:mod:`drapebench.hydra_folder`)."""

from pathlib import Path

from drapebench.hydra_folder import forget_earlier_hydra, keep_earlier_hydra, put_back_earlier_hydra


def _hydra(run_dir: Path, text: str) -> dict:
    hydra_dir = run_dir / ".hydra"
    hydra_dir.mkdir(parents=True, exist_ok=True)
    (hydra_dir / "overrides.yaml").write_text(text)
    return {p.name: p.read_text() for p in hydra_dir.iterdir()}


def _listing(run_dir: Path) -> dict:
    return {p.name: p.read_text() for p in (run_dir / ".hydra").iterdir()}


def test_a_run_that_does_not_take_the_folder_puts_back_the_earlier_hydra_and_leaves_nothing_aside(tmp_path):
    for refused in (True, False):
        run_dir = tmp_path / f"run_{refused}"
        earlier = _hydra(run_dir, "- earlier")
        keep_earlier_hydra(run_dir, ".hydra")
        _hydra(run_dir, "- new")  # what Hydra writes before the run starts
        put_back_earlier_hydra(run_dir, refused=refused)
        assert _listing(run_dir) == earlier
        assert [p.name for p in run_dir.iterdir()] == [".hydra"]


def test_where_there_was_no_earlier_hydra_a_refused_run_removes_its_own_and_a_failed_one_keeps_it(tmp_path):
    refused_dir, failed_dir = tmp_path / "refused", tmp_path / "failed"
    for run_dir in (refused_dir, failed_dir):
        run_dir.mkdir()
        keep_earlier_hydra(run_dir, ".hydra")
        _hydra(run_dir, "- new")
    put_back_earlier_hydra(refused_dir, refused=True)
    put_back_earlier_hydra(failed_dir, refused=False)
    assert list(refused_dir.iterdir()) == []
    assert _listing(failed_dir) == {"overrides.yaml": "- new"}


def test_a_run_that_takes_the_folder_keeps_its_own_hydra_and_drops_the_copy(tmp_path, monkeypatch):
    import tempfile

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "tmp"))
    (tmp_path / "tmp").mkdir()
    run_dir = tmp_path / "run"
    _hydra(run_dir, "- earlier")
    keep_earlier_hydra(run_dir, ".hydra")
    assert list((tmp_path / "tmp").iterdir())  # the copy
    _hydra(run_dir, "- new")
    forget_earlier_hydra(run_dir)
    assert _listing(run_dir) == {"overrides.yaml": "- new"}
    assert list((tmp_path / "tmp").iterdir()) == []
    put_back_earlier_hydra(run_dir, refused=True)  # nothing kept any more: a no-op
    assert _listing(run_dir) == {"overrides.yaml": "- new"}
