import igl
import numpy as np
import trimesh

from drapebench.garments.fields import SDF_BAND, signed_distance_grid


def test_narrow_band_sdf_is_exact_in_the_band_and_bounded_outside(tmp_path, monkeypatch):
    monkeypatch.setenv("DRAPEBENCH_DATA", str(tmp_path))
    mesh = trimesh.creation.icosphere(subdivisions=3, radius=0.15)
    mesh.vertices[:, 2] *= 2.0  # an ellipsoid: not a trivially radial distance
    V, F = np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces, dtype=np.int64)
    grid, sdf = signed_distance_grid(V, F, 0.01)
    P = grid.points()
    unsigned = np.sqrt(igl.point_mesh_squared_distance(P, V, F)[0])
    inside = igl.fast_winding_number(V, F, P) > 0.5
    exact = np.where(inside, -unsigned, unsigned).reshape(grid.shape)
    band = (exact > SDF_BAND[0]) & (exact < SDF_BAND[1])
    assert band.sum() > 1000
    np.testing.assert_allclose(sdf[band], exact[band], atol=1e-6)
    assert (np.sign(sdf) == np.sign(exact)).all()
    # off the band the estimate stays on the right side of it
    assert (sdf[exact >= SDF_BAND[1]] >= SDF_BAND[1] - 1e-6).all() and (sdf[exact <= SDF_BAND[0]] <= SDF_BAND[0] + 1e-6).all()
    # second call: from the cache, identical
    np.testing.assert_array_equal(signed_distance_grid(V, F, 0.01)[1], sdf)
