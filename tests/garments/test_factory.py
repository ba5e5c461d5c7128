import numpy as np
import pytest
import torch

from drapebench.garments import GARMENT_KINDS, garment_from_config, load_garment, make_garment
from drapebench.garments.factory import EXPECTED_LOOPS, garment_params
from drapebench.garments.validate import cross_sections


@pytest.mark.parametrize("kind", ["skirt", "pants"])
def test_fast_kinds_are_valid_on_lowres(kind, body_lowres):
    g = make_garment(kind, body_lowres)
    s = g.params
    assert s["stat_boundary_loops"] == EXPECTED_LOOPS[kind]
    assert s["stat_min_clearance_mm"] >= 2.0 and s["stat_self_intersecting_faces"] == 0
    assert s["stat_min_angle_ge20"] >= 0.99 and abs(s["stat_mean_edge_mm"] - 15.0) < 0.15 * 15.0
    assert g.topology.n_vertices == g.n_vertices and len(g.pins) > 0
    # pins are the waistband: the highest vertices of the garment
    assert g.vertices[g.pins, 2].mean() > g.vertices[:, 2].quantile(0.9)
    V, F = g.vertices.numpy(), g.faces.numpy()
    hip = body_lowres.shaped()[1][0, body_lowres.joint_index("left_hip"), 2].item()
    knee = body_lowres.shaped()[1][0, body_lowres.joint_index("left_knee"), 2].item()
    assert cross_sections(V, F, 0.5 * (hip + knee) if kind == "pants" else hip - 0.1) == (2 if kind == "pants" else 1)


def test_cached_garment_is_identical(body_lowres):
    a = make_garment("skirt", body_lowres)
    b = make_garment("skirt", body_lowres)
    assert torch.equal(a.vertices, b.vertices) and torch.equal(a.faces, b.faces)


def test_parameters_and_errors():
    p = garment_params("skirt", seed=3, flare=0.3)
    assert p["flare"] == 0.3 and p != garment_params("skirt", seed=4, flare=0.3)
    with pytest.raises(ValueError, match="valid kinds: tshirt"):
        garment_params("poncho")
    with pytest.raises(ValueError, match="unknown parameter"):
        garment_params("skirt", sleeve=1.0)
    with pytest.raises(ValueError, match=r"ease 0.08 m is outside .*SDF_BAND"):
        garment_params("tshirt", ease=0.08)


def test_export_and_load_round_trip(tmp_path, body_lowres):
    g = make_garment("skirt", body_lowres)
    for suffix in (".obj", ".ply"):
        g.export(tmp_path / f"s{suffix}")
        back = load_garment(tmp_path / f"s{suffix}", body_lowres)
        assert np.allclose(back.vertices.numpy(), g.vertices.numpy(), atol=1e-5)
        assert torch.equal(back.faces, g.faces)


def _write(path, V, F):
    with open(path, "w") as f:
        f.writelines(f"v {x} {y} {z}\n" for x, y, z in V)
        f.writelines(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in F)


def test_broken_garments_are_reported_by_name(tmp_path, body_lowres):
    g = make_garment("skirt", body_lowres)
    V, F = g.vertices.numpy().astype(np.float64), g.faces.numpy()
    cases = {
        "degenerate_faces": (V, np.concatenate([F, [[0, 0, 1]]])),
        "duplicate_vertices": (np.concatenate([V, V[:1]]), np.concatenate([F, [[len(V), F[0, 1], F[0, 2]]]])),
        "unreferenced_vertices": (np.concatenate([V, [[0, 0, 5.0]]]), F),
        "inconsistent_winding": (V, np.concatenate([F[:10], F[10:11, ::-1], F[11:]])),
        "inside_body": (np.where(np.arange(len(V))[:, None] == 5, 0.0, V), F),
        "orientation": (V, F[:, ::-1]),
    }
    e = np.concatenate([F[:, [0, 1]]])[0]
    cases["non_manifold_edges"] = (np.concatenate([V, [[0, 0, 5.0], [0, 0, 6.0]]]),
                                   np.concatenate([F, [[e[0], e[1], len(V)], [e[1], e[0], len(V) + 1]]]))  # fmt: skip
    for name, (v, f) in cases.items():
        _write(tmp_path / f"{name}.obj", v, f)
        with pytest.raises(ValueError, match=name):
            load_garment(tmp_path / f"{name}.obj", body_lowres)
    with pytest.raises(FileNotFoundError):
        load_garment(tmp_path / "nope.obj", body_lowres)


@pytest.mark.slow
@pytest.mark.parametrize("kind", GARMENT_KINDS)
@pytest.mark.parametrize("resolution", [0.012, 0.018, 0.025])
@pytest.mark.parametrize("betas", [0.0, -1.5, 1.5])
def test_every_kind_resolution_and_shape_is_valid(kind, resolution, betas, body_full):
    shape = torch.zeros(10)
    shape[0] = betas
    g = make_garment(kind, body_full, betas=shape, resolution=resolution)  # raises with the report if invalid
    assert 500 < g.n_vertices < 20000


@pytest.mark.slow
@pytest.mark.parametrize("kind", GARMENT_KINDS)
@pytest.mark.parametrize("component,value", [(0, -3.0), (0, 3.0), (1, -3.0), (1, 3.0)])
def test_every_kind_is_valid_at_the_ends_of_the_shape_space(kind, component, value, body_full):
    shape = torch.zeros(10)
    shape[component] = value
    g = make_garment(kind, body_full, betas=shape)  # raises with the report if invalid
    assert 500 < g.n_vertices < 20000


def test_the_gallery_draws_every_garment_config():
    from drapebench.cache import PROJECT_ROOT
    from drapebench.garments.gallery import garment_configs

    configs = garment_configs()
    assert set(configs) == {f.stem for f in (PROJECT_ROOT / "conf" / "garment").glob("*.yaml")} - {"obj"}  # obj: a user's file
    assert configs["skirt_flared"] == ("skirt", {"flare": 0.3}) and list(configs)[:2] == ["tshirt", "tank"]
    assert list(configs).index("skirt") < list(configs).index("skirt_flared") < list(configs).index("dress")


@pytest.mark.parametrize("argv, says", [
    (["--garments"], "--garments: name at least one garment config"),  # was matplotlib's "cannot write empty image"
    (["--garments", "tshrt"], "--garments: no garment config ['tshrt']; configs: dress, gown"),
])  # fmt: skip
def test_the_gallery_command_refuses_no_or_unknown_garments_before_drawing(argv, says, tmp_path, capsys, monkeypatch):
    from drapebench.garments import gallery

    monkeypatch.setattr(gallery, "render_gallery", lambda *a, **k: pytest.fail("drew on a bad argument"))
    with pytest.raises(SystemExit) as stop:
        gallery.main([*argv, "--out", str(tmp_path / "g.png")])
    assert stop.value.code == 2 and says in capsys.readouterr().err and not (tmp_path / "g.png").exists()


def test_keep_component_near_ignores_vertices_no_face_uses():
    from drapebench.garments.mesh_ops import keep_component_near

    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [5, 0, 0], [6, 0, 0], [5, 1, 0], [5.2, 0.2, 0]], dtype=float)
    F = np.array([[0, 1, 2], [3, 4, 5]])  # vertex 6, nearest the seed, is in no face
    kept, faces = keep_component_near(V, F, np.array([5.2, 0.2, 0.0]))
    assert len(faces) == 1 and np.allclose(kept, V[3:6])


def test_a_garment_made_for_the_sequence_shape_at_the_end_of_the_shape_space(body_lowres):
    """garment.betas=motion builds on the sequence's betas; at beta1 = +3 (heavy) the skirt's loft once had
    slices without a body hull above the waist, which left NaN vertices."""
    cfg = {"kind": "skirt", "seed": 0, "params": {}, "betas": "motion"}
    g = garment_from_config(cfg, body_lowres, [0.0, 3.0])  # raises with the validation report if invalid
    assert g.betas[:2].tolist() == [0.0, 3.0] and torch.isfinite(g.vertices).all()
    assert garment_from_config({**cfg, "betas": None}, body_lowres, [0.0, 3.0]).betas.abs().sum() == 0
    with pytest.raises(ValueError, match="garment.betas must be null .* or a list of numbers"):
        garment_from_config({**cfg, "betas": "heavy"}, body_lowres)


def test_a_negative_ease_or_a_resolution_out_of_range_is_refused():
    with pytest.raises(ValueError, match=r"ease -0.01 m is outside \[0, "):
        garment_params("skirt", ease=-0.01)
    with pytest.raises(ValueError, match=r"closing -0.02 m is outside \[0, "):
        garment_params("tshirt", closing=-0.02)
    with pytest.raises(ValueError, match=r"resolution 0.2 m is outside \[0.003, 0.05\]"):
        garment_params("skirt", resolution=0.2)
    with pytest.raises(ValueError, match=r"resolution 0.001 m is outside"):
        garment_params("skirt", resolution=0.001)
    assert garment_params("skirt", ease=0.0, resolution=0.05)["ease"] == 0.0


def test_user_pins_outside_the_vertex_range_or_too_few_are_refused():
    from drapebench.garments.pins import check_pins

    with pytest.raises(ValueError, match=r"pin indices \[-1\] are outside \[0, 10\) \(0-based vertex indices\); give garment.pins"):
        check_pins([-1, 2, 3, 4], 10, "toy")
    with pytest.raises(ValueError, match=r"pin indices \[10\] are outside"):
        check_pins([1, 2, 3, 10], 10, "toy")
    with pytest.raises(ValueError, match=r"2 distinct pins given, at least 3 needed; give garment.pins \(load_garment's pins\) 3 or more"):
        check_pins([1, 1, 2], 10, "toy")
    assert check_pins([0, 5, 9], 10, "toy").tolist() == [0, 5, 9]


def test_triangle_quality_fails_below_99_percent_well_shaped_triangles():
    from drapebench.garments.validate import GarmentReport, triangle_quality

    good = np.array([[0.0, 0, 0], [1, 0, 0], [0.5, 0.87, 0]])
    sliver = np.array([[0.0, 0, 0], [1, 0, 0], [0.5, 0.05, 0]])  # min angle < 6 deg
    for n_bad, fails in ((5, True), (1, False)):
        tris = [good] * (100 - n_bad) + [sliver] * n_bad
        V = np.concatenate([t + [2.0 * k, 0, 0] for k, t in enumerate(tris)])
        report = GarmentReport()
        triangle_quality(V, np.arange(len(V)).reshape(-1, 3), report, None)
        assert ("triangle_quality" in report.failures) == fails, n_bad
