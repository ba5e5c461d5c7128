"""VAE collision model inference cost per frame on the CPU, by stage (VTO Table 2 analogue): motion
descriptor, GRU regressor, VAE decoder, body transforms and the projection (posing the decoded canonical
garment with the diffused body model), for the tshirt and the dress on anny. The paper, on a GTX 1080 Ti:
regressor / decoder / projection 1.7 / 1.6 / 1.4 ms (tshirt), 1.7 / 3.5 / 2.9 ms (dress). Target here: the
whole inference at most 5 ms/frame for the tshirt on 2 CPU cores. Timing does not depend on trained
values: the VAE, pose descriptor and regressor are freshly initialised; the diffused body is the fitted,
cached one (its first fit takes about a minute).

Run: python benchmarks/bench_vae.py [--frames 120] [--device cuda] [--out reports/vae_table2]
(--out writes <out>.md and <out>.csv: VTO Table 2 with the paper's figures beside ours and the machine named;
the committed GPU table is reports/vae_table2_gpu, made with --device cuda.)
"""

import argparse
import platform
import sys
from pathlib import Path

import pandas as pd
import torch

import methods
from drapebench.body import load_body, make_sequence
from drapebench.cache import atomic_write
from drapebench.garments import make_garment
from drapebench.physics import Material
from drapebench.results import git_commit
from drapebench.table_file import write_csv
from methods.vae.descriptor import motion_descriptor
from methods.vae.network import GarmentVAE, PoseDescriptor, Regressor


def untrained_state(model, garment, seq) -> dict:
    """A state for ``model.load_state_dict`` with freshly initialised networks of the configured sizes."""
    p, body = model.p, model.body
    pose = PoseDescriptor(body.n_joints, int(p["regressor"]["pose_code"]))
    r = p["regressor"]
    n_in = motion_descriptor(seq, body.full_betas(seq.betas)[: int(r["betas"])].cpu(), pose.code, r["root"]).shape[-1]
    vae = GarmentVAE(garment.n_vertices, int(p["vae"]["latent"]), p["vae"]["hidden"])
    regressor = Regressor(n_in, vae.latent, int(p["regressor"]["hidden"]), int(p["regressor"]["layers"]))
    return {"vae": vae.state_dict(), "regressor": regressor.state_dict(), "pose": pose.state_dict(),
            "n_vertices": garment.n_vertices, "n_in": n_in, "template": garment.vertices, "evaluations": [],
            "projection_stats": {}}  # fmt: skip


# VTO Table 2 (GTX 1080 Ti), ms per frame: regressor / decoder / projection (posing)
PAPER_MS = {"tshirt": (1.7, 1.6, 1.4), "dress": (1.7, 3.5, 2.9)}
STAGES = {"regressor": ("descriptor", "regressor"), "decoder": ("decoder",), "posing": ("body", "projection")}


def machine(device: str) -> str:
    """The hardware a timing ran on: the GPU's name, or the CPU model and torch's thread count."""
    if device.startswith("cuda"):
        return f"{torch.cuda.get_device_name(0)} (torch {torch.__version__})"
    cpu = next((line.split(":", 1)[1].strip() for line in Path("/proc/cpuinfo").read_text().splitlines()
                if line.startswith("model name")), platform.processor() or platform.machine())  # fmt: skip
    return f"{cpu}, {torch.get_num_threads()} torch threads (torch {torch.__version__})"


def write_table(rows: list[dict], out: Path, device: str, frames: int) -> None:
    """``out``.md and ``out``.csv: per garment the paper's and our regressor / decoder / posing ms per frame."""
    df = pd.DataFrame(rows).set_index("garment")
    command = "python benchmarks/bench_vae.py " + " ".join(sys.argv[1:])
    about = (f"Produced by `{command}` from runs at commit(s) {git_commit()} on {machine(device)}.",
             f"Scene: garments tshirt, dress; body anny; motion kick ({frames} frames); best of 3 drapes per stage; untrained "
             "networks of the configured sizes (timing does not depend on trained values).",
             "Legend: ms per frame (lower). regressor: motion descriptor + GRU; decoder: VAE decoder; posing: body transforms + "
             "the diffused body model's projection of the canonical garment; paper: VTO Table 2 on a GTX 1080 Ti.")  # fmt: skip
    with atomic_write(out.with_suffix(".md"), "w") as f:
        f.write(f"# vae_table2 (VTO Table 2)\n\n{df.to_markdown(floatfmt='.2f')}\n\n" + "\n\n".join(about) + "\n")
    write_csv(out.with_suffix(".csv"), about, df, float_format="%.3f")


def sync(device: str) -> None:
    """Wait for queued GPU work, so that a stage's wall time is its own."""
    if device.startswith("cuda"):
        torch.cuda.synchronize()


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=120, help="frames of the kick motion per drape")
    ap.add_argument("--device", default="cpu", help="torch device (cpu, cuda)")
    ap.add_argument("--out", type=Path, help="also write VTO Table 2 to <out>.md and <out>.csv (e.g. reports/vae_table2)")
    args = ap.parse_args()
    torch.manual_seed(0)
    body = load_body("anny", device=args.device)
    seq = make_sequence("kick", args.frames, seed=0)
    rows = []
    for kind in ("tshirt", "dress"):
        g = make_garment(kind, body)
        m = methods.get("vae")({})
        m.bind(body, Material())
        m.load_state_dict(untrained_state(m, g, seq))
        m.drape(g, seq)  # warm-up: torch kernels
        sync(args.device)
        runs = [m.drape(g, seq) for _ in range(3)]
        per = {k: min(r.timings_ms[k] for r in runs) / seq.n_frames for k in runs[0].timings_ms}
        print(f"vae {kind} ({g.n_vertices} vertices) on anny, {seq.n_frames} frames of kick, {args.device}, {torch.get_num_threads()} threads: "
              f"{sum(per.values()):.2f} ms/frame ({', '.join(f'{k} {v:.2f}' for k, v in per.items())} ms/frame; best of 3 runs per stage)")  # fmt: skip
        ours = {stage: sum(per.get(k, 0.0) for k in parts) for stage, parts in STAGES.items()}
        paper = dict(zip(STAGES, PAPER_MS[kind]))
        rows.append({"garment": kind, "vertices": str(g.n_vertices), **{f"{s} (ms)": ours[s] for s in STAGES}, "total (ms)": sum(ours.values()),
                     **{f"paper {s} (ms)": paper[s] for s in STAGES}, "paper total (ms)": sum(paper.values())})  # fmt: skip
    if args.out:
        write_table(rows, args.out, args.device, seq.n_frames)
        print(args.out.with_suffix(".md"))


if __name__ == "__main__":
    main()
