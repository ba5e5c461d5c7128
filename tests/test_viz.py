"""drape.rrd recordings: strain colours and a file the rerun CLI verifies."""

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
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
    assert (c[1, :, 0] > c[1, :, 2] + 100).all()  # red-orange where edges changed


def test_recording_verifies(tmp_path):
    v, f = SQUARE
    topo = get_topology(v, f)
    T = 6
    g = v[None] * torch.linspace(1.0, 1.1, T)[:, None, None]
    pen = torch.zeros(T, 4, dtype=torch.bool)
    pen[2, 0] = True
    path = record_drape(tmp_path / "d.rrd", g - 0.01, f, g, topo, 30.0, penetrating=pen, reference=g + 0.01)
    assert path.stat().st_size > 1000 and not list(tmp_path.glob(".*.tmp"))
    rerun = Path(sys.executable).parent / "rerun"
    env = dict(os.environ, CI="1")  # CI keeps the CLI from writing analytics settings into ~/.config
    v = subprocess.run([str(rerun), "rrd", "verify", str(path)], check=False, capture_output=True, text=True, timeout=60, env=env)
    assert v.returncode == 0, v.stderr
    stats = subprocess.run([str(rerun), "rrd", "stats", str(path)], check=False, capture_output=True, text=True, timeout=60, env=env).stdout
    for component in ("Mesh3D:vertex_positions", "Mesh3D:vertex_colors", "Mesh3D:triangle_indices", "EntityBehavior:visible"):
        assert component in stats, component


def test_method_stages_are_recorded_as_their_own_entities(tmp_path):
    v, f = SQUARE
    topo = get_topology(v, f)
    T = 4
    g = v[None].expand(T, -1, -1) + 0.0
    handles = torch.zeros(T, 4, dtype=torch.bool)
    handles[:, :2] = True
    handles[3, 3] = True
    path = record_drape(tmp_path / "s.rrd", g - 0.01, f, g, topo, 30.0, stages={"arap": g + 0.02, "handles": handles})
    rerun = Path(sys.executable).parent / "rerun"
    env = dict(os.environ, CI="1")
    out = subprocess.run([str(rerun), "rrd", "print", "-v", str(path)], check=False, capture_output=True, text=True, timeout=60, env=env)
    assert out.returncode == 0, out.stderr
    assert "stages/arap" in out.stdout and "stages/handles" in out.stdout
    assert "Points3D:positions" in out.stdout
