"""Physics-based reference drapes on Newton (VBD or Style3D), cached by content hash.

Schedule (one "timeline" of body poses at the sequence's fps):
1. The garment starts as its template on the rest body (pose 0, translation 0) of shape
   ``seq.betas``; if that differs from ``garment.betas`` each vertex first moves by the shape
   blend-shape offset of its nearest body vertex (what the skinning baseline does).
2. ``settle_frames`` frames (not output): the body moves from the rest pose to the sequence's first
   frame over the first half (a C2 smoothstep; no motion at all when frame 0 is the rest pose, as
   for sequences with a transition prefix) and holds it for the rest, so the cloth comes to rest.
3. The sequence's T frames play at ``seq.fps`` (its transition prefix included); the garment after
   each frame is the output.

The body is an animated triangle-mesh collider: every substep its points are linearly interpolated
between frames, its per-vertex velocities set to the frame difference x fps (Newton's friction
needs them), its BVH refitted and its bounding box updated (Newton culls contacts with the box it
had at model finalisation otherwise). ``garment.pins`` (waistband / neck band) are kinematic: they
follow linear blend skinning of their start positions with their nearest rest-body vertex's
weights; ``pins=False`` leaves them free.

Failures (nothing is cached): :class:`SimulationDiverged` on NaN, a vertex faster than ``max_speed``,
an edge stretched past ``MAX_STRETCH``, or an edge with no pinned end held past ``SNAG_STRETCH`` x its
rest length for ``SNAG_SECONDS`` (the cloth snagged on the body: pinned edges follow the body and are
left out); :class:`GarmentLeftBody` when the garment's centroid (mean
vertex) leaves the body's axis-aligned bounding box grown by ``LEAVE_MARGIN`` on every side (it fell
off) or drops into the lowest ``FEET_BAND`` of the body's height (it slid down to the feet);
:class:`GarmentInsideBody` when more than ``INSIDE_SHARE`` of its vertices stay inside the body (the
eps_c rule) for ``INSIDE_SECONDS`` (a physically impossible drape), all checked after every frame.
After a failure that a smaller step can cure (NaN, speed, a torn edge, a snag) the whole simulation is
run again with each of ``settings.retry_substeps`` in turn; a garment that left the body or stayed
inside it, or one moved to a body shape farther than ``FAR_SHAPE`` from its own, is not retried and the
error names the likely cause (the pins, the material, ``garment.betas=motion``). Every attempt is
recorded in the record's ``stats["attempts"]`` and the cache key stays the requested settings. A cached
drape is checked for a snag and for the garment inside the body again when it is loaded; one that fails
is simulated again.
"""

from __future__ import annotations

import contextlib
import json
import logging
import re
import time
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path

import numpy as np
import torch

from drapebench.body.skinning import nearest_body_vertices, transfer_shape
from drapebench.cache import Cache, atomic_write, body_key
from drapebench.errors import DrapeFailed
from drapebench.physics.material import Material
from drapebench.progress import progress as progress_bar
from drapebench.progress import progress_enabled
from drapebench.reference.settings import SimSettings

REFERENCES = Cache("reference", 1)  # bump when the simulation or the stored format changes
MAX_START_INSIDE = 0.01  # a garment with more of its vertices inside the rest body is rejected
MAX_STRETCH = 4.0  # an edge longer than this x its rest length counts as a blow-up
SNAG_STRETCH = 2.5  # an edge with no pinned end held longer than this x its rest length ...
SNAG_SECONDS = 0.5  # ... for this long (sequence time) means the cloth snagged on the body
log = logging.getLogger("drapebench")
LEAVE_MARGIN = 0.10  # m: a garment centroid this far outside the body's bounding box has fallen off
FEET_BAND = 0.15  # a garment centroid in this lowest fraction of the body's height has slid down to the feet
# A drape with more than INSIDE_SHARE of its vertices inside the body for INSIDE_SECONDS is physically impossible.
# The accepted references of the committed tables have eps_c (share inside, mean +- std over frames) of at most
# 0.035 +- 0.13 % (vbd) and 0.30 +- 0.61 % (style3d) (reports/*.csv); a too stiff material leaves a third inside.
INSIDE_SHARE = 0.05
INSIDE_SECONDS = 0.5
FAR_SHAPE = 2.0  # std: a garment moved to a body shape farther than this from its own (the range of the training
#                  data and the tables' shapes) by nearest-vertex transfer is the likely cause of a failure


class SimulationDiverged(DrapeFailed):
    """The reference simulation blew up (NaN, runaway speed or torn elements); no drape was cached, only a
    record of the failure, so the same simulation fails at once until ``force=true``.

    Attributes: garment, sequence (names), frame (sequence frame, negative while settling), reason, cause (the
    likely cause and what to change, when known; else :meth:`advice`); attempts (substeps and failure of each
    try, see :func:`simulate_record`) once retries are done. ``smaller_step_helps``: whether the retry ladder
    (more substeps) can cure this kind of failure.
    """

    verb = "diverged"
    smaller_step_helps = True

    def __init__(self, garment: str, sequence: str, frame: int, n_frames: int, reason: str, settings: SimSettings,
                 cause: str | None = None):  # fmt: skip
        self.garment, self.sequence, self.frame, self.reason, self.cause = garment, sequence, frame, reason, cause
        self._args = (garment, sequence, frame, n_frames, reason, settings, cause)
        where = f"settling frame {frame + settings.settle_frames} of {settings.settle_frames}" if frame < 0 else \
            f"frame {frame} of {n_frames}"  # fmt: skip
        super().__init__(f"reference simulation ({settings.solver}) of garment {garment!r} on sequence {sequence!r} {self.verb} "
                         f"at {where}: {reason}. {cause or self.advice(settings)}")  # fmt: skip

    @staticmethod
    def advice(settings: SimSettings) -> str:
        """What to change when nothing more specific is known."""
        return (f"Try more substeps (substeps={2 * settings.substeps}, i.e. a smaller dt), more iterations "
                f"(iterations={2 * settings.iterations}), a higher sequence fps, or a slower motion; the other solver "
                f"(solver={'style3d' if settings.solver == 'vbd' else 'vbd'}) may also cope.")  # fmt: skip

    def __reduce__(self):  # rebuilt from its arguments (and attempts): parallel workers send it pickled
        return type(self), self._args, {"attempts": getattr(self, "attempts", None)}


class GarmentLeftBody(SimulationDiverged):
    """The garment left the body (fell off, or slid down to the feet); nothing was cached. A smaller step
    does not hold a garment on the body, so it is not retried."""

    verb = "lost the garment"
    smaller_step_helps = False

    @staticmethod
    def advice(settings: SimSettings) -> str:
        if not settings.pins:
            return "The pins are off (reference.pins=false): nothing holds the garment up; turn them on (not retried)."
        return ("Its pins do not hold it: a garment=obj needs garment.pins on its waistband or shoulders (the vertices held "
                "to the body), not the hem; a garment made on another body shape needs garment.betas=motion (not "
                "retried: more substeps do not help).")  # fmt: skip


class GarmentInsideBody(SimulationDiverged):
    """Too much of the garment stayed inside the body: a physically impossible drape; nothing was cached.
    A smaller step does not make the cloth follow the body, so it is not retried."""

    verb = "left the garment inside the body"
    smaller_step_helps = False

    @staticmethod
    def advice(settings: SimSettings) -> str:
        return ("The cloth cannot follow the body: the material is the likely cause (a young or bending_multiplier far "
                "above the presets' makes it too stiff to bend around the body; conf/material/), or a garment made for "
                "another body shape (garment.betas=motion) (not retried: more substeps do not help).")  # fmt: skip


FAILURES = {c.__name__: c for c in (SimulationDiverged, GarmentLeftBody, GarmentInsideBody)}


@dataclass
class SimulationRecord:
    """A reference drape: vertices (T, V, 3); timings_s of the simulation that produced it (setup,
    settle, sequence; stored with the cache entry, so they are the original cost even when loaded);
    load_s the wall time of this call; from_cache; path of the cache file (None when not cached);
    stats (max speed, contact count, ...)."""

    vertices: torch.Tensor
    timings_s: dict
    settings: SimSettings
    from_cache: bool = False
    load_s: float = 0.0
    path: str | None = None
    stats: dict = field(default_factory=dict)

    @property
    def sim_s(self) -> float:
        """Total original simulation wall time (s)."""
        return float(sum(self.timings_s.values()))


def _versions() -> dict:
    out = {}
    for pkg in ("newton", "warp-lang"):
        try:
            out[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            out[pkg] = None
    return out


def _cache_path(garment, seq, settings: SimSettings, *key_parts):
    name = re.sub(r"[^A-Za-z0-9_.-]+", "-", f"{garment.name}_{seq.name}_{settings.solver}")
    return REFERENCES.path(*key_parts, prefix=name)


def _write_record(value: tuple, path) -> None:
    verts, meta = value
    with open(path, "wb") as f:
        np.savez(f, vertices=verts, meta=np.array(json.dumps(meta)))


def _reader(shape: tuple):
    def read(path) -> tuple | None:
        with np.load(path, allow_pickle=False) as data:
            verts, meta = data["vertices"], json.loads(str(data["meta"]))
        return (verts, meta) if verts.shape == shape else None

    return read


def _smoothstep(u: np.ndarray) -> np.ndarray:
    u = np.clip(u, 0.0, 1.0)
    return u * u * u * (u * (6.0 * u - 15.0) + 10.0)


def _timeline(seq, body, settle_frames: int):
    """Body vertices (1 + S + T, Vb, 3) and transforms (1 + S + T, J, 4, 4): rest pose, settling, sequence."""
    betas = seq.betas[None, : body.n_betas].to(body.dtype)
    s = torch.as_tensor(_smoothstep(2.0 * np.arange(settle_frames + 1) / max(settle_frames, 1)), dtype=body.dtype)
    s[0] = 0.0
    pose0, trans0 = seq.poses[:1].to(body.dtype), seq.trans[:1].to(body.dtype)
    with torch.no_grad():
        pre = body.forward(betas.expand(len(s), -1), s[:, None, None] * pose0, s[:, None] * trans0)
    verts = torch.cat([pre.vertices, seq.vertices(body).to(body.dtype)]).double().numpy()
    transforms = torch.cat([pre.transforms, seq.transforms(body).to(body.dtype)])
    return verts, transforms


def _start_state(garment, seq, body):
    """Start positions (V, 3) on the rest body of shape seq.betas, and each vertex's nearest body vertex."""
    idx = nearest_body_vertices(garment.vertices, body, garment.betas)
    with torch.no_grad():
        start = transfer_shape(garment.vertices.to(body.dtype), idx, body, garment.betas, seq.betas)
    return start, idx


class GarmentStartsInside(ValueError):
    """The garment starts inside the rest body of the sequence's shape; nothing was simulated."""


def _check_start(garment, start: torch.Tensor, rest_body: torch.Tensor, body) -> None:
    from drapebench.geometry.sdf import signed_distance

    sd = signed_distance(start[None].float(), rest_body[None].float(), body.faces, outer_faces=body.outer_faces)[0]
    inside = sd < 0
    if inside.float().mean() > MAX_START_INSIDE:
        raise GarmentStartsInside(
            f"garment {garment.name!r} starts inside the body: {int(inside.sum())} of {garment.n_vertices} vertices "
            f"({100 * inside.float().mean():.1f}%, deepest {-1e3 * float(sd.min()):.1f} mm) are inside the rest body "
            f"({body.name}, the sequence's betas). The reference simulator accepts at most "
            f"{100 * MAX_START_INSIDE:.0f}%: rebuild the garment with more ease, for the sequence's body shape "
            f"(make_garment(..., betas=seq.betas)), or move it outward."
        )


def _pin_targets(start: torch.Tensor, pins: torch.Tensor, idx: torch.Tensor, body, transforms: torch.Tensor) -> np.ndarray:
    """(1 + S + T, P, 3) positions of the pinned vertices: LBS of their start positions with nearest-vertex weights."""
    from drapebench.body.lbs import lbs

    if len(pins) == 0:
        return np.zeros((transforms.shape[0], 0, 3))
    with torch.no_grad():
        return lbs(start[pins], body.weights[idx[pins]].to(start.dtype), transforms.to(start.dtype)).double().numpy()


def _left_body(x: np.ndarray, body_points: np.ndarray) -> str | None:
    """Why the garment (V, 3) has left the body (Vb, 3) by the rule of this module's docstring, or None."""
    centre = x.mean(0)
    lo, hi = body_points.min(0), body_points.max(0)
    outside = float(np.maximum(lo - centre, centre - hi).max())
    if outside > LEAVE_MARGIN:
        return (f"the garment fell off: its centroid is {100 * outside:.0f} cm outside the body's bounding box "
                f"(limit LEAVE_MARGIN={100 * LEAVE_MARGIN:.0f} cm)")  # fmt: skip
    height = (centre[2] - lo[2]) / (hi[2] - lo[2])
    if height < FEET_BAND:
        return (f"the garment slid down to the feet: its centroid is at {100 * height:.0f}% of the body's height "
                f"(limit FEET_BAND={100 * FEET_BAND:.0f}%)")  # fmt: skip
    return None


def _free_edges(garment, pinned: bool) -> np.ndarray:
    """(E,) bool: the garment's edges with no pinned end (every edge when the pins are off)."""
    edges = garment.topology.edges.numpy()
    pin = np.zeros(garment.n_vertices, dtype=bool)
    if pinned:
        pin[garment.pins.numpy()] = True
    return ~pin[edges].any(1)


def _snag_frames(fps: float) -> int:
    """Frames an over-stretched free edge may last at ``fps`` before it counts as a snag."""
    return max(1, round(SNAG_SECONDS * fps))


def _snag_reason(peak: float, n_frames: int) -> str:
    return (f"an edge away from the pins stayed stretched past {SNAG_STRETCH:g}x its rest length for {n_frames} frames "
            f"(up to {peak:.1f}x; limits SNAG_STRETCH={SNAG_STRETCH:g}, SNAG_SECONDS={SNAG_SECONDS:g}): the cloth snagged "
            f"on the body")  # fmt: skip


def find_snag(vertices: np.ndarray, garment, pinned: bool, fps: float) -> tuple[int, str] | None:
    """The frame at which a drape (T, V, 3) of ``garment`` (m) has held an edge with no pinned end past
    ``SNAG_STRETCH`` x its rest length for ``SNAG_SECONDS`` at ``fps``, and why; None when it never does."""
    edges, free = garment.topology.edges.numpy(), _free_edges(garment, pinned)
    if not free.any():
        return None
    rest = garment.topology.rest_edge_lengths.double().numpy()[free]
    x = np.asarray(vertices, dtype=np.float64)
    ratio = (np.linalg.norm(x[:, edges[free, 1]] - x[:, edges[free, 0]], axis=-1) / rest).max(1)
    held, need = 0, _snag_frames(fps)
    for t, r in enumerate(ratio):
        held = held + 1 if r > SNAG_STRETCH else 0
        if held >= need:
            return t, _snag_reason(float(ratio[t - need + 1 : t + 1].max()), need)
    return None


def inside_share(x: np.ndarray, body_points: np.ndarray, body_faces: torch.Tensor) -> float:
    """Share (0..1) of the garment's vertices x (V, 3) inside the posed body (Vb, 3), by the eps_c rule."""
    from drapebench.geometry.sdf import inside_body

    points = torch.as_tensor(x, dtype=torch.float32)[None]
    return float(inside_body(points, torch.as_tensor(body_points, dtype=torch.float32)[None], body_faces.cpu()).float().mean())


def find_inside(shares, fps: float) -> tuple[int, str] | None:
    """The first index of ``shares`` (per-frame shares of the garment inside the body) at which more than
    ``INSIDE_SHARE`` has stayed inside for ``INSIDE_SECONDS`` at ``fps``, and why; None when it never does."""
    need, held = max(1, round(INSIDE_SECONDS * fps)), 0
    for t, share in enumerate(shares):
        held = held + 1 if share > INSIDE_SHARE else 0
        if held >= need:
            least = min(shares[t - need + 1 : t + 1])
            return t, (f"at least {100 * least:.0f}% of its vertices stayed inside the body for {need} frames (limits "
                       f"INSIDE_SHARE={100 * INSIDE_SHARE:g}%, INSIDE_SECONDS={INSIDE_SECONDS:g}): a physically impossible drape")  # fmt: skip
    return None


def _likely_cause(garment, seq) -> str | None:
    """The cause a failure most likely has when the scene shows one, with the fix: a garment moved to a body
    shape farther than ``FAR_SHAPE`` from its own. None: the failure's own advice stands."""
    a, b = seq.betas.double().reshape(-1), garment.betas.double().reshape(-1)
    n = min(len(a), len(b))
    far = float((a[:n] - b[:n]).abs().max()) if n else 0.0
    if far > FAR_SHAPE:
        return (f"The garment was made on another body shape and moved to the sequence's, {far:.1f} standard deviations "
                f"away (limit FAR_SHAPE={FAR_SHAPE:g}), by nearest-vertex transfer: make it on the sequence's shape "
                "(garment.betas=motion) (not retried: more substeps do not help).")  # fmt: skip
    return None


def _run(garment, seq, body, material: Material, settings: SimSettings, show_progress: bool):
    t_setup = time.perf_counter()
    S, T = int(settings.settle_frames), seq.n_frames
    start, idx = _start_state(garment, seq, body)
    verts, transforms = _timeline(seq, body, S)
    _check_start(garment, start, torch.as_tensor(verts[0]), body)

    name = f"reference {settings.solver} {garment.name} {seq.name}"
    log.info("%s: %d frames (%d settling) x %d substeps; warp loads its kernels now (the first time on a machine it "
             "compiles them, about 100 s on a CPU)", name, S + T, S, settings.substeps)  # fmt: skip
    from drapebench.reference.scene import ClothScene, resolve_device  # imports newton/warp

    device = resolve_device(settings.device)
    pins = garment.pins.long() if settings.pins else torch.zeros(0, dtype=torch.long)
    pin_q = _pin_targets(start, pins, idx, body, transforms)
    rest = garment.vertices.double().numpy()
    faces = garment.faces.numpy()
    edges = garment.topology.edges.numpy()
    rest_len = garment.topology.rest_edge_lengths.double().numpy()
    free = _free_edges(garment, bool(settings.pins))
    snag_need, held, held_peak, inside = _snag_frames(float(seq.fps)), 0, 0.0, []
    scene = ClothScene(rest, faces, start.double().numpy(), verts[0], body.faces.numpy(), pins.numpy(), material,
                       settings, device)  # fmt: skip
    timings = {"setup": time.perf_counter() - t_setup, "settle": 0.0, "sequence": 0.0}

    n_sub, fps = int(settings.substeps), float(seq.fps)
    dt = 1.0 / (fps * n_sub)
    out = np.empty((T, garment.n_vertices, 3), dtype=np.float32)
    x_prev = scene.positions().astype(np.float64)
    max_speed = 0.0
    bar = progress_bar(total=S + T, desc=name, unit="frame") if show_progress else None
    log_every = max(1, (S + T) // 10) if show_progress and not progress_enabled() else 0  # log lines where no bar shows
    try:
        for k in range(S + T):
            t0 = time.perf_counter()
            body_v = (verts[k + 1] - verts[k]) * fps
            pin_v = (pin_q[k + 1] - pin_q[k]) * fps
            scene.begin_frame()
            for j in range(1, n_sub + 1):
                a = j / n_sub
                scene.set_body(((1 - a) * verts[k] + a * verts[k + 1]).astype(np.float32), body_v.astype(np.float32))
                scene.set_pinned(((1 - a) * pin_q[k] + a * pin_q[k + 1]).astype(np.float32), pin_v.astype(np.float32))
                scene.step(dt)
            x = scene.positions().astype(np.float64)
            frame = k - S
            if not np.isfinite(x).all():
                bad = int((~np.isfinite(x)).any(1).sum())
                raise SimulationDiverged(garment.name, seq.name, frame, T, f"{bad} vertices became NaN/Inf", settings)
            speed = float(np.linalg.norm(x - x_prev, axis=1).max() * fps)
            max_speed = max(max_speed, speed)
            if speed > settings.max_speed:
                raise SimulationDiverged(garment.name, seq.name, frame, T,
                                         f"a vertex moved at {speed:.3g} m/s (limit max_speed={settings.max_speed:g})",
                                         settings)  # fmt: skip
            ratio = np.linalg.norm(x[edges[:, 1]] - x[edges[:, 0]], axis=1) / rest_len
            if ratio.max() > MAX_STRETCH:
                raise SimulationDiverged(garment.name, seq.name, frame, T,
                                         f"an edge stretched to {ratio.max():.1f}x its rest length", settings)  # fmt: skip
            free_max = float(ratio[free].max()) if free.any() else 0.0
            held, held_peak = (held + 1, max(held_peak, free_max)) if free_max > SNAG_STRETCH else (0, 0.0)
            if held >= snag_need:
                raise SimulationDiverged(garment.name, seq.name, frame, T, _snag_reason(held_peak, snag_need), settings)
            left = _left_body(x, verts[k + 1])
            if left is not None:
                raise GarmentLeftBody(garment.name, seq.name, frame, T, left, settings)
            inside.append(inside_share(x, verts[k + 1], body.faces))
            stuck = find_inside(inside[-max(1, round(INSIDE_SECONDS * fps)) :], fps)
            if stuck is not None:
                raise GarmentInsideBody(garment.name, seq.name, frame, T, stuck[1], settings)
            x_prev = x
            if frame >= 0:
                out[frame] = x
            timings["settle" if frame < 0 else "sequence"] += time.perf_counter() - t0
            if bar is not None:
                bar.update(1)
            if k == 0 or (log_every and (k + 1) % log_every == 0):
                elapsed = time.perf_counter() - t_setup
                log.info("%s: frame %d of %d, %.0f s%s", name, k + 1, S + T, elapsed,
                         " (kernels loaded or compiled, scene built)" if k == 0 else "")  # fmt: skip
    finally:
        if bar is not None:
            bar.close()
    stats = {"max_speed": max_speed, "device": device, "n_substeps": (S + T) * n_sub, "inside_share": inside[S:], **_versions()}
    return out, timings, stats


def _resolve(garment, seq, body, material: Material, cfg: SimSettings):
    """The settings with their device resolved, and the cache file of this simulation."""
    if cfg.device is None:
        cfg = cfg.with_(device="cuda:0" if torch.cuda.is_available() else "cpu")
    device_kind = cfg.device.split(":")[0]
    path = _cache_path(
        garment, seq, cfg, garment.vertices, garment.faces, garment.pins if cfg.pins else None, garment.betas,
        seq.betas, seq.poses, seq.trans, float(seq.fps), body_key(body), material.to_dict(),
        {**cfg.to_dict(), "device": device_kind, "retry_substeps": None}, _versions(),
    )  # fmt: skip
    return cfg, path


def reference_path(garment, seq, body, material: Material | None = None, solver: str = "vbd", **settings):
    """The cache file (a Path, which may not exist yet) :func:`simulate_record` reads and writes for these arguments."""
    return _resolve(garment, seq, body, material or Material(), SimSettings.for_solver(solver, **settings))[1]


def _run_with_retries(garment, seq, body, material: Material, settings: SimSettings, show_progress: bool):
    """:func:`_run` at ``settings.substeps``, then after each failure that a smaller step can cure at the next
    of ``settings.retry_substeps`` above it (a garment that left the body or stayed inside it, or one moved to a
    far body shape, is not retried: the error names the likely cause instead). stats gain ``substeps`` (the
    count that succeeded) and ``attempts`` (substeps and failure of each try; the successful one has failure
    None); timings gain ``retries`` (s spent on failed tries) if any. Raises the last failure (its reason lists
    the earlier ones) when every attempt fails."""
    ladder = [int(settings.substeps), *(n for n in settings.retry_substeps if n > settings.substeps)]
    attempts, failed_s, err, cause = [], 0.0, None, None
    for n in ladder:
        t0 = time.perf_counter()
        try:
            verts, timings, stats = _run(garment, seq, body, material, settings.with_(substeps=n), show_progress)
        except SimulationDiverged as e:
            err, cause = e, _likely_cause(garment, seq)
            failed_s += time.perf_counter() - t0
            attempts.append({"substeps": n, "failure": f"{type(e).__name__} at frame {e.frame}: {e.reason}"})
            if not e.smaller_step_helps or cause is not None:
                break
            continue
        attempts.append({"substeps": n, "failure": None})
        if failed_s:
            timings = {**timings, "retries": failed_s}
        return verts, timings, {**stats, "substeps": n, "attempts": attempts}
    reason = err.reason
    if len(attempts) > 1:
        reason += " (also failed with " + "; ".join(f"substeps={a['substeps']}: {a['failure']}" for a in attempts[:-1]) + ")"
    err = type(err)(garment.name, seq.name, err.frame, seq.n_frames, reason, settings.with_(substeps=attempts[-1]["substeps"]), cause)
    err.attempts = attempts
    raise err


def _failure_path(path: Path) -> Path:
    return path.with_name(path.stem + ".failed.json")


def _record_failure(path: Path, err: SimulationDiverged) -> None:
    """Remember that the simulation cached at ``path`` failed at every substep count tried (the error's
    arguments and attempts, no drape), so the next run with the same key fails at once."""
    garment, sequence, frame, n_frames, reason, settings, cause = err._args
    record = {"error": type(err).__name__, "garment": garment, "sequence": sequence, "frame": frame, "n_frames": n_frames,
              "reason": reason, "settings": settings.to_dict(), "cause": cause, "attempts": getattr(err, "attempts", None)}  # fmt: skip
    with atomic_write(_failure_path(path), "w") as f:
        json.dump(record, f)


def recorded_failure(path: str | Path) -> SimulationDiverged | None:
    """The failure recorded for the simulation cached at ``path`` (:func:`reference_path`), as the error it raised
    (with its ``attempts``); None when there is none. An unreadable record is removed with a warning."""
    failure = _failure_path(Path(path))
    if not failure.exists():
        return None
    try:
        r = json.loads(failure.read_text())
        err = FAILURES[r["error"]](r["garment"], r["sequence"], r["frame"], r["n_frames"], r["reason"], SimSettings(**r["settings"]),
                                   r.get("cause"))  # fmt: skip
    except (ValueError, KeyError, TypeError) as e:
        log.warning("removing the unreadable failure record %s (%s)", failure, e)
        failure.unlink(missing_ok=True)
        return None
    err.attempts = r["attempts"]
    return err


def _raise_recorded_failure(path: Path) -> None:
    """Raise the failure recorded for the simulation cached at ``path``, if any (``force=true`` runs it again)."""
    err = recorded_failure(path)
    if err is not None:
        log.warning("this simulation failed before with the same settings (%s); not run again (force=true runs it)", _failure_path(path).name)
        raise err


def simulate_record(
    garment,
    seq,
    body,
    material: Material | None = None,
    solver: str = "vbd",
    *,
    cache: bool = True,
    force: bool = False,
    progress: bool = True,
    **settings,
) -> SimulationRecord:
    """Like :func:`simulate`, returning a :class:`SimulationRecord` (vertices, original timings, stats)."""
    material = material or Material()
    cfg = SimSettings.for_solver(solver, **settings)
    if seq.poses.shape[1] != body.n_joints:
        raise ValueError(f"sequence {seq.name!r} has {seq.poses.shape[1]} joints, body {body.name} has {body.n_joints}")
    if garment.pins.numel() and int(garment.pins.max()) >= garment.n_vertices:
        raise ValueError(f"garment {garment.name!r} pins index vertex {int(garment.pins.max())} of {garment.n_vertices}")
    t0 = time.perf_counter()
    cfg, path = _resolve(garment, seq, body, material, cfg)
    hit = _cached(path, garment, seq, body, cfg, force, t0) if cache else None
    if hit is not None:
        return hit
    with REFERENCES.building(path) if cache else contextlib.nullcontext(False) as waited:
        hit = _cached(path, garment, seq, body, cfg, False, t0) if waited else None  # simulated by the process that held the lock
        if hit is not None:
            return hit
        if cache and not force:
            _raise_recorded_failure(path)
        try:
            verts, timings, stats = _run_with_retries(garment, seq, body, material, cfg, progress)
        except SimulationDiverged as err:
            if cache:
                _record_failure(path, err)
            raise
        if cache:
            meta = {"timings_s": timings, "stats": stats, "settings": cfg.to_dict(), "garment": garment.name,
                    "sequence": seq.name, "material": material.to_dict()}  # fmt: skip
            REFERENCES.store(path, lambda tmp: _write_record((verts, meta), tmp))
    return SimulationRecord(torch.from_numpy(verts), timings, cfg, False, time.perf_counter() - t0,
                            str(path) if cache else None, stats)  # fmt: skip


def _cached(path: Path, garment, seq, body, cfg, force: bool, t0: float) -> SimulationRecord | None:
    """The cached simulation at ``path`` as a record (``from_cache`` True), or None when there is none or it fails
    the snag and inside checks (with a warning: it is simulated again)."""
    hit = REFERENCES.load(path, _reader((seq.n_frames, garment.n_vertices, 3)), force)
    if hit is None:
        return None
    verts, meta = hit
    shares = meta["stats"].get("inside_share")  # per frame, from the simulation; computed for older entries
    if shares is None:
        shares = [inside_share(x, b, body.faces) for x, b in zip(verts, seq.vertices(body).double().numpy())]
    failed = find_snag(verts, garment, bool(cfg.pins), float(seq.fps)) or find_inside(shares, float(seq.fps))
    if failed is None:
        return SimulationRecord(torch.from_numpy(verts), meta["timings_s"], cfg, True, time.perf_counter() - t0, str(path), meta["stats"])
    log.warning("the cached reference %s fails its checks at frame %d (%s); simulating it again", path.name, *failed)
    return None


def simulate(
    garment,
    seq,
    body,
    material: Material | None = None,
    solver: str = "vbd",
    *,
    substeps: int | None = None,
    iterations: int | None = None,
    settle_frames: int | None = None,
    cache: bool = True,
    progress: bool = True,
    dtype: torch.dtype = torch.float32,
    **settings,
) -> torch.Tensor:
    """Physics-based drape of ``garment`` over ``seq`` on ``body``: (T, V, 3) metres, one row per frame.

    Args:
        garment: :class:`drapebench.garments.Garment` (template on the rest body; ``pins`` are kinematic).
        seq: :class:`drapebench.body.BodySequence` (all T frames are returned, transition included).
        body: the :class:`drapebench.body.BodyModel` the sequence poses (its mesh is the collider).
        material: :class:`drapebench.physics.Material` (default cotton); mapping in
            :mod:`drapebench.reference.materials`.
        solver: "vbd" (default) or "style3d"; defaults in ``conf/reference/<solver>.yaml``.
        substeps, iterations, settle_frames: override the solver defaults (None keeps them); other
            :class:`SimSettings` fields (pins, self_contact, contact_ke, damping, device, ...) as keywords.
        cache: read/write ``data/cache/reference`` (keyed by garment, sequence, body model, material,
            settings, device kind and Newton/warp versions); only complete successful runs are stored. A
            simulation that failed at every substep count leaves a ``.failed.json`` record instead, and the
            same call raises that failure at once (``force=True`` in :func:`simulate_record` runs it again).
        progress: show a frames/s progress bar (quiet under CI or without a TTY).
        dtype: output dtype (float32 default).
    Raises:
        ValueError: bad settings, or a garment that starts inside the body.
        SimulationDiverged: NaN, a vertex faster than ``max_speed``, an edge torn past 4x its rest
            length, an edge away from the pins held past 2.5x for 0.5 s (a snag), or
            (:class:`GarmentLeftBody`) the garment left the body, at every substep count
            tried (``retry_substeps``); names the garment, frame and what to change.
    """
    rec = simulate_record(garment, seq, body, material, solver, cache=cache, progress=progress, substeps=substeps,
                          iterations=iterations, settle_frames=settle_frames, **settings)  # fmt: skip
    return rec.vertices.to(dtype)
