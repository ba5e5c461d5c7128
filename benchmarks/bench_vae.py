"""VAE collision model inference cost per frame on the CPU, by stage (VTO Table 2 analogue): motion
descriptor, GRU regressor, VAE decoder, body transforms and the projection (posing the decoded canonical
garment with the diffused body model), for the tshirt and the dress on anny. The paper, on a GTX 1080 Ti:
regressor / decoder / projection 1.7 / 1.6 / 1.4 ms (tshirt), 1.7 / 3.5 / 2.9 ms (dress). Target here: the
whole inference at most 5 ms/frame for the tshirt on 2 CPU cores. Timing does not depend on trained
values: the VAE, pose descriptor and regressor are freshly initialised; the diffused body is the fitted,
cached one (its first fit takes about a minute).

Run: python benchmarks/bench_vae.py [--frames 120]
"""

import argparse

import torch

import methods
from drapebench.body import load_body, make_sequence
from drapebench.garments import make_garment
from drapebench.physics import Material
from methods.vae.descriptor import motion_descriptor
from methods.vae.network import GarmentVAE, PoseDescriptor, Regressor


def untrained_state(model, garment, seq) -> dict:
    """A state for ``model.load_state_dict`` with freshly initialised networks of the configured sizes."""
    p, body = model.p, model.body
    pose = PoseDescriptor(body.n_joints, int(p["regressor"]["pose_code"]))
    n_in = motion_descriptor(seq, body.full_betas(seq.betas), pose.code).shape[-1]
    vae = GarmentVAE(garment.n_vertices, int(p["vae"]["latent"]), p["vae"]["hidden"])
    regressor = Regressor(n_in, vae.latent, int(p["regressor"]["hidden"]), int(p["regressor"]["layers"]))
    return {"vae": vae.state_dict(), "regressor": regressor.state_dict(), "pose": pose.state_dict(),
            "n_vertices": garment.n_vertices, "n_in": n_in, "template": garment.vertices, "evaluations": [],
            "projection_stats": {}}  # fmt: skip


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=120, help="frames of the kick motion per drape")
    args = ap.parse_args()
    torch.manual_seed(0)
    body = load_body("anny")
    seq = make_sequence("kick", args.frames, seed=0)
    for kind in ("tshirt", "dress"):
        g = make_garment(kind, body)
        m = methods.get("vae")({})
        m.bind(body, Material())
        m.load_state_dict(untrained_state(m, g, seq))
        m.drape(g, seq)  # warm-up: torch kernels
        runs = [m.drape(g, seq) for _ in range(3)]
        per = {k: min(r.timings_ms[k] for r in runs) / seq.n_frames for k in runs[0].timings_ms}
        print(f"vae {kind} ({g.n_vertices} vertices) on anny, {seq.n_frames} frames of kick, cpu, {torch.get_num_threads()} threads: "
              f"{sum(per.values()):.2f} ms/frame ({', '.join(f'{k} {v:.2f}' for k, v in per.items())} ms/frame; best of 3 runs per stage)")  # fmt: skip


if __name__ == "__main__":
    main()
