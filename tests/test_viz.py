"""drape.rrd recordings: strain colours and a file the rerun CLI verifies."""

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from drapebench.geometry.topology import get_topology
from drapebench.viz import record_drape, strain_colors

SQUARE = torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]]), torch.tensor([[0, 1, 2], [1, 3, 2]])


def test_strain_colors_white_at_rest_red_when_stretched():
    v, f = SQUARE
    topo = get_topology(v, f)
    x = torch.stack([v, v * torch.tensor([1.2, 1.0, 1.0])])  # frame 1: 20 % stretch along x
    c = strain_colors(x, topo, max_strain=0.1)
    assert c.shape == (2, 4, 3) and c.dtype == np.uint8
    assert (c[0] > 230).all()  # white at rest
    assert (c[1, :, 0].astype(int) > c[1, :, 2].astype(int) + 100).all()  # red-orange where edges changed (in int: uint8 + 100 wraps)


def test_recording_verifies(tmp_path):
    v, f = SQUARE
    topo = get_topology(v, f)
    T = 6
    g = v[None] * torch.linspace(1.0, 1.1, T)[:, None, None]
    pen = torch.zeros(T, 4, dtype=torch.bool)
    pen[2, 0] = True
    import pandas as pd

    metrics = pd.DataFrame({"frame": range(2, T), "eps_c": [0.0, 1.0, 0.5, 0.0], "vertex_error_mm": [1.0, 2.0, 3.0, 4.0]})
    path = record_drape(tmp_path / "d.rrd", g - 0.01, f, g, topo, 30.0, penetrating=pen, reference=g + 0.01, metrics=metrics)
    assert path.stat().st_size > 1000 and not list(tmp_path.glob(".*.tmp"))
    rerun = Path(sys.executable).parent / "rerun"
    env = dict(os.environ, CI="1")  # CI keeps the CLI from writing analytics settings into ~/.config
    v = subprocess.run([str(rerun), "rrd", "verify", str(path)], check=False, capture_output=True, text=True, timeout=60, env=env)
    assert v.returncode == 0, v.stderr
    stats = subprocess.run([str(rerun), "rrd", "stats", str(path)], check=False, capture_output=True, text=True, timeout=60, env=env).stdout
    for component in ("Mesh3D:vertex_positions", "Mesh3D:vertex_normals", "Mesh3D:vertex_colors", "Mesh3D:triangle_indices",
                      "EntityBehavior:visible", "Scalars:scalars", "TextDocument:text", "EyeControls3D:position"):  # fmt: skip
        assert component in stats, component
    printed = subprocess.run([str(rerun), "rrd", "print", "-v", str(path)], capture_output=True, text=True, timeout=60, env=env).stdout
    assert "metrics/eps_c" in printed and "metrics/vertex_error_mm" in printed and "/legend" in printed


def test_the_camera_sees_every_body_vertex_of_every_frame():
    from drapebench.viz import camera

    rng = np.random.default_rng(0)
    body = rng.normal(size=(5, 200, 3)) * [0.2, 0.15, 0.5] + [0.0, 0.0, 1.0]
    body[-1] += [1.5, 0.0, 0.0]  # the body walks 1.5 m to the side in the last frame
    eye, target = camera(body, fov_y_deg=45.0, aspect=0.9)
    forward = (target - eye) / np.linalg.norm(target - eye)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    d = body.reshape(-1, 3) - eye
    depth = d @ forward
    vertical, horizontal = np.abs(d @ up) / depth, np.abs(d @ right) / depth
    t = np.tan(np.radians(22.5))
    assert vertical.max() <= t and horizontal.max() <= t * 0.9  # every vertex inside the view
    assert max(vertical.max() / t, horizontal.max() / (t * 0.9)) > 0.85  # and the body fills it, not lost in the distance
    assert eye[1] < target[1] and eye[2] > target[2]  # from the front (-Y) and above


def test_walk_in_place_takes_out_the_horizontal_travel_only():
    from drapebench.viz import walk_in_place

    T = 5
    trans = torch.stack([torch.zeros(T), -0.5 * torch.arange(T), 0.02 * torch.arange(T)], -1)  # walking along -Y, bobbing
    x = torch.tensor([[0.1, 0.2, 1.0], [0.0, -0.1, 0.5]], dtype=torch.float64)[None] + trans[:, None].double()
    still = walk_in_place(x, trans)
    assert still.dtype == torch.float64
    assert torch.allclose(still[..., :2], x[:1, :, :2].expand(T, -1, -1))  # no horizontal travel left
    assert torch.equal(still[..., 2], x[..., 2])  # heights untouched


def test_method_stages_are_recorded_as_their_own_entities(tmp_path):
    v, f = SQUARE
    topo = get_topology(v, f)
    T = 4
    g = v[None].expand(T, -1, -1) + 0.0
    handles = torch.zeros(T, 4, dtype=torch.bool)
    handles[:, :2] = True
    handles[3, 3] = True
    path = record_drape(tmp_path / "s.rrd", g - 0.01, f, g, topo, 30.0, stages={"arap": g + 0.02, "handles": handles, "canonical": g - 1.0},
                        displaced_from=("arap",))  # fmt: skip
    rerun = Path(sys.executable).parent / "rerun"
    env = dict(os.environ, CI="1")
    out = subprocess.run([str(rerun), "rrd", "print", "-v", str(path)], check=False, capture_output=True, text=True, timeout=60, env=env)
    assert out.returncode == 0, out.stderr
    assert "stages/arap" in out.stdout and "stages/handles" in out.stdout
    assert "moved/arap" in out.stdout  # the drape coloured by its distance from the stage, in a view of its own
    assert "stages/canonical" in out.stdout and "moved/canonical" not in out.stdout  # a stage in another space: no distance
    assert "Points3D:positions" in out.stdout


def test_distance_from_a_stage_is_coloured_white_to_blue_on_a_rounded_scale():
    from drapebench.viz import displacement_rgb, displacement_scale

    assert displacement_scale(np.array([0.0, 0.1])) == 1.0  # at least 1 mm
    assert displacement_scale(np.linspace(0, 7.3, 1001)) == 10.0  # the p99 (7.2 mm) rounded up to 1, 2, 5 x 10^k
    assert displacement_scale(np.linspace(0, 15, 1001)) == 20.0
    rgb = displacement_rgb(np.array([0.0, 5.0, 10.0, 50.0]), 10.0)
    assert rgb.dtype == np.uint8 and (rgb[0] == [235, 235, 240]).all() and (rgb[2] == rgb[3]).all()
    assert rgb[1, 2] > rgb[1, 0] and rgb[2, 2] > rgb[2, 0]  # blue grows with the distance


def _renderer_missing() -> str | None:
    """Why a recording cannot be rendered here (None when it can): rerun's viewer needs a display
    (xvfb-run) and a Vulkan driver (Mesa's software one, lavapipe, on a machine without a GPU)."""
    import shutil

    if shutil.which("xvfb-run") is None:
        return "no xvfb-run (Debian: apt-get install xvfb mesa-vulkan-drivers)"
    if not list(Path("/usr/share/vulkan/icd.d").glob("lvp_icd*.json")):
        return "no software Vulkan driver (Debian: apt-get install mesa-vulkan-drivers)"
    return None


def render(rrd: Path, png: Path, size: str = "900x600") -> Path:
    """Screenshot of the rerun viewer opening ``rrd``, as a user sees it, into ``png`` (headless)."""
    rerun = Path(sys.executable).parent / "rerun"
    env = dict(os.environ, CI="1", WGPU_BACKEND="vulkan")
    cmd = ["xvfb-run", "-a", "-s", f"-screen 0 {size}x24", str(rerun), "--screenshot-to", str(png), "--window-size", size, str(rrd)]
    subprocess.run(cmd, check=True, capture_output=True, timeout=300, env=env)
    return png


@pytest.mark.skipif(_renderer_missing() is not None, reason=f"cannot render a recording here: {_renderer_missing()}")
def test_a_recording_renders_a_shaded_body_in_a_framed_view(tmp_path, body_lowres):
    """The viewer shows the whole body, shaded (its vertex normals give it many tones, a silhouette has
    one), and the garment's magenta (inside-the-body) vertices, beside the metric plots."""
    import matplotlib.image as mpimg
    import pandas as pd

    T = 4
    body = body_lowres.v_template[None].expand(T, -1, -1) + 0.0
    b = body[0]
    belly = b[(b[:, 2] - b[:, 2].mean()).abs() < 0.1]  # a 30 cm square 3 cm in front of the belly (the body faces -Y)
    v, f = SQUARE
    corner = torch.stack([belly[:, 0].mean() - 0.15, belly[:, 1].min() - 0.03, b[:, 2].mean() - 0.15])
    g = (corner + 0.3 * v[:, [0, 2, 1]])[None].expand(T, -1, -1) + 0.0
    pen = torch.ones(T, 4, dtype=torch.bool)
    metrics = pd.DataFrame({"frame": range(T), "eps_e": [1.0, 2.0, 3.0, 2.0], "eps_c": [0.0, 1.0, 0.0, 0.5]})
    path = record_drape(tmp_path / "d.rrd", body, body_lowres.faces, g, get_topology(v, f), 30.0, penetrating=pen, metrics=metrics)
    img = mpimg.imread(render(path, tmp_path / "d.png"))[..., :3]
    h, w = img.shape[:2]
    view = (img[: int(h * 0.9), : int(w * 0.55)] * 255).astype(int)  # the 3D view is the left 3/5
    r, gr, b = view[..., 0], view[..., 1], view[..., 2]
    skin = (r > 90) & (r > gr + 8) & (gr > b + 5)
    rows = torch.nonzero(torch.as_tensor(skin.any(1))).squeeze(1)
    assert skin.mean() > 0.02, "no body in the 3D view"
    assert rows[0] > 0.05 * view.shape[0] and rows[-1] < 0.98 * view.shape[0], "the body is cropped at the top or bottom"
    _, counts = np.unique(r[skin] // 4, return_counts=True)
    assert counts.max() < 0.5 * counts.sum(), "the body is one flat colour (a silhouette): no vertex normals"
    magenta = (r > 150) & (b > 120) & (gr < 90)
    assert magenta.sum() > 50, "the garment's inside-the-body vertices are not magenta"


def test_strain_colour_scale_is_white_orange_red():
    from drapebench.viz import strain_rgb

    c = strain_rgb(np.array([0.0, 0.05, 0.1, 0.5]))
    assert c.tolist() == [[235, 235, 240], [255, 160, 40], [210, 30, 30], [210, 30, 30]]  # white 0, orange 5 %, red >= 10 %
    assert (np.diff(strain_rgb(np.linspace(0.05, 0.1, 11))[:, 1].astype(int)) <= 0).all()  # orange darkens to red
