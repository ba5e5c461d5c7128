"""Parametric garments built on the canonical body: offset surfaces and lofts, cut along isolines, remeshed.

Construction (measured recipe in ``docs/references.md``): the body's signed distance on a
grid (cached per body shape) -> a morphological closing for tops (armpits) -> marching cubes at an
offset ``ease`` -> for loose garments, the union with a convex-hull loft that hangs past both legs
-> exact isoline cuts (hem, waist, neck, sleeves, legs) whose heights and axes come from the body's
joints -> the component around a seed joint -> isotropic remeshing to ``resolution``. The result is
validated (:mod:`drapebench.garments.validate`) and cached by content hash.

Parameters (all kinds): ``ease`` offset from the body (m); ``length`` where the garment ends
(tops: 0 = spine1 .. 1 = hip joint height; skirts, dresses, pants: 0 = hip .. 1 = ankle);
``resolution`` target mean edge length (m); ``sleeve`` position along the arm (0 shoulder, 1 elbow,
2 wrist; negative = armhole); ``flare`` loft widening (m per m) below the hips; ``seed`` varies
ease, length and sleeve slightly.
"""

from __future__ import annotations

import pickle

import numpy as np
import torch
from scipy.spatial import cKDTree

from drapebench.cache import Cache, body_key
from drapebench.garments.fields import SDF_BAND, closed_field, loft_field, marching_cubes, signed_distance_grid
from drapebench.garments.garment import Garment, load_garment
from drapebench.garments.mesh_ops import cut_by_field, isotropic_remesh, keep_component_near
from drapebench.garments.validate import validate_garment
from drapebench.geometry.topology import get_topology
from drapebench.keys import check_known, is_finite_number, is_number

TOPS = ("tshirt", "tank", "longsleeve")
LOOSE = ("skirt", "dress", "gown")
LEGS = ("pants", "shorts")
GARMENT_KINDS = TOPS + LOOSE + LEGS
VERSION = 7  # bump to invalidate cached garments when the construction changes
GARMENTS = Cache("garments", VERSION)


def _write_pickle(rec: dict, path) -> None:
    with open(path, "wb") as f:
        pickle.dump(rec, f)


def _read_pickle(path) -> dict:
    with open(path, "rb") as f:
        return pickle.load(f)


DEFAULTS = {
    "tshirt": dict(ease=0.02, length=0.8, sleeve=0.45, closing=0.04, neck_drop=0.035),
    "tank": dict(ease=0.015, length=0.8, sleeve=0.1, closing=0.04, neck_drop=0.05),
    "longsleeve": dict(ease=0.02, length=0.8, sleeve=1.85, closing=0.04, neck_drop=0.035),
    "skirt": dict(ease=0.015, length=0.45, flare=0.12),
    "dress": dict(ease=0.02, length=0.5, sleeve=0.3, closing=0.04, neck_drop=0.05, flare=0.15),
    "gown": dict(ease=0.02, length=0.85, sleeve=0.1, closing=0.04, neck_drop=0.05, flare=0.2),
    "pants": dict(ease=0.012, length=0.92, closing=0.0),
    "shorts": dict(ease=0.012, length=0.35, closing=0.0),
}
COMMON = dict(resolution=0.015)
ARM_PARTS = ("collar", "shoulder", "elbow", "wrist")


def _landmarks(body, betas: torch.Tensor) -> tuple[np.ndarray, np.ndarray, dict]:
    with torch.no_grad():
        v, j = body.shaped(betas[None, : body.n_betas])
    v, j = v[0].double().cpu().numpy(), j[0].double().cpu().numpy()  # a garment is built on the CPU, whatever the body's device
    return v, j, {n: j[i] for i, n in enumerate(body.joint_names)}


def _lerp(a: float, b: float, t: float) -> float:
    return a + (b - a) * t


def _arm_cut(P, arm_weight, J, side, u, keep_value=-0.1):
    """Cut field of one sleeve: the signed distance (m) past a plane across the arm at position ``u``
    (0 shoulder, 1 elbow, 2 wrist), blended by the point's smooth arm weight w in [0, 1] towards
    ``keep_value`` (never cut) on the torso, so the opening follows a smooth curve."""
    sh, el, wr = J[f"{side}_shoulder"], J[f"{side}_elbow"], J[f"{side}_wrist"]
    if u <= 1:
        axis = (el - sh) / np.linalg.norm(el - sh)
        p = sh + u * (el - sh)
    else:
        axis = (wr - el) / np.linalg.norm(wr - el)
        p = el + (u - 1) * (wr - el)
    return arm_weight * ((P - p) @ axis) + (1.0 - arm_weight) * keep_value


def _arm_weight(P, body_v, weights, joint_names, side, k=8, sigma=0.02):
    """Smooth share (0..1) of a side's arm joints (shoulder/elbow/wrist) in the skinning weights of the
    body vertices near each point (Gaussian-weighted over the k nearest)."""
    arm = [joint_names.index(f"{side}_{p}") for p in ("shoulder", "elbow", "wrist")]
    d, idx = cKDTree(body_v).query(P, k=k)
    g = np.exp(-(((d - d[:, :1]) / sigma) ** 2))
    w_arm = weights[:, arm].sum(1)[idx]
    return (g * w_arm).sum(1) / g.sum(1)


def _build(kind, body, betas, p, seed):
    body_v, _, J = _landmarks(body, betas)
    faces = body.faces.cpu().numpy()
    dominant = body.weights.cpu().numpy().argmax(1)
    names = body.joint_names
    h = float(np.clip(p["resolution"] / 2.5, 0.004, 0.008))
    grid, sdf = signed_distance_grid(body_v, faces, h)
    z = lambda n: float(J[n][2])  # noqa: E731
    hip_z = 0.5 * (z("left_hip") + z("right_hip"))
    ankle_z = 0.5 * (z("left_ankle") + z("right_ankle"))
    waist_z = z("spine1") + 0.03
    if kind in LEGS:
        field = closed_field(sdf, grid, p["closing"]) - p["ease"]
    elif kind == "skirt":
        keep = ~np.isin(dominant, [names.index(f"{s}_{a}") for s in ("left", "right") for a in ARM_PARTS])
        loft = loft_field(grid, body_v, keep, J["pelvis"][:2], waist_z, (hip_z - 0.12, hip_z + 0.08), p["ease"], p["flare"])
        field = np.minimum(loft, sdf - p["ease"])  # the union keeps the ease where hull slices are sparse
    else:
        field = closed_field(sdf, grid, p["closing"]) - p["ease"]
        if kind in LOOSE:
            keep = ~np.isin(dominant, [names.index(f"{s}_{a}") for s in ("left", "right") for a in ARM_PARTS])
            loft = loft_field(grid, body_v, keep, J["pelvis"][:2], waist_z, (hip_z - 0.12, hip_z + 0.08), p["ease"], p["flare"])
            zz = grid.axes()[2][None, None, :]
            field = np.minimum(field, loft + 10.0 * np.maximum(zz - waist_z, 0.0))
    V, F = marching_cubes(field, grid, 0.0)
    cuts = []
    if kind in TOPS or kind in ("dress", "gown"):
        n = np.array([0.0, 0.35, 1.0]) / np.linalg.norm([0.0, 0.35, 1.0])
        cuts.append((V - (J["neck"] - [0, 0, p["neck_drop"]])) @ n)  # keep below the (front-lowered) neck plane
        for side in ("left", "right"):
            cuts.append(_arm_cut(V, _arm_weight(V, body_v, body.weights.cpu().numpy(), names, side), J, side, p["sleeve"]))
    if kind in TOPS:
        cuts.append(_lerp(z("spine1"), hip_z, p["length"]) - V[:, 2])
        seed_joint = "spine2"
    elif kind in LOOSE:
        cuts.append(_lerp(hip_z, ankle_z, p["length"]) - V[:, 2])
        if kind == "skirt":
            cuts.append(V[:, 2] - waist_z)
        seed_joint = "spine2" if kind != "skirt" else "pelvis"
    else:
        cuts.append(V[:, 2] - (z("spine1") + 0.01))
        cuts.append(_lerp(hip_z, ankle_z, p["length"]) - V[:, 2])
        seed_joint = "left_hip"
    V, F = cut_by_field(V, F, np.max(np.stack(cuts), 0))
    V, F = keep_component_near(V, F, J[seed_joint])
    V, F = isotropic_remesh(V, F, p["resolution"])
    V, F = keep_component_near(V, F, J[seed_joint])
    return V, F, body_v, J, hip_z, ankle_z


def _pins(kind, V, F, J) -> np.ndarray:
    """Waistband ring (skirts, pants) or neck-and-shoulder band (tops, dresses)."""
    from drapebench.geometry.topology import build_topology_arrays

    loops = build_topology_arrays(V, F)["boundary_loops"]
    top = max(loops, key=lambda lp: V[lp, 2].mean())
    d, _ = cKDTree(V[top]).query(V)
    band = d < 0.02
    if kind in TOPS or kind in ("dress", "gown"):
        sh_z = 0.5 * (J["left_shoulder"][2] + J["right_shoulder"][2])
        sh_x = abs(J["left_shoulder"][0])
        band |= (V[:, 2] > sh_z) & (np.abs(V[:, 0]) < sh_x + 0.02)
    return np.flatnonzero(band)


def _sections(kind, V, hip_z, ankle_z, length) -> list:
    """Cross-section expectations: loose garments are one piece below the hips, pants two legs."""
    hem = _lerp(hip_z, ankle_z, length)
    if kind in LOOSE:
        return [(_lerp(hip_z, hem, 0.5), 1)]
    if kind in LEGS:
        return [(_lerp(hip_z, hem, 0.6), 2)]
    return []


EXPECTED_LOOPS = {"tshirt": 4, "tank": 4, "longsleeve": 4, "skirt": 2, "dress": 4, "gown": 4, "pants": 3, "shorts": 3}


def garment_params(kind: str, seed: int = 0, **params) -> dict:
    """Full parameter set of a kind (defaults + overrides), with the seed's small variations applied."""
    if kind not in DEFAULTS:
        raise ValueError(f"unknown garment kind {kind!r}; valid kinds: {', '.join(GARMENT_KINDS)}")
    defaults = {**COMMON, **DEFAULTS[kind]}
    check_known(params, defaults, "parameter", f"for {kind}")
    p = {**defaults, **params}
    if seed < 0:
        raise ValueError(f"garment.seed must be >= 0 (it seeds numpy's generator), got {seed}; e.g. garment.seed=0")
    for name, value in params.items():
        if not is_finite_number(value):
            raise ValueError(f"garment.params.{name} must be a finite number, got {value!r}; e.g. garment.params.{name}={defaults[name]}")
    if not 0.003 <= p["resolution"] <= 0.05:
        raise ValueError(f"garment.params.resolution {p['resolution']} m is outside [0.003, 0.05]; e.g. garment.params.resolution={COMMON['resolution']}")
    for name in ("ease", "closing"):
        if not 0.0 <= p.get(name, 0.0) <= SDF_BAND[1] - 0.005:
            raise ValueError(f"garment.params.{name} {p[name]} m is outside [0, {SDF_BAND[1] - 0.005:g}]: the body distance grid is exact "
                             f"only within {SDF_BAND[1]:g} m of the body (drapebench.garments.fields.SDF_BAND)")
    if seed:
        rng = np.random.default_rng(seed)
        p["ease"] *= rng.uniform(0.9, 1.1)
        p["length"] += rng.uniform(-0.03, 0.03)
        if "sleeve" in p:
            p["sleeve"] += rng.uniform(-0.05, 0.05)
    return p


def make_garment(kind: str, body, betas=None, seed: int = 0, name: str | None = None, cache: bool = True, **params) -> Garment:
    """Build (or load from cache) a garment of ``kind`` on ``body`` at shape ``betas`` (rest pose).

    Raises ValueError with the validation report if the construction fails its checks.
    """
    p = garment_params(kind, seed, **params)
    betas_t = body.full_betas(betas).float().cpu()
    path = GARMENTS.path(kind, p, betas_t, body_key(body), prefix=kind, suffix=".pkl")

    def build() -> dict:
        V, F, body_v, J, hip_z, ankle_z = _build(kind, body, betas_t, p, seed)
        report = validate_garment(V, F, body_v, body.faces.cpu().numpy(), target_edge=p["resolution"],
                                  expected_loops=EXPECTED_LOOPS[kind], sections=_sections(kind, V, hip_z, ankle_z, p["length"]))  # fmt: skip
        if not report.ok:
            raise ValueError(f"{kind} on {body.name} (betas {betas_t[:4].tolist()}, params {p}) failed validation:\n{report}")
        return dict(V=V.astype(np.float32), F=F, pins=_pins(kind, V, F, J), stats=report.stats)

    rec = GARMENTS.get_or_build(path, build, _write_pickle, _read_pickle, enabled=cache)
    return Garment(
        name=name or kind, kind=kind, vertices=torch.as_tensor(rec["V"], device="cpu"), faces=torch.as_tensor(rec["F"], device="cpu"),
        pins=torch.as_tensor(rec["pins"], dtype=torch.long, device="cpu"), topology=get_topology(rec["V"], rec["F"]),
        params={**p, "seed": seed, **{f"stat_{k}": v for k, v in rec["stats"].items()}}, betas=betas_t, body_name=body.name,
    )  # fmt: skip


def garment_from_config(g: dict, body, sequence_betas=None) -> Garment:
    """The garment a config's ``garment`` node (a dict: kind, seed, params, path, pins, betas) describes: kind
    ``obj`` loads the user's file ``path`` (:func:`load_garment`; ``pins`` given or found), any other kind is
    built (:func:`make_garment`) on the body shape ``betas``: None = the mean body, ``"motion"`` = the
    sequence's ``sequence_betas`` (S',), or a list. Raises ValueError naming a key the chosen kind does not
    read or an invalid ``betas``."""
    if g["kind"] == "obj":
        if g.get("params"):
            raise ValueError(f"garment.params {sorted(g['params'])} are parameters of the built kinds; garment=obj reads path and pins")
        if g.get("path") in (None, "???"):
            raise ValueError("garment=obj needs the file: garment.path=/path/to/garment.obj (or .ply)")
        if g.get("betas") is not None:
            raise ValueError("garment.betas is read by the built kinds; a garment=obj file is made on the mean body")
        return load_garment(g["path"], body, kind="obj", pins=g.get("pins"))
    for key in ("path", "pins"):
        if g.get(key) is not None:
            raise ValueError(f"garment.{key} is read only by garment=obj (a user's file), not by garment={g['kind']}; "
                             f"use python run.py garment=obj garment.path=/path/to/garment.obj")  # fmt: skip
    betas = _garment_betas(g.get("betas"), sequence_betas)
    body.full_betas(betas, key="garment.betas")  # refused naming the key the user typed
    return make_garment(g["kind"], body, betas=betas, seed=int(g.get("seed", 0)),
                        **g.get("params", {}))  # fmt: skip


def garment_label(g) -> str:
    """The name a config's ``garment`` node goes by in run records, tables and recordings: its ``name`` (a config
    that builds a kind with other parameters, e.g. ``skirt_flared``), else its ``kind``."""
    return g.get("name") or g["kind"]


def _garment_betas(betas, sequence_betas):
    """The body shape (list of floats, or None = mean) a config's ``garment.betas`` names."""
    if betas is None:
        return None
    if betas == "motion":
        return None if sequence_betas is None else [float(b) for b in sequence_betas]
    if isinstance(betas, (list, tuple)) and all(map(is_number, betas)):
        return [float(b) for b in betas]
    raise ValueError(f"garment.betas must be null (the mean body), motion (the sequence's body shape) or a list of numbers, "
                     f"not {betas!r}; e.g. garment.betas=motion or garment.betas=[0.0,2.0]")
