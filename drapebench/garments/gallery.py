"""Render every garment of ``conf/garment`` (each kind and its variants) on the canonical body, front and
side, into one PNG.

``python -m drapebench.garments.gallery --out docs/garments.png [--body anny]``
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np


def _shade(V, F, base, light):
    n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    lam = 0.35 + 0.65 * np.abs(n @ light)
    return np.clip(np.asarray(base)[None] * lam[:, None], 0, 1)


def garment_configs(names=None) -> dict[str, tuple[str, dict]]:
    """name -> (kind, factory params) of the garment kind configs in ``conf/garment`` (all, or ``names``),
    in the order of ``GARMENT_KINDS`` with each kind's variants after it."""
    from omegaconf import OmegaConf

    from drapebench.cache import PROJECT_ROOT
    from drapebench.garments import GARMENT_KINDS

    confs = {f.stem: OmegaConf.load(f) for f in sorted((PROJECT_ROOT / "conf" / "garment").glob("*.yaml"))}
    confs = {n: c for n, c in confs.items() if c.kind in GARMENT_KINDS}  # garment=obj is a user's file, not a kind
    unknown = sorted(set(names or []) - set(confs))
    if unknown:
        raise ValueError(f"no garment config {unknown}; configs: {', '.join(confs)}")
    order = sorted(confs, key=lambda n: (GARMENT_KINDS.index(confs[n].kind), n != confs[n].kind, n))
    return {n: (confs[n].kind, OmegaConf.to_container(confs[n].params)) for n in order if names is None or n in names}


def render_gallery(out: Path, body_name: str = "anny", names=None) -> Path:
    """Draw each garment config (front and side view) on the body; returns the written PNG path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    from drapebench.body import load_body
    from drapebench.cache import atomic_write
    from drapebench.garments import make_garment

    body = load_body(body_name)
    garments = garment_configs(names)
    bV, bF = body.v_template.numpy(), body.faces.numpy()
    views = {"front": (0, -90), "side": (0, 0)}  # elevation, azimuth; the body faces -Y
    n = len(garments)
    fig = plt.figure(figsize=(1.7 * n, 2 * 2.6))
    for col, (name, (kind, params)) in enumerate(garments.items()):
        g = make_garment(kind, body, **params)
        gV, gF = g.vertices.numpy(), g.faces.numpy()
        for row, (vname, (elev, azim)) in enumerate(views.items()):
            ax = fig.add_subplot(2, n, row * n + col + 1, projection="3d")
            light = np.array([np.cos(np.radians(azim)), np.sin(np.radians(azim)), 0.4])
            light /= np.linalg.norm(light)
            V = np.concatenate([bV, gV])
            F = np.concatenate([bF, gF + len(bV)])
            colors = np.concatenate([_shade(bV, bF, (0.85, 0.75, 0.68), light), _shade(gV, gF, (0.25, 0.45, 0.8), light)])
            pc = Poly3DCollection(V[F], facecolors=colors, edgecolors="none")
            ax.add_collection3d(pc)
            lo, hi = bV.min(0), bV.max(0)
            c, r = (lo + hi) / 2, (hi - lo).max() / 2
            ax.set_xlim(c[0] - r, c[0] + r), ax.set_ylim(c[1] - r, c[1] + r), ax.set_zlim(c[2] - r, c[2] + r)
            ax.view_init(elev=elev, azim=azim)
            ax.set_box_aspect((1, 1, 1), zoom=1.6)
            ax.set_axis_off()
            if row == 0:
                ax.set_title(f"{name}\n{g.n_vertices} vertices", fontsize=9)
    fig.subplots_adjust(0, 0, 1, 0.93, 0, 0)
    out = Path(out)
    with atomic_write(out, mode=None) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
    return out


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, default=Path("docs/garments.png"))
    parser.add_argument("--body", default="anny", help="body name (anny, anny_lowres) or SMPL-format file")
    parser.add_argument("--garments", nargs="*", help="subset of the garment configs (conf/garment)")
    args = parser.parse_args(argv)
    if args.garments == []:
        parser.error("--garments: name at least one garment config, or leave --garments out for all of them")
    try:
        garment_configs(args.garments)  # the names checked before the body is loaded
    except ValueError as err:
        parser.error(f"--garments: {err}")
    print(render_gallery(args.out, args.body, args.garments))


if __name__ == "__main__":
    main()
