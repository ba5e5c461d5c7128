"""drapebench.collision_sources: the inside vertices of a drape split by the drape's extras."""

import pytest
import torch

from drapebench.collision_sources import collision_sources


def test_inside_vertices_are_split_by_mask_and_by_stage(body_lowres):
    """Points 5 mm inside the body along its normals (the first half of them) and 5 mm outside (the rest); a mask
    over the first quarter and the last half (a third of it inside); an earlier stage with the first three quarters
    inside: the split reads those shares back."""
    from drapebench.body import make_sequence

    seq = make_sequence("walk", 2, transition=0)
    bv, bn = seq.vertices(body_lowres)[:2], seq.vertex_normals(body_lowres)[:2]
    idx = torch.arange(0, body_lowres.n_vertices, 7)
    n = len(idx)
    order = torch.arange(n)
    side = lambda inside: torch.where(inside, -1.0, 1.0).to(bv.dtype)[None, :, None]  # noqa: E731
    drape = bv[:, idx] + 0.005 * side(order < n // 2) * bn[:, idx]
    before = bv[:, idx] + 0.005 * side(order < 3 * n // 4) * bn[:, idx]
    held = ((order < n // 4) | (order >= n // 2))[None].expand(2, n)
    found = collision_sources(drape, {"before": before}, {"held": held}, bv, body_lowres)
    assert abs(found["eps_c"] - 50.0) < 3.0
    assert abs(found["stages"]["before"] - 75.0) < 3.0 and found["inside_at"]["before"] > 95.0
    mask = found["masks"]["held"]
    assert abs(mask["share"] - 75.0) < 1.0 and abs(mask["eps_c"] - 100 / 3) < 3.0 and abs(mask["share_of_inside"] - 50.0) < 3.0
    median, _, deepest = found["depth_mm"]
    assert 4.0 < median < 5.5 and deepest < 20.0


@pytest.mark.parametrize("what", ["missing", "empty", "file"])
def test_the_command_stops_on_a_folder_that_is_not_a_run_s_with_a_message(tmp_path, what, capsys):
    from drapebench.collision_sources import main

    path = tmp_path / "x"
    if what == "empty":
        path.mkdir()
    elif what == "file":
        path.write_text("")
    with pytest.raises(SystemExit) as stop:
        main([str(path)])
    assert stop.value.code == 2 and f"{path} has no config.yaml or metrics.json: give a finished run's folder" in capsys.readouterr().err
