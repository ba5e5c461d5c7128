"""Training-step cost of GAPS and GenSim on a device: milliseconds per optimisation step, measured as the
difference between two fits of the same model (``--steps`` and 5 steps), so the per-garment set-up, the
training-frame preparation and the first steps' warm-up are left out. GAPS: the tshirt (about 4k vertices) on
anny, windows of 3 frames, batch ``--batch``; GenSim: PEN on its CPU-budget training garments (anny_lowres).
Every step ends with the loss read back (``loss.item()``), so a CUDA step's time is its kernels'.

Run: python benchmarks/bench_train_step.py [--device cuda] [--steps 40] [--batch 8] [--methods gaps gensim]
(benchmarks/gpu_check.sh runs it on cuda and on cpu.)
"""

import argparse
import os
import tempfile

import torch

import methods
from drapebench.body import load_body, make_sequence
from drapebench.data import TrainData
from drapebench.garments import make_garment
from drapebench.physics import Material


def gaps_fit(device: str, steps: int, batch: int) -> float:
    """Training seconds of ``steps`` GAPS steps (template canonical garment: no relaxation solve)."""
    body_cpu = load_body("anny")
    garment = make_garment("tshirt", body_cpu, resolution=0.013)
    seqs = [make_sequence(m, 60, seed=0, transition=10) for m in ("walk", "dance", "jump")]
    m = methods.get("gaps")({"canonical": "template"})
    data = TrainData(body=load_body("anny", device=device), material=Material(), garment=garment, load_train=lambda: seqs)
    return m.fit(data, {"steps": steps, "batch_size": batch, "seed": 0, "checkpoint_every": 10_000}).train_s


GENSIM = {"train": {"garments": [["tshirt", {}], ["skirt", {}]], "seeds": [1], "resolutions": [0.02], "sequences": 2,
                    "n_frames": 20, "frames_per_sequence": 8, "body": "anny_lowres"}}  # fmt: skip


def gensim_fit(device: str, steps: int, batch: int) -> float:
    """Training seconds of ``steps`` GenSim (PEN) steps of ``batch`` frames."""
    m = methods.get("gensim")(GENSIM)
    data = TrainData(body=load_body("anny_lowres", device=device), material=Material())
    return m.fit(data, {"steps": steps, "batch_size": batch, "seed": 0, "checkpoint_every": 10_000}).train_s


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--steps", type=int, default=40)
    ap.add_argument("--batch", type=int, default=8)
    ap.add_argument("--methods", nargs="+", default=["gaps", "gensim"], choices=["gaps", "gensim"])
    args = ap.parse_args()
    os.environ.setdefault("DRAPEBENCH_DATA", tempfile.mkdtemp(prefix="bench_train_step_"))  # no partial checkpoints kept
    fits = {"gaps": gaps_fit, "gensim": gensim_fit}
    where = torch.cuda.get_device_name(0) if args.device.startswith("cuda") else f"cpu, {torch.get_num_threads()} threads"
    for name in args.methods:
        first = fits[name](args.device, 5, args.batch)
        total = fits[name](args.device, args.steps, args.batch)
        per = (total - first) / (args.steps - 5) * 1e3
        print(f"{name} training step on {args.device} ({where}), batch {args.batch}: {per:.1f} ms/step "
              f"({args.steps} steps in {total:.2f} s, 5 in {first:.2f} s)", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
