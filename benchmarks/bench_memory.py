"""Peak memory (RSS) of a long lbs run: drape, evaluate and write the prediction of a tshirt on
anny_lowres for 1,000 and 10,000 frames of a walk, each in a fresh process (the run.py pipeline
without training, reference or recording).

Run: python benchmarks/bench_memory.py [n_frames ...]
"""

import os
import subprocess
import sys
import tempfile
import time


def _one(n_frames: int) -> None:
    """The pipeline in this process (the child)."""
    import methods
    from drapebench.body import load_body, make_sequence
    from drapebench.data import TrainData
    from drapebench.garments import make_garment
    from drapebench.metrics import evaluate
    from drapebench.physics import Material
    from drapebench.results import write_prediction

    body = load_body("anny_lowres")
    garment = make_garment("tshirt", body)
    seq = make_sequence("walk", n_frames, seed=0)
    method = methods.get("lbs")({})
    method.fit(TrainData(body=body, material=Material(), garment=garment, load_train=None, test_sequences=[seq]))
    t = time.perf_counter()
    result = method.drape(garment, seq)
    summary, _ = evaluate(garment, seq, body, result.vertices)
    with tempfile.TemporaryDirectory() as tmp:
        write_prediction(os.path.join(tmp, "prediction.h5"), result.vertices, garment.faces)
    print(f"eps_c {summary['eps_c']:.4f} penetration_mm {summary['penetration_mm']:.4f} in {time.perf_counter() - t:.0f} s")


def main(frames: list[int]) -> None:
    for n in frames:
        child = subprocess.Popen([sys.executable, __file__, "--one", str(n)], stdout=subprocess.PIPE, text=True)
        out = child.stdout.read().strip()
        _, status, usage = os.wait4(child.pid, 0)
        if status != 0:
            raise SystemExit(f"{n} frames: the child failed with status {status}")
        print(f"lbs tshirt on anny_lowres, walk, {n} frames: peak RSS {usage.ru_maxrss / 2**20:.2f} GB ({out})")


if __name__ == "__main__":
    if sys.argv[1:2] == ["--one"]:
        _one(int(sys.argv[2]))
    else:
        main([int(a) for a in sys.argv[1:]] or [1000, 10000])
