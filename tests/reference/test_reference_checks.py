"""The reference's failure checks (NaN, speed, stretch, a snag, garment leaving the body) and its retry ladder, fed
bad frames by a fake Newton scene inside the real simulation loop (fast)."""

import pickle

import numpy as np
import pytest
import torch

import drapebench.reference.scene as scene_module
from drapebench.body import make_sequence
from drapebench.garments import make_garment
from drapebench.physics import Material
from drapebench.reference import GarmentInsideBody, GarmentLeftBody, SimulationDiverged, simulate_record
import drapebench.reference.simulator as simulator
from drapebench.reference.simulator import FEET_BAND, INSIDE_SHARE, LEAVE_MARGIN, SNAG_STRETCH, _left_body, find_snag

N_FRAMES, TRANSITION, SETTLE = 4, 2, 2


@pytest.fixture(scope="module")
def scene(body_lowres):
    return make_garment("skirt", body_lowres, resolution=0.03), make_sequence("walk", N_FRAMES, transition=TRANSITION, seed=3)


def fake_scene(monkeypatch, fault, bad_below=None):
    """Replace Newton's scene by one whose garment stays where it started until ``fault(x, frames_done)`` changes
    it; ``bad_below``: the fault only happens with fewer substeps than this (a smaller step cures it)."""
    steps = []

    class FakeScene:
        def __init__(self, rest, faces, start, body_points, body_faces, pins, material, settings, device):
            self.x, self.substeps, self.frames = start.astype(np.float32), settings.substeps, 0
            steps.append(settings.substeps)

        def begin_frame(self):
            self.frames += 1

        def set_body(self, points, velocities):
            pass

        def set_pinned(self, q, qd):
            pass

        def step(self, dt):
            assert dt == pytest.approx(1.0 / (30.0 * self.substeps))

        def positions(self):
            if bad_below is None or self.substeps < bad_below:
                return fault(self.x.copy(), self.frames)
            return self.x

    monkeypatch.setattr(scene_module, "ClothScene", FakeScene)
    return steps


def nan_at_3(x, n):
    x[0] = np.nan if n >= 3 else x[0]
    return x


def fast_at_3(x, n):
    return x + (n >= 3) * np.float32(10.0)  # 10 m in one frame at 30 fps: 300 m/s


def torn_at_3(x, n):
    x[0, 2] += 0.15 if n >= 3 else 0.0  # one vertex 15 cm off: its edges (about 3 cm) stretch past 4x, at 4.5 m/s
    return x


def pulled(g, vertex: int, ratio: float) -> np.ndarray:
    """The offset (3,) m along +z that stretches ``vertex``'s longest-stretched edge to ``ratio`` x its rest length."""
    x, topo = g.vertices.double().numpy(), g.topology
    e, rest = topo.edges.numpy(), topo.rest_edge_lengths.double().numpy()
    mine = (e == vertex).any(1)
    other = np.where(e[mine, 0] == vertex, e[mine, 1], e[mine, 0])
    lo, hi = 0.0, 1.0
    for _ in range(60):
        d = 0.5 * (lo + hi)
        r = np.linalg.norm(x[vertex] + [0.0, 0.0, d] - x[other], axis=1) / rest[mine]
        lo, hi = (d, hi) if r.max() < ratio else (lo, d)
    return np.array([0.0, 0.0, lo], dtype=np.float32)


def free_vertex(g) -> int:
    """A vertex far from the pins (the hem of the skirt)."""
    return int(torch.argmin(g.vertices[:, 2]))


def falls(x, n):
    return x - np.float32([0.0, 0.0, 0.3 * n])  # 30 cm lower each frame: 9 m/s, below max_speed


@pytest.mark.parametrize("fault, error, match", [
    (nan_at_3, SimulationDiverged, r"became NaN/Inf"),
    (fast_at_3, SimulationDiverged, r"moved at .* m/s"),
    (torn_at_3, SimulationDiverged, r"an edge stretched to \d"),
    (falls, GarmentLeftBody, r"lost the garment at .*(fell off|slid down to the feet)"),
])  # fmt: skip
def test_a_bad_frame_fails_the_run_and_caches_nothing(scene, body_lowres, monkeypatch, tmp_path, fault, error, match):
    monkeypatch.setenv("DRAPEBENCH_DATA", str(tmp_path))
    g, seq = scene
    steps = fake_scene(monkeypatch, fault)
    with pytest.raises(error, match=match) as err:
        simulate_record(g, seq, body_lowres, Material(), settle_frames=SETTLE, retry_substeps=[], progress=False)
    assert steps == [10] and err.value.attempts == [{"substeps": 10, "failure": err.value.attempts[0]["failure"]}]
    assert not list((tmp_path / "cache" / "reference").glob("*.npz"))  # no drape; only the failure record


def test_a_divergence_is_retried_with_a_smaller_step_and_recorded(scene, body_lowres, monkeypatch, tmp_path):
    monkeypatch.setenv("DRAPEBENCH_DATA", str(tmp_path))
    g, seq = scene
    steps = fake_scene(monkeypatch, torn_at_3, bad_below=30)
    rec = simulate_record(g, seq, body_lowres, Material(), settle_frames=SETTLE, retry_substeps=[5, 20, 40], progress=False)
    assert steps == [10, 20, 40]  # 5 is not a smaller step than the requested 10: skipped
    assert rec.stats["substeps"] == 40 and rec.settings.substeps == 10
    attempts = rec.stats["attempts"]
    assert [a["substeps"] for a in attempts] == [10, 20, 40] and attempts[-1]["failure"] is None
    assert all(a["failure"].startswith("SimulationDiverged at frame 0: an edge stretched") for a in attempts[:2])
    assert rec.timings_s["retries"] > 0 and torch.isfinite(rec.vertices).all()
    again = simulate_record(g, seq, body_lowres, Material(), settle_frames=SETTLE, retry_substeps=[5, 20, 40], progress=False)
    assert again.from_cache and steps == [10, 20, 40] and again.stats["attempts"] == attempts
    assert len(list((tmp_path / "cache" / "reference").glob("*.npz"))) == 1


def test_when_every_attempt_fails_the_error_lists_them_and_survives_pickling(scene, body_lowres, monkeypatch, tmp_path):
    monkeypatch.setenv("DRAPEBENCH_DATA", str(tmp_path))
    g, seq = scene
    steps = fake_scene(monkeypatch, torn_at_3)
    with pytest.raises(SimulationDiverged, match=r"also failed with substeps=10: SimulationDiverged.*substeps=20") as err:
        simulate_record(g, seq, body_lowres, Material(), settle_frames=SETTLE, progress=False)  # vbd.yaml: [20, 40]
    assert steps == [10, 20, 40] and [a["substeps"] for a in err.value.attempts] == [10, 20, 40]
    back = pickle.loads(pickle.dumps(err.value))
    assert type(back) is SimulationDiverged and back.attempts == err.value.attempts and str(back) == str(err.value)
    assert not list((tmp_path / "cache" / "reference").glob("*.npz"))  # no drape; only the failure record


def pushed_in(g):
    """A fault that pulls the garment towards its vertical axis from frame 1 on: the skirt ends inside the hips."""
    centre = g.vertices.mean(0).numpy() * np.float32([1.0, 1.0, 0.0])

    def fault(x, n):
        return (x - centre) * np.float32([0.5, 0.5, 1.0]) + centre if n >= 1 else x

    return fault


@pytest.mark.parametrize("fault, betas, pins, error, cause", [
    (falls, None, True, GarmentLeftBody, r"Its pins do not hold it: .*garment.pins .*not retried"),
    (falls, None, False, GarmentLeftBody, r"The pins are off \(reference.pins=false\)"),
    ("pushed_in", None, True, GarmentInsideBody, r"stayed inside the body for 3 frames .*the material is the likely cause .*not retried"),
    (torn_at_3, [0.0, 3.0], True, SimulationDiverged, r"3.0 standard deviations away .*garment.betas=motion\) \(not retried"),
])  # fmt: skip
def test_a_failure_more_substeps_cannot_fix_is_not_retried_and_names_its_likely_cause(
    scene, body_lowres, monkeypatch, tmp_path, fault, betas, pins, error, cause
):
    monkeypatch.setenv("DRAPEBENCH_DATA", str(tmp_path))
    monkeypatch.setattr(simulator, "INSIDE_SECONDS", 0.1)  # 3 frames at 30 fps (the run has 2 + 6)
    g, seq = scene
    if betas is not None:
        seq = make_sequence("walk", N_FRAMES, transition=TRANSITION, seed=3, betas=betas)
    steps = fake_scene(monkeypatch, pushed_in(g) if fault == "pushed_in" else fault)
    with pytest.raises(error, match=cause) as err:
        simulate_record(g, seq, body_lowres, Material(), settle_frames=SETTLE, pins=pins, progress=False)  # vbd.yaml: [20, 40]
    assert steps == [10] and type(err.value) is error and "Try more substeps" not in str(err.value)
    cache = tmp_path / "cache" / "reference"
    assert not list(cache.glob("*.npz")) and len(list(cache.glob("*.failed.json"))) == 1  # recorded, never cached
    with pytest.raises(error, match=cause):  # the recorded failure is raised at once, with its cause
        simulate_record(g, seq, body_lowres, Material(), settle_frames=SETTLE, pins=pins, progress=False)
    assert steps == [10]


def test_a_cached_drape_with_the_garment_inside_the_body_is_simulated_again(scene, body_lowres, monkeypatch, tmp_path, caplog):
    monkeypatch.setenv("DRAPEBENCH_DATA", str(tmp_path))
    monkeypatch.setattr(simulator, "INSIDE_SECONDS", 0.1)
    g, seq = scene
    steps = fake_scene(monkeypatch, pushed_in(g))
    monkeypatch.setattr(simulator, "INSIDE_SHARE", 1.0)  # an older simulator without the check: cached
    rec = simulate_record(g, seq, body_lowres, Material(), settle_frames=SETTLE, progress=False)
    assert not rec.from_cache and max(rec.stats["inside_share"]) > 0.3
    monkeypatch.setattr(simulator, "INSIDE_SHARE", INSIDE_SHARE)
    with pytest.raises(GarmentInsideBody):
        simulate_record(g, seq, body_lowres, Material(), settle_frames=SETTLE, progress=False)
    assert steps == [10, 10] and "fails its checks" in caplog.text


def test_the_leave_body_rule(scene, body_lowres):
    g, _ = scene
    body = body_lowres.v_template.double().numpy()
    x = g.vertices.double().numpy()
    assert _left_body(x, body) is None
    width = body[:, 0].max() - body[:, 0].min()
    side = x + np.array([width + LEAVE_MARGIN + 0.05, 0.0, 0.0])
    assert "fell off" in _left_body(side, body)
    assert _left_body(x + np.array([width / 2 + LEAVE_MARGIN - 0.05, 0.0, 0.0]), body) is None  # within the margin
    feet = x - np.array([0.0, 0.0, x[:, 2].mean() - body[:, 2].min() - 0.5 * FEET_BAND * np.ptp(body[:, 2])])
    assert "slid down to the feet" in _left_body(feet, body)


def test_a_held_stretch_away_from_the_pins_is_a_snag(scene, body_lowres, monkeypatch, tmp_path):
    monkeypatch.setenv("DRAPEBENCH_DATA", str(tmp_path))
    monkeypatch.setattr(simulator, "SNAG_SECONDS", 0.1)  # 3 frames at 30 fps (the run has 2 + 4)
    g, seq = scene
    v, offset = free_vertex(g), pulled(g, free_vertex(g), 3.0)  # past SNAG_STRETCH, below MAX_STRETCH

    def snagged(x, n):
        x[v] += offset if n >= 2 else 0.0
        return x

    steps = fake_scene(monkeypatch, snagged)
    with pytest.raises(SimulationDiverged, match=r"stayed stretched past 2.5x its rest length for 3 frames \(up to 3.0x") as err:
        simulate_record(g, seq, body_lowres, Material(), settle_frames=SETTLE, retry_substeps=[], progress=False)
    assert steps == [10] and err.value.frame == 3 - SETTLE  # stretched from timeline frame 1 on, the third such frame is 3
    assert not list((tmp_path / "cache" / "reference").glob("*.npz"))


def test_find_snag_counts_free_edges_held_long_enough(scene):
    g, _ = scene
    x = g.vertices.numpy()[None].repeat(20, 0)
    v = free_vertex(g)
    x[5:12, v] += pulled(g, v, 3.0)  # 7 frames past 2.5x
    assert find_snag(x, g, pinned=True, fps=30.0) is None  # 0.5 s at 30 fps is 15 frames
    frame, reason = find_snag(x, g, pinned=True, fps=10.0)  # 5 frames
    assert frame == 9 and "snagged" in reason
    x[5:12, v] -= pulled(g, v, 3.0) - pulled(g, v, 0.99 * SNAG_STRETCH)
    assert find_snag(x, g, pinned=True, fps=10.0) is None  # below the limit
    pin = int(g.pins[0])
    x[:, pin] += pulled(g, pin, 3.0)  # a pinned vertex follows the body: its edges do not count ...
    assert find_snag(x, g, pinned=True, fps=30.0) is None
    assert find_snag(x, g, pinned=False, fps=30.0) is not None  # ... unless the pins are off


def test_a_cached_drape_that_snags_is_simulated_again(scene, body_lowres, monkeypatch, tmp_path, caplog):
    monkeypatch.setenv("DRAPEBENCH_DATA", str(tmp_path))
    monkeypatch.setattr(simulator, "SNAG_SECONDS", 0.1)
    g, seq = scene
    v, offset = free_vertex(g), pulled(g, free_vertex(g), 3.0)

    def snagged(x, n):
        x[v] += offset if n >= 2 else 0.0
        return x

    steps = fake_scene(monkeypatch, snagged)
    monkeypatch.setattr(simulator, "SNAG_STRETCH", 10.0)  # an older check that let it through: cached
    rec = simulate_record(g, seq, body_lowres, Material(), settle_frames=SETTLE, retry_substeps=[], progress=False)
    assert not rec.from_cache and steps == [10]
    monkeypatch.setattr(simulator, "SNAG_STRETCH", SNAG_STRETCH)
    with pytest.raises(SimulationDiverged, match="snagged"):
        simulate_record(g, seq, body_lowres, Material(), settle_frames=SETTLE, retry_substeps=[], progress=False)
    assert steps == [10, 10] and "fails its checks" in caplog.text


def test_an_edge_stretched_every_other_frame_is_not_a_snag(scene, body_lowres, monkeypatch, tmp_path):
    monkeypatch.setenv("DRAPEBENCH_DATA", str(tmp_path))
    monkeypatch.setattr(simulator, "SNAG_SECONDS", 0.1)  # 3 frames at 30 fps (the run has 2 + 4)
    g, seq = scene
    v, offset = free_vertex(g), pulled(g, free_vertex(g), 3.0)

    def flapping(x, n):
        x[v] += offset if n % 2 == 0 else 0.0  # past SNAG_STRETCH on frames 2, 4, 6: never 3 in a row
        return x

    steps = fake_scene(monkeypatch, flapping)
    rec = simulate_record(g, seq, body_lowres, Material(), settle_frames=SETTLE, retry_substeps=[], progress=False)
    assert steps == [10] and not rec.from_cache


def test_speed_is_each_frames_displacement_not_the_distance_from_the_start(scene, body_lowres, monkeypatch, tmp_path):
    monkeypatch.setenv("DRAPEBENCH_DATA", str(tmp_path))
    g, seq = scene
    steps = fake_scene(monkeypatch, lambda x, n: x + np.float32([0.0, 0.0, n / 30.0]))  # rises steadily at 1 m/s
    rec = simulate_record(g, seq, body_lowres, Material(), settle_frames=SETTLE, retry_substeps=[], max_speed=2.0, progress=False)
    assert steps == [10] and rec.stats["max_speed"] == pytest.approx(1.0, rel=1e-3)
