"""Named datasets of body sequences with random body shapes, built once into ``data/datasets/<name>.h5``.

``python -m drapebench.body.dataset train_small`` builds one (``--force`` rebuilds, ``--list`` shows
the names). A complete file whose stored spec hash (spec + motion generator version) matches is
reused; a missing, incomplete, corrupt or outdated file is rebuilt. Held-out motion kinds (``kick``
and ``stress`` never appear in training sets) give a split by motion; disjoint per-sequence seeds
(drawn from each spec's own ``seed``) give a split within a motion. ``train_random_small`` and
``train_random`` hold procedural random motion (``motion=random``) with random body shapes, as many
sequences and frames as ``train_small`` and ``train``; ``train_gaps`` 60 sequences of named and random motion (the scale of a
self-supervised method's public code, below).
"""

from __future__ import annotations

import argparse
import json
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import h5py
import numpy as np

from drapebench.body.defaults import DEFAULT_TRANSITION, HELD_OUT_MOTIONS
from drapebench.body.motions import MOTION_VERSION, MOTIONS, NAMED_MOTIONS, split_motions
from drapebench.body.sequence import BodySequence, make_sequence
from drapebench.cache import Cache, content_hash, data_dir
from drapebench.progress import progress

# TRAIN_MOTIONS are the named training motions (the held-out ones and static left out); the train_random* sets hold
# motion=random instead.
TRAIN_MOTIONS = split_motions(held_out=(*HELD_OUT_MOTIONS, "static"), motions=NAMED_MOTIONS)[0]


@dataclass(frozen=True)
class DatasetSpec:
    """What a dataset holds: ``per_motion`` sequences of each motion, ``n_frames`` frames each
    (plus ``transition``), seeds from ``seed``, body shapes ``betas ~ N(0, beta_sigma^2)`` clipped
    to +-``beta_clip`` on the first ``n_shape_betas`` components (zero on the rest)."""

    motions: tuple[str, ...]
    per_motion: int
    n_frames: int
    split: str
    seed: int = 0
    fps: float = 30.0
    transition: int = DEFAULT_TRANSITION
    beta_sigma: float = 1.0
    beta_clip: float = 2.0
    n_shape_betas: int = 4
    n_betas: int = 10
    params: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        bad = [m for m in self.motions if m not in MOTIONS]
        if bad:
            raise ValueError(f"unknown motion(s) {bad}; valid motions: {', '.join(MOTIONS)}")

    def hash(self) -> str:
        """Content hash of the spec and the motion generator version (a changed generator rebuilds datasets)."""
        return content_hash(asdict(self), MOTION_VERSION)


DATASET_FILES = Cache("datasets", 1)  # named files in data/datasets, checked by the spec hash they store
DATASETS: dict[str, DatasetSpec] = {
    "train_small": DatasetSpec(TRAIN_MOTIONS, per_motion=2, n_frames=90, split="train", seed=0),
    "train": DatasetSpec(TRAIN_MOTIONS, per_motion=8, n_frames=150, split="train", seed=0),
    "train_random_small": DatasetSpec(("random",), per_motion=14, n_frames=90, split="train", seed=30000),
    "train_random": DatasetSpec(("random",), per_motion=56, n_frames=150, split="train", seed=30000),
    # a self-supervised method's scale (no simulation): the 60 sequences of Chen et al. 2024's public code; named
    # motions (arm_raise and twist left out, that method's README) and random motion, 10 sequences of each
    "train_gaps": DatasetSpec(("walk", "run", "jump", "squat", "dance", "random"), per_motion=10, n_frames=150, split="train", seed=50000),
    "val": DatasetSpec(TRAIN_MOTIONS, per_motion=1, n_frames=120, split="val", seed=5000),
    "test": DatasetSpec(("walk", "run", "jump", "dance") + HELD_OUT_MOTIONS[:1], per_motion=1, n_frames=120, split="test", seed=10000),
    "test_heldout": DatasetSpec(HELD_OUT_MOTIONS, per_motion=2, n_frames=120, split="test", seed=20000),
}


def beta_bound(name_or_spec) -> np.ndarray:
    """(n_betas,) the largest |beta_k| in a dataset's sequences (``beta_clip`` on the first
    ``n_shape_betas`` components, 0 after): the body shapes a model trained on it has seen."""
    spec = _resolve(name_or_spec)[1]
    bound = np.zeros(spec.n_betas)
    bound[: spec.n_shape_betas] = spec.beta_clip
    return bound


def sequence_plan(spec: DatasetSpec) -> list[tuple[str, int, int, np.ndarray]]:
    """(motion, index, seed, betas (n_betas,) float32) per sequence, deterministic in ``spec.seed`` (>= 0)."""
    if spec.seed < 0:
        raise ValueError(f"a dataset's seed must be >= 0 (it seeds numpy's generator), got {spec.seed}; e.g. data.seed=40000")
    rng = np.random.default_rng(spec.seed)
    plan = []
    for motion in spec.motions:
        for k in range(spec.per_motion):
            seed = int(rng.integers(2**31))
            betas = np.zeros(spec.n_betas, dtype=np.float32)
            betas[: spec.n_shape_betas] = np.clip(rng.normal(0, spec.beta_sigma, spec.n_shape_betas), -spec.beta_clip, spec.beta_clip)
            plan.append((motion, k, seed, betas))
    return plan


def redrawn(name_or_spec, draw: int) -> DatasetSpec:
    """A dataset's spec with the same motions, counts and frames but other sequence seeds and body shapes (draw
    ``draw`` >= 1; 0 is the dataset itself): fresh training motion for a method that needs no simulation."""
    spec = _resolve(name_or_spec)[1]
    if spec.split != "train":
        raise ValueError(f"only training datasets are redrawn, not a {spec.split!r} split")
    return replace(spec, seed=spec.seed + REDRAW_SEED_STRIDE * int(draw))


REDRAW_SEED_STRIDE = 1_000_003  # a redrawn spec's seed: seed + stride x draw (no two named specs' seeds that close)


def spec_sequences(spec: DatasetSpec) -> list[BodySequence]:
    """Generate the sequences a spec describes (deterministic in ``spec.seed``), with a progress bar."""
    return [
        make_sequence(
            motion, spec.n_frames, spec.fps, seed, betas=betas, transition=spec.transition,
            split=spec.split, name=f"{spec.split}_{motion}_{k:03d}", **spec.params.get(motion, {}),
        )
        for motion, k, seed, betas in progress(sequence_plan(spec), desc=f"sequences ({spec.split})", unit="seq")
    ]  # fmt: skip


def dataset_path(name: str) -> Path:
    """Where a named dataset lives: ``data/datasets/<name>.h5``."""
    return data_dir() / "datasets" / f"{name}.h5"


def _resolve(name_or_spec) -> tuple[str, DatasetSpec]:
    if isinstance(name_or_spec, DatasetSpec):
        return f"custom_{name_or_spec.hash()}", name_or_spec
    if name_or_spec not in DATASETS:
        raise KeyError(f"unknown dataset {name_or_spec!r}; known datasets: {', '.join(DATASETS)}")
    return name_or_spec, DATASETS[name_or_spec]


def dataset_hash(name_or_spec) -> str:
    """Content hash of a dataset (spec + motion generator version), e.g. for checkpoint keys of methods trained on it."""
    return _resolve(name_or_spec)[1].hash()


def _is_current(path: Path, spec_hash: str, force: bool = False) -> bool:
    """True if ``path`` is a sealed, intact dataset built from ``spec_hash`` (else a warning names what is wrong)."""

    def read(p) -> bool | None:
        with h5py.File(p, "r") as f:
            current = f.attrs.get("spec_hash") == spec_hash and f.attrs.get("format") == DATASET_FILES.version
            return True if current and f.attrs.get("complete", False) else None

    return bool(DATASET_FILES.load(path, read, force))


def build_dataset(name_or_spec, force: bool = False, path: Path | None = None) -> Path:
    """Build a named dataset (or a :class:`DatasetSpec`) into h5 unless an identical one exists; returns its path."""
    name, spec = _resolve(name_or_spec)
    path = Path(path) if path is not None else dataset_path(name)
    if _is_current(path, spec.hash(), force):
        return path
    seqs = spec_sequences(spec)

    def write(tmp) -> None:
        with h5py.File(tmp, "w") as f:
            f.attrs["spec"] = json.dumps(asdict(spec))
            f.attrs["spec_hash"] = spec.hash()
            f.attrs["format"] = DATASET_FILES.version
            for seq in seqs:
                seq.write_h5(f.create_group(seq.name))
            f.attrs["complete"] = True

    return DATASET_FILES.store(path, write)


def check_complete(f: h5py.File) -> None:
    """Raise ValueError unless the open dataset file ``f`` was written to the end (its ``complete`` flag)."""
    if not f.attrs.get("complete", False):
        raise ValueError(f"{f.filename} is incomplete; rebuild it with `python -m drapebench.body.dataset <name> --force`")


def load_dataset(name_or_path) -> list[BodySequence]:
    """Sequences of a dataset, by name (built if needed) or by file path."""
    path = Path(name_or_path)
    if path.suffix != ".h5":
        path = build_dataset(str(name_or_path))
    with h5py.File(path, "r") as f:
        check_complete(f)
        return [BodySequence.read_h5(f[k]) for k in sorted(f.keys())]


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description="Build a named dataset of body sequences into data/datasets/.")
    parser.add_argument("names", nargs="*", help=f"dataset names ({', '.join(DATASETS)})")
    parser.add_argument("--force", action="store_true", help="rebuild even if an identical dataset exists")
    parser.add_argument("--list", action="store_true", help="list the known datasets and exit")
    args = parser.parse_args(argv)
    if args.list or not args.names:
        for name, spec in DATASETS.items():
            print(f"{name:20s} {len(spec.motions) * spec.per_motion:4d} sequences x {spec.n_frames} frames  {', '.join(spec.motions)}")
        return
    unknown = [n for n in args.names if n not in DATASETS]  # all checked before any is built
    if unknown:
        parser.error(f"unknown dataset {', '.join(map(repr, unknown))}; known datasets: {', '.join(DATASETS)}")
    for name in args.names:
        _, spec = _resolve(name)
        fresh = not args.force and _is_current(dataset_path(name), spec.hash())
        path = build_dataset(name, force=args.force)
        print(f"{path} ({'up to date, skipped' if fresh else 'built'})")


if __name__ == "__main__":
    main()
