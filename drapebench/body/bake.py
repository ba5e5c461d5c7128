"""Bake the SMPL-format ``anny`` and ``anny_lowres`` bodies from the Anny package.

Run ``python -m drapebench.body.bake`` (needs the ``bake`` extra: ``pip install anny==0.6.2``).
Writes ``data/bodies/anny.npz`` (Anny default topology, 13,718 vertices) and
``data/bodies/anny_lowres.npz`` (topology ``notoes_collapse10pc``, 1,229 vertices).

What is baked:

* **Skeleton**: Anny's 104 bones reduced to the 22 joints of :data:`JOINT_NAMES` (SMPL naming).
  Each joint is driven by its first Anny bone; the other bones of its group (fingers, toes, eyes,
  twist bones) keep their reference relative transform, and their skinning weights are summed into
  the joint (see :data:`BONE_GROUPS`). Joint positions are the driver bones' heads in Anny's
  reference pose (identity ``local-ref`` deltas), which is also the rest pose of the baked model:
  ``pose = 0`` reproduces ``v_template`` exactly.
* **Shape space**: ``N_SAMPLES`` phenotypes (gender, age, muscle, weight, height, proportions) drawn
  with a fixed seed from the adult population of :data:`PHENOTYPE_POPULATION` are posed at the
  reference pose; a PCA of the full-resolution meshes gives ``shapedirs`` scaled so that ``betas`` are
  in standard deviations of that population: betas ~ N(0, I) is the population.
  The low-resolution body reuses the same PCA coefficients (its ``shapedirs`` are regressed on them),
  so the same ``betas`` mean the same person at both resolutions.
* **Joint regressor**: per joint, an affine combination (weights summing to one) of nearby vertices
  fitted by ridge least squares so that ``J_regressor @ v_shaped`` follows the joint over all samples.

Anny conventions carried over: metres, Z up, facing -Y, +X is the body's left; the pelvis (root
head) is at the origin for every shape.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np

from drapebench.body.model import BODY_DIR
from drapebench.cache import atomic_write, cache_dir

JOINT_NAMES = (
    "pelvis", "spine1", "spine2", "spine3", "neck", "head",
    "left_hip", "left_knee", "left_ankle", "left_foot",
    "right_hip", "right_knee", "right_ankle", "right_foot",
    "left_collar", "left_shoulder", "left_elbow", "left_wrist",
    "right_collar", "right_shoulder", "right_elbow", "right_wrist",
)  # fmt: skip
PARENTS = (-1, 0, 1, 2, 3, 4, 0, 6, 7, 8, 0, 10, 11, 12, 3, 14, 15, 16, 3, 18, 19, 20)

# Reduced joint -> Anny bones (the first is the driver). "{s}" is the side suffix (L / R).
BONE_GROUPS = {
    "pelvis": ["root", "pelvis.L", "pelvis.R", "spine05"],
    "spine1": ["spine04", "spine03"],
    "spine2": ["spine02"],
    "spine3": ["spine01"],
    "neck": ["neck01", "neck02", "neck03"],
    "head": ["head", "eye.L", "eye.R"],
    "hip": ["upperleg01.{s}", "upperleg02.{s}"],
    "knee": ["lowerleg01.{s}", "lowerleg02.{s}"],
    "ankle": ["foot.{s}"],
    "foot": ["toe1-1.{s}", "toe*.{s}"],
    "collar": ["clavicle.{s}", "shoulder01.{s}"],
    "shoulder": ["upperarm01.{s}", "upperarm02.{s}"],
    "elbow": ["lowerarm01.{s}", "lowerarm02.{s}"],
    "wrist": ["wrist.{s}", "finger*.{s}", "metacarpal*.{s}"],
}

# The adult population the shape space spans, per Anny phenotype (values in Anny's [0, 1] range; draws
# are clipped to it): ("uniform", lo, hi) or ("normal", mean, std). Anny's height phenotype is about
# 1.09 m per unit (measured: 1.37 m at 0 to 2.45 m at 1 for a young adult) and 0.5 is 1.83 m tall at
# mid gender, so a uniform draw spans giants and children; the normal below puts the population at
# 1.70 m +- 0.09 m (std, gender included). Age 0.6-0.95 is young adult to old (0.667 = young adult).
# Weight, muscle and proportions change the waist by at most 0.77-0.93 m over their whole range
# (measured), so they are drawn over all of it.
PHENOTYPE_POPULATION = {
    "gender": ("uniform", 0.0, 1.0),
    "age": ("uniform", 0.6, 0.95),
    "muscle": ("uniform", 0.0, 1.0),
    "weight": ("uniform", 0.0, 1.0),
    "height": ("normal", 0.38, 0.075),
    "proportions": ("uniform", 0.0, 1.0),
}
N_SAMPLES = 320
N_BETAS = 10
SEED = 0
TOPOLOGIES = {"anny": "anny", "anny_lowres": "notoes_collapse10pc"}


def _group_of_bones(labels: list[str]) -> np.ndarray:
    """Map each Anny bone label to a reduced joint index; raise if a bone is left unassigned."""
    import fnmatch

    out = np.full(len(labels), -1, dtype=np.int64)
    drivers = {}
    for j, name in enumerate(JOINT_NAMES):
        side = None
        key = name
        if name.startswith(("left_", "right_")):
            side = "L" if name.startswith("left_") else "R"
            key = name.split("_", 1)[1]
        patterns = [p.format(s=side) for p in BONE_GROUPS[key]]
        for b, label in enumerate(labels):
            if out[b] < 0 and any(fnmatch.fnmatchcase(label, p) for p in patterns):
                out[b] = j
        drivers[name] = labels.index(patterns[0])
    missing = [labels[b] for b in np.flatnonzero(out < 0)]
    if missing:
        raise RuntimeError(f"Anny bones not assigned to a reduced joint: {missing}")
    return out, np.array([drivers[n] for n in JOINT_NAMES])


def sample_phenotypes(n: int, seed: int = SEED) -> dict[str, np.ndarray]:
    """``n`` adult phenotypes drawn from :data:`PHENOTYPE_POPULATION`, each clipped to Anny's [0, 1]."""
    rng = np.random.default_rng(seed)
    out = {}
    for key, (law, a, b) in PHENOTYPE_POPULATION.items():
        draw = rng.uniform(a, b, n) if law == "uniform" else rng.normal(a, b, n)
        out[key] = np.clip(draw, 0.0, 1.0)
    return out


def _anny_reference(model, phenotypes: dict[str, np.ndarray], batch: int = 32):
    """Reference-pose vertices (N,V,3) and bone heads (N,104,3) for the given phenotypes."""
    import torch

    n = len(next(iter(phenotypes.values())))
    verts, heads = [], []
    with torch.no_grad():
        for s in range(0, n, batch):
            kw = {k: torch.as_tensor(v[s : s + batch], dtype=torch.float64) for k, v in phenotypes.items()}
            out = model(phenotype_kwargs=kw)
            verts.append(out["vertices"].double().numpy())
            heads.append(out["bone_poses"][..., :3, 3].double().numpy())
    return np.concatenate(verts), np.concatenate(heads)


def _fit_joint_regressor(verts: np.ndarray, joints: np.ndarray, weights: np.ndarray, n_near: int = 64, ridge: float = 1e-4) -> tuple[np.ndarray, np.ndarray]:
    """Affine vertex combinations per joint fitted over samples.

    verts (N,V,3), joints (N,J,3), weights (V,J) skinning weights. For each joint, candidates are the
    ``n_near`` vertices closest to the mean joint among those skinned (> 0.05) to it or its parent.
    Returns the (J,V) regressor and the per-joint RMS residual in metres.
    """
    N, V, _ = verts.shape
    J = joints.shape[1]
    mean_v = verts.mean(0)
    reg = np.zeros((J, V))
    rms = np.zeros(J)
    for j in range(J):
        p = PARENTS[j]
        mask = weights[:, j] > 0.05
        if p >= 0:
            mask |= weights[:, p] > 0.05
        cand = np.flatnonzero(mask)
        d = np.linalg.norm(mean_v[cand] - joints[:, j].mean(0), axis=1)
        cand = cand[np.argsort(d)[:n_near]]
        # rows: (sample, coord); columns: candidate vertices; constraint sum(w) = 1
        A = verts[:, cand, :].transpose(0, 2, 1).reshape(N * 3, len(cand))
        b = joints[:, j, :].reshape(N * 3)
        # Centre on the mean joint so the ridge pulls towards uniform weights of nearby points.
        K = len(cand)
        H = A.T @ A + ridge * np.trace(A.T @ A) / K * np.eye(K)
        kkt = np.block([[H, np.ones((K, 1))], [np.ones((1, K)), np.zeros((1, 1))]])
        rhs = np.concatenate([A.T @ b, [1.0]])
        w = np.linalg.solve(kkt, rhs)[:K]
        reg[j, cand] = w
        rms[j] = np.sqrt(np.mean((A @ w - b) ** 2))
    return reg, rms


def _reduced_weights(model, bone_to_joint: np.ndarray) -> np.ndarray:
    """Anny's sparse top-k bone weights summed into the reduced joints: (V, 22)."""
    w = model.vertex_bone_weights.double().numpy()
    idx = model.vertex_bone_indices.numpy()
    V = w.shape[0]
    out = np.zeros((V, len(JOINT_NAMES)))
    np.add.at(out, (np.repeat(np.arange(V), w.shape[1]), bone_to_joint[idx].ravel()), w.ravel())
    return out / out.sum(1, keepdims=True)


def bake(out_dir: Path = BODY_DIR, n_samples: int = N_SAMPLES, n_betas: int = N_BETAS, seed: int = SEED) -> dict:
    """Bake both bodies into ``out_dir``; returns a dict of fidelity figures for PROVENANCE.md."""
    os.environ.setdefault("ANNY_CACHE_DIR", str(cache_dir("anny")))
    os.environ.setdefault("WARP_CACHE_PATH", str(cache_dir("warp")))
    import anny
    import torch

    t0 = time.time()
    phen = sample_phenotypes(n_samples, seed)
    from importlib.metadata import version

    report: dict = {"anny_version": version("anny"), "n_samples": n_samples, "seed": seed}
    coeffs = None
    for name, topology in TOPOLOGIES.items():
        model = anny.Anny(topology=topology).to(torch.float64)
        labels = list(model.bone_labels)
        bone_to_joint, drivers = _group_of_bones(labels)
        verts, heads = _anny_reference(model, phen)
        joints = heads[:, drivers]
        faces = model.get_triangular_faces().numpy()
        weights = _reduced_weights(model, bone_to_joint)
        V = verts.shape[1]
        flat = verts.reshape(n_samples, -1)
        mean = flat.mean(0)
        if coeffs is None:  # PCA on the full-resolution body defines the betas
            U, S, Vt = np.linalg.svd(flat - mean, full_matrices=False)
            std = S[:n_betas] / np.sqrt(n_samples - 1)
            coeffs = U[:, :n_betas] * np.sqrt(n_samples - 1)  # (N, S) in std units
            coeffs *= _growth_signs(Vt[:n_betas], mean.reshape(-1, 3))  # + beta = a larger body
            explained = (S[:n_betas] ** 2).sum() / (S**2).sum()
            report["pca_explained_variance"] = float(explained)
            report["pca_std"] = std.tolist()
        # shapedirs by least squares on the shared coefficients (exact PCA for the full body)
        dirs, *_ = np.linalg.lstsq(coeffs, flat - mean, rcond=None)  # (S, V*3)
        shapedirs = dirs.T.reshape(V, 3, n_betas)
        recon = mean + coeffs @ dirs
        report[f"{name}_pca_train_err_mm"] = float(np.linalg.norm((recon - flat).reshape(n_samples, V, 3), axis=-1).mean() * 1e3)
        # Joint regressor fitted on the PCA-reconstructed shapes the model will actually produce
        n_near = int(np.clip(64 * V / 1229, 64, 320))  # a similar surface patch at both resolutions
        J_reg, rms = _fit_joint_regressor(recon.reshape(n_samples, V, 3), joints, weights, n_near=n_near)
        report[f"{name}_joint_regressor_rms_mm"] = float(np.sqrt((rms**2).mean()) * 1e3)
        arrays = dict(
            v_template=mean.reshape(V, 3).astype(np.float32),
            shapedirs=shapedirs.astype(np.float32),
            J_regressor=J_reg.astype(np.float32),
            weights=weights.astype(np.float32),
            parents=np.array(PARENTS, dtype=np.int64),
            faces=faces.astype(np.int32),
            joint_names=np.array(JOINT_NAMES),
            up_axis=np.array("z"),
            anny_topology=np.array(topology),
            anny_bone_labels=np.array(labels),
            anny_bone_to_joint=bone_to_joint,
            phenotype_population=np.array(json.dumps(PHENOTYPE_POPULATION)),
            anny_version=np.array(report["anny_version"]),
            pca_std=np.array(report["pca_std"], dtype=np.float32),  # std of each PCA coefficient (metres, L2 over all V*3 coords)
            pca_explained_variance=np.array(report["pca_explained_variance"]),
            n_samples=np.array(n_samples),
            seed=np.array(seed),
        )
        path = Path(out_dir) / f"{name}.npz"
        with atomic_write(path) as f:
            np.savez_compressed(f, **arrays)
        report[f"{name}_vertices"] = V
        report[f"{name}_bytes"] = path.stat().st_size
    report["shape_space"] = shape_space_table(Path(out_dir) / "anny.npz")
    report["bake_s"] = time.time() - t0
    return report


def _growth_signs(directions: np.ndarray, mean_vertices: np.ndarray) -> np.ndarray:
    """(S,) +-1 per PCA direction (S, V*3) so that a positive coefficient moves the vertices away from the
    body's centroid on average (a larger body); the SVD's sign is arbitrary."""
    radial = (mean_vertices - mean_vertices.mean(0)).reshape(-1)
    return np.where(directions @ radial >= 0, 1.0, -1.0)


def shape_space_table(path: Path, components: int = 4, values=(-3, -2, 0, 2, 3)) -> dict:
    """Height and waist girth (m) of the baked body ``path`` at each of ``values`` on each of the first
    ``components`` betas (the others 0): {"b0": {"-3": [height, girth], ...}, ...}."""
    import torch

    from drapebench.body.measure import body_height, waist_girth
    from drapebench.body.model import load_body

    body = load_body(str(path), dtype=torch.float64)
    table = {}
    for k in range(min(components, body.n_betas)):
        row = {}
        for value in values:
            betas = torch.zeros(1, body.n_betas, dtype=torch.float64)
            betas[0, k] = value
            v, j = body.shaped(betas)
            v, j = v[0].numpy(), j[0].numpy()
            row[str(value)] = [round(body_height(v), 3), round(waist_girth(v, body.faces.numpy(), j, body.joint_names), 3)]
        table[f"b{k}"] = row
    return table


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, default=BODY_DIR, help="output folder (default data/bodies)")
    parser.add_argument("--samples", type=int, default=N_SAMPLES, help="number of sampled phenotypes")
    parser.add_argument("--betas", type=int, default=N_BETAS, help="number of PCA shape components")
    args = parser.parse_args(argv)
    if args.betas < 1 or args.samples <= args.betas:  # the PCA of N samples has at most N - 1 components that vary
        parser.error(f"--samples {args.samples} --betas {args.betas}: need 1 <= betas < samples "
                     f"(defaults: --samples {N_SAMPLES} --betas {N_BETAS})")  # fmt: skip
    report = bake(args.out, args.samples, args.betas)
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
