"""``python -m drapebench.body.bake``: a shape space it cannot make is refused before Anny is sampled."""

import pytest


@pytest.mark.parametrize("argv", [["--betas", "0"], ["--samples", "-1"], ["--samples", "10", "--betas", "10"]])
def test_the_bake_command_refuses_a_shape_space_it_cannot_make(argv, tmp_path, capsys, monkeypatch):
    from drapebench.body import bake

    monkeypatch.setattr(bake, "bake", lambda *a, **k: pytest.fail("baked on a bad argument"))
    with pytest.raises(SystemExit) as stop:
        bake.main([*argv, "--out", str(tmp_path / "bodies")])
    assert stop.value.code == 2 and "need 1 <= betas < samples" in capsys.readouterr().err
    assert not (tmp_path / "bodies").exists()
