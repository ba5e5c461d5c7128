"""GenSim's fabric statistics (paper Sec. 3.3): the mean and std of absolute edge-length changes
|l - l0| over about 50 physics-simulated frames of garments and motions outside the test set.

``python -m methods.gensim.fabric`` simulates the scenes of :data:`FIT_SCENES` with the Newton reference
(cached like every reference), samples :data:`FRAMES_PER_SCENE` frames of each evenly after the body has
reached its first pose, fits a Gaussian to the pooled |l - l0| and prints (and caches) mu and sigma.
"""

from __future__ import annotations

import argparse
import json
import logging

import numpy as np
import torch

from drapebench.cache import Cache, body_key, write_json

log = logging.getLogger("drapebench")
FITS = Cache("gensim", 1)
# (garment kind, factory parameters, size seed, training motion): seed 7 gives other sizes than the
# default garments, and none of these motions is a held-out test motion.
FIT_SCENES = (("tshirt", {}, 7, "walk"), ("tank", {}, 7, "jump"), ("longsleeve", {}, 7, "arm_raise"), ("skirt", {}, 7, "walk"),
              ("skirt", {"flare": 0.3}, 7, "twist"), ("skirt", {"flare": 0.02}, 7, "squat"), ("tank", {}, 7, "run"))
N_FIT_FRAMES = 50
FRAMES_PER_SCENE = 10


def edge_change(vertices: torch.Tensor, topology) -> torch.Tensor:
    """|l - l0| (T, E) m of every edge of ``vertices`` (T, V, 3) against the template."""
    from drapebench.geometry.ops import edge_lengths

    return (edge_lengths(vertices, topology.edges) - topology.rest_edge_lengths).abs()


def fit_fabric(body_name: str = "anny_lowres", solver: str = "vbd", n_frames: int = 60, scenes=FIT_SCENES, force: bool = False) -> dict:
    """{"mean": mu (m), "std": sigma (m), "n_frames", "n_edges", "scenes", ...}: the Gaussian fit of |l - l0|
    pooled over the sampled frames; cached by content (body, scenes, solver) in ``data/cache/gensim``."""
    from drapebench.body import load_body, make_sequence
    from drapebench.garments import make_garment
    from drapebench.reference import simulate

    body = load_body(body_name)
    path = FITS.path(body_key(body), list(scenes), solver, n_frames, FRAMES_PER_SCENE, N_FIT_FRAMES, prefix="fabric", suffix=".json")
    fit = FITS.load(path, lambda p: json.loads(p.read_text()), force=force)
    if fit is not None:
        return fit
    from drapebench.errors import DrapeFailed

    changes, used, skipped = [], [], []
    for kind, params, seed, motion in scenes:
        if len(used) * FRAMES_PER_SCENE >= N_FIT_FRAMES:
            break
        garment = make_garment(kind, body, seed=seed, **params)
        seq = make_sequence(motion, n_frames, seed=seed)
        try:
            x = simulate(garment, seq, body, solver=solver)
        except DrapeFailed as err:
            log.warning("fabric fit: skipping %s on %s: %s", kind, motion, err)
            skipped.append([kind, params, seed, motion])
            continue
        frames = np.linspace(seq.n_transition, seq.n_frames - 1, FRAMES_PER_SCENE).round().astype(int)
        changes.append(edge_change(x[frames].to(garment.topology.dtype), garment.topology).reshape(-1))
        used.append([kind, params, seed, motion])
    if len(used) * FRAMES_PER_SCENE < N_FIT_FRAMES:
        raise RuntimeError(f"fabric fit: only {len(used) * FRAMES_PER_SCENE} of {N_FIT_FRAMES} frames simulated (skipped {skipped}); "
                           "add scenes to FIT_SCENES or use solver='style3d'")  # fmt: skip
    phi = torch.cat(changes).double()
    fit = {"mean": float(phi.mean()), "std": float(phi.std()), "n_frames": len(used) * FRAMES_PER_SCENE, "n_edges": int(len(phi)),
           "scenes": used, "skipped": skipped, "body": body_name, "solver": solver}  # fmt: skip
    FITS.store(path, lambda tmp: write_json(tmp, fit))
    return fit


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description="Fit GenSim's fabric statistics (mu, sigma of |l - l0|) to reference simulations.")
    parser.add_argument("--body", default="anny_lowres")
    parser.add_argument("--solver", default="vbd", choices=("vbd", "style3d"))
    parser.add_argument("--force", action="store_true", help="refit even if a cached fit exists")
    args = parser.parse_args(argv)
    print(json.dumps(fit_fabric(args.body, args.solver, force=args.force), indent=2))


if __name__ == "__main__":
    main()
