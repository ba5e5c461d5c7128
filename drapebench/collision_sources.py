"""Where a run's collisions come from: the garment vertices inside the body (what ε_c counts) split by each
per-vertex mask the method's drape reports in its extras (e.g. which vertices a stage held fixed) and by whether
they were inside at each earlier stage in the drape's space (the method's ``displaced_from`` extras, e.g. a
deformation a network then corrects).

Run: python -m drapebench.collision_sources <run dir> [<run dir> ...]

The run's trained method drapes its test sequence again (:func:`drapebench.trained_run.load_run`); frames of the
transition from the rest pose are left out when the run's metrics leave them out (``eval.skip_transition``). Per
run it prints ε_c of the drape and of every stage, and for every mask the share of the vertices it holds, ε_c
among them and the share of the inside vertices they make; then the share of the inside vertices that were inside
at each stage, and their depth (mm: median, 90th percentile, max).
"""

from __future__ import annotations

import argparse

import numpy as np
import torch

from drapebench.geometry.sdf import closest_body_point


def signed_distances(points: torch.Tensor, body_vertices: torch.Tensor, body, chunk: int = 16) -> torch.Tensor:
    """(T, V) signed distance (m, negative inside) of points (T, V, 3) to the posed body (T, Vb, 3) of ``body``
    (its faces and outer faces), as ε_c reads it, ``chunk`` frames at a time."""
    return torch.cat([closest_body_point(points[a : a + chunk], body_vertices[a : a + chunk], body.faces, outer_faces=body.outer_faces).distance
                      for a in range(0, len(points), chunk)])  # fmt: skip


def collision_sources(drape: torch.Tensor, stages: dict, masks: dict, body_vertices: torch.Tensor, body) -> dict:
    """For a drape (T, V, 3) m on the posed body (T, Vb, 3), earlier ``stages`` {name: (T, V, 3) m, in the drape's
    space} and per-vertex ``masks`` {name: (T, V) bool}: {"eps_c": % of vertices inside, "stages": {name: its ε_c},
    "masks": {name: {"share": % of the vertices it holds, "eps_c": % inside among them, "share_of_inside": % of the
    inside vertices it holds}}, "inside_at": {stage: % of the drape's inside vertices inside at that stage},
    "depth_mm": (median, p90, max) of the inside vertices' depth, or None when none is inside}."""
    distance = signed_distances(drape, body_vertices, body)
    inside = distance < 0
    at = {k: signed_distances(v, body_vertices, body) < 0 for k, v in stages.items()}
    n_in = max(int(inside.sum()), 1)
    pct = lambda x: 100.0 * float(x)  # noqa: E731
    depth = (-distance[inside] * 1e3).cpu()
    return {
        "eps_c": pct(inside.double().mean()),
        "stages": {k: pct(v.double().mean()) for k, v in at.items()},
        "masks": {k: {"share": pct(m.double().mean()), "eps_c": pct((inside & m).sum() / max(int(m.sum()), 1)),
                      "share_of_inside": pct((inside & m).sum() / n_in)} for k, m in masks.items()},  # fmt: skip
        "inside_at": {k: pct((inside & v).sum() / n_in) for k, v in at.items()},
        "depth_mm": tuple(np.percentile(depth.numpy(), [50, 90, 100])) if len(depth) else None,
    }


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("runs", nargs="+", help="run folders (each with its config.yaml and metrics.json)")
    args = parser.parse_args(argv)
    from drapebench.trained_run import load_run

    for run_dir in args.runs:
        try:
            run = load_run(run_dir)
        except (FileNotFoundError, ValueError) as err:  # not a run's folder, or its model no longer cached
            parser.error(str(err))
        with torch.inference_mode():
            result = run.method.drape(run.garment, run.seq)
        n = result.vertices.shape[0]
        first = run.seq.n_transition if run.cfg.eval.skip_transition and run.seq.n_transition < n else 0  # as the metrics skip it
        extras = result.extras or {}
        stages = {k: extras[k][first:] for k in run.method.displaced_from if k in extras}
        masks = {k: v[first:].bool() for k, v in extras.items() if torch.is_tensor(v) and v.dtype == torch.bool and v.shape[:1] == (n,)}
        found = collision_sources(result.vertices[first:], stages, masks, run.seq.vertices(run.body)[first:].to(result.vertices.device), run.body)
        print(f"{run_dir}: {run.cfg.method.name} on the {run.garment.kind}, {n - first} frames; eps_c {found['eps_c']:.3f} %")
        for name, value in found["stages"].items():
            print(f"  stage {name}: eps_c {value:.3f} %; {found['inside_at'][name]:.1f} % of the drape's inside vertices were inside there")
        for name, m in found["masks"].items():
            print(f"  mask {name}: {m['share']:.1f} % of the vertices, eps_c {m['eps_c']:.3f} % among them, "
                  f"{m['share_of_inside']:.1f} % of the inside vertices")  # fmt: skip
        if found["depth_mm"] is not None:
            print("  depth of the inside vertices (mm): median {:.2f}, p90 {:.2f}, max {:.2f}".format(*found["depth_mm"]))


if __name__ == "__main__":
    main()
