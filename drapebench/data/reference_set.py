"""Reference training data: physics-based drapes of one garment over many motions and body shapes.

``build_reference_set(garment, body, material, spec)`` plans the body sequences of a
:class:`ReferenceSetSpec` (:func:`drapebench.body.dataset.sequence_plan`: motions x ``per_motion``,
random body shapes, deterministic in ``seed``), simulates each with
:func:`drapebench.reference.simulate_record` in parallel worker processes (joblib), and returns a
:class:`ReferenceSet`. Each drape is one entry of the reference cache, so a rerun or a run resumed
after an interruption simulates only the sequences not done yet. A simulation that fails
(:class:`~drapebench.reference.SimulationDiverged`, the garment leaving the body, a garment starting
inside a body shape) is never cached: it is recorded in the set's manifest (``data/cache/reference_sets``,
garment, sequence, cause) and skipped, also by later runs, until ``force``; its place in the set goes to a
replacement (:func:`replacement_sequence`: the same motion kind and body shape, another seed), up to
``replace_failed`` tries per place, each failure recorded.

Presets are ``conf/data/<name>.yaml`` (``data=cpu`` small, the default; ``data=paper`` large, for a GPU);
by hand: ``python -m drapebench.data.reference_set --garment tshirt --body anny --data cpu --jobs 2``; on a
cluster, one job per sequence through Hydra's submitit launcher: :mod:`drapebench.data.reference_jobs`.
:func:`collect_reference_set` says what the cache holds of a set (done, failed, missing) without simulating.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch

from drapebench.body.dataset import REDRAW_SEED_STRIDE, spec_sequences
from drapebench.body.sequence import make_sequence
from drapebench.cache import Cache
from drapebench.data.reference_spec import ReferenceSetSpec
from drapebench.data.references import References, read_drape
from drapebench.progress import progress as progress_bar

MANIFESTS = Cache("reference_sets", 1)  # per (garment, planned drapes): which sequences failed and why


@dataclass
class ReferenceSet:
    """The successful drapes of a reference set: ``set[i]`` is (BodySequence, vertices (T, V, 3) float32 m),
    read from the reference cache on each access; ``sequences`` those sequences; ``failed`` one dict per
    failed simulation (garment, sequence, error, cause; replacements' failures included); ``planned`` one
    sequence per place of the plan (the planned one or, where it failed, its last replacement);
    ``sim_s`` the original simulation time of the successful drapes; ``wall_s`` this build's wall time."""

    garment: str
    spec: ReferenceSetSpec
    planned: list
    paths: dict[str, str]
    failed: list[dict]
    sim_s: float = 0.0
    wall_s: float = 0.0

    @property
    def sequences(self) -> list:
        """The sequences with a drape, in plan order."""
        return [seq for seq in self.planned if seq.name in self.paths]

    def __len__(self) -> int:
        return len(self.paths)

    def __getitem__(self, i: int):
        seq = self.sequences[i]
        return seq, read_drape(self.paths[seq.name]).float()

    def __iter__(self):
        return (self[i] for i in range(len(self)))

    def references(self) -> References:
        """The drapes as :class:`drapebench.data.References` (for :class:`drapebench.data.TrainData`)."""
        return References.from_files({(self.garment, name): path for name, path in self.paths.items()})

    def summary(self) -> str:
        """One line: sequences ok / failed, frames, simulation and wall time."""
        frames = sum(seq.n_frames for seq in self.sequences)
        causes = "; ".join(f"{f['sequence']}: {f['error']}" for f in self.failed)
        return (f"reference set {self.spec.name} ({self.garment}, {self.spec.solver}): {len(self)} ok / {len(self.failed)} failed "
                f"of {len(self.planned)} sequences, {frames} frames, simulation {self.sim_s / 60:.1f} min, "
                f"this build {self.wall_s / 60:.1f} min" + (f" (failed: {causes})" if causes else ""))  # fmt: skip


def sequence_failure(garment, seq, err: Exception) -> dict:
    """The record of a failed simulation of ``garment`` on ``seq``: garment, sequence, error, cause (the message), attempts."""
    return {"garment": garment.name, "sequence": seq.name, "error": type(err).__name__, "cause": str(err),
            "attempts": getattr(err, "attempts", None)}  # fmt: skip


def replacement_sequence(seq, attempt: int):
    """The ``attempt``-th (>= 1) replacement of a planned sequence whose simulation failed: the same motion kind,
    parameters, length, transition and body shape, the seed moved by ``attempt`` x the redraw stride, named
    ``<name>_r<attempt>``."""
    n_transition = int(seq.n_transition)
    return make_sequence(seq.motion, len(seq.poses) - n_transition, seq.fps, seq.seed + REDRAW_SEED_STRIDE * int(attempt), betas=seq.betas,
                         transition=n_transition, split=seq.split, name=f"{seq.name}_r{attempt}", **seq.params)  # fmt: skip


def simulate_one(garment, seq, body, material, spec: ReferenceSetSpec, force: bool = False, threads: int | None = None) -> dict:
    """Simulate (or load) the drape of ``garment`` on ``seq`` against the collider ``body`` in this process (a worker
    or a cluster job; ``threads`` torch threads); a dict with the cache path, the original simulation time and
    ``from_cache``, or the failure (garment, sequence, error, cause; a diverged simulation's failure is also
    recorded beside the cache by :mod:`drapebench.reference.simulator`, so the next try fails at once)."""
    from drapebench.reference import SimulationDiverged, simulate_record
    from drapebench.reference.simulator import GarmentStartsInside

    if threads is not None:
        torch.set_num_threads(threads)
    try:
        rec = simulate_record(garment, seq, body, material, spec.solver, force=force, progress=False, **spec.settings)
    except (SimulationDiverged, GarmentStartsInside) as err:
        return sequence_failure(garment, seq, err)
    return {"sequence": seq.name, "path": rec.path, "sim_s": rec.sim_s, "from_cache": rec.from_cache,
            "attempts": rec.stats.get("attempts")}  # fmt: skip


def build_reference_set(garment, body, material, spec: ReferenceSetSpec, n_jobs: int | None = None, progress: bool = True,
                        force: bool = False) -> ReferenceSet:  # fmt: skip
    """Simulate ``garment`` (made on ``body``) over every sequence of ``spec`` (see the module docstring).

    Args:
        garment: :class:`drapebench.garments.Garment`; body: its :class:`drapebench.body.BodyModel` (the
            collider unless ``spec.body`` names another); material: :class:`drapebench.physics.Material`.
        n_jobs: worker processes (None: ``spec.n_jobs``); 1 runs in this process.
        progress: a bar over sequences (on stderr; quiet per :func:`drapebench.progress.progress_enabled`).
        force: simulate every sequence again, failed ones included.
    Returns:
        :class:`ReferenceSet` of the successful drapes; failures are in ``.failed``.
    """
    from joblib import Parallel, delayed

    from drapebench.body import load_body
    from drapebench.reference import reference_path

    t0 = time.perf_counter()
    collider = load_body(spec.body) if spec.body else body
    planned = spec_sequences(spec.dataset_spec())
    paths = [str(reference_path(garment, seq, collider, material, spec.solver, **spec.settings)) for seq in planned]
    manifest_path = MANIFESTS.path(garment.name, paths, prefix=f"{garment.name}_{spec.name}", suffix=".json")
    manifest = None if force else MANIFESTS.load(manifest_path, lambda p: json.loads(Path(p).read_text()))
    failed = {f["sequence"]: f for f in (manifest or {}).get("failed", [])}
    n_jobs = int(spec.n_jobs if n_jobs is None else n_jobs)
    if n_jobs < 1:  # 0 was read as "the preset's", a negative number reached joblib as "every core but ..."
        raise ValueError(f"n_jobs: at least 1 worker process, got {n_jobs} (None: the preset's {spec.n_jobs})")
    threads = max(1, (os.cpu_count() or 1) // n_jobs) if n_jobs > 1 else None
    done: dict[str, dict] = {}
    seqs = list(planned)  # per place in the plan: the planned sequence or its latest replacement

    def save() -> None:
        doc = {"garment": garment.name, "spec": asdict(spec), "failed": list(failed.values()),
               "done": [done[s.name] for s in seqs if s.name in done]}  # fmt: skip
        MANIFESTS.store(manifest_path, lambda tmp: Path(tmp).write_text(json.dumps(doc, indent=2)))

    for attempt in range(int(spec.replace_failed) + 1):
        if attempt:
            seqs = [replacement_sequence(orig, attempt) if seq.name in failed else seq for orig, seq in zip(planned, seqs)]
        todo = [seq for seq in seqs if seq.name not in failed and seq.name not in done]
        if not todo:
            if any(seq.name in failed for seq in seqs):
                continue  # every replacement of this round failed before (recorded): the next round's
            break
        jobs = (delayed(simulate_one)(garment, seq, collider, material, spec, force, threads) for seq in todo)
        desc = f"references {garment.name} {spec.name}" + (f" (replacements, round {attempt})" if attempt else "")
        bar = progress_bar(total=len(todo), desc=desc, unit="seq") if progress else None
        try:
            for result in Parallel(n_jobs=n_jobs, return_as="generator_unordered")(jobs):
                if "path" in result:
                    done[result["sequence"]] = result
                else:
                    failed[result["sequence"]] = result
                    save()
                if bar is not None:
                    bar.update(1)
                    bar.set_postfix(ok=len(done), failed=len(failed))
        finally:
            if bar is not None:
                bar.close()
    save()
    return ReferenceSet(garment.name, spec, seqs, {name: r["path"] for name, r in done.items()}, list(failed.values()),
                        sum(r["sim_s"] for r in done.values()), time.perf_counter() - t0)  # fmt: skip


def collect_reference_set(garment, body, material, spec: ReferenceSetSpec) -> tuple[ReferenceSet, list]:
    """What the cache holds of the reference set of ``spec`` now, simulating nothing: (the :class:`ReferenceSet` of
    the sealed drapes and the recorded failures (diverged simulations), the planned sequences with neither). ``body``
    is the garment's body (the collider unless ``spec.body`` names another)."""
    from drapebench.body import load_body
    from drapebench.reference import reference_path
    from drapebench.reference.simulator import REFERENCES, recorded_failure

    def read_meta(path):
        with np.load(path, allow_pickle=False) as data:
            return json.loads(str(data["meta"]))

    collider = load_body(spec.body) if spec.body else body
    seqs, paths, failed, missing, sim_s = [], {}, [], [], 0.0
    for planned in spec_sequences(spec.dataset_spec()):
        for attempt in range(int(spec.replace_failed) + 1):  # the planned sequence, then its replacements in turn
            seq = replacement_sequence(planned, attempt) if attempt else planned
            path = reference_path(garment, seq, collider, material, spec.solver, **spec.settings)
            meta = REFERENCES.load(path, read_meta)
            failure = None if meta is not None else recorded_failure(path)
            if meta is not None:
                paths[seq.name], sim_s = str(path), sim_s + sum(meta["timings_s"].values())
            elif failure is not None:
                failed.append(sequence_failure(garment, seq, failure))
                if attempt < int(spec.replace_failed):
                    continue
            else:
                missing.append(seq)
            break
        seqs.append(seq)
    return ReferenceSet(garment.name, spec, seqs, paths, failed, sim_s), missing


def load_reference_set(cfg_data, garment, body, material, n_jobs: int | None = None, progress: bool = True,
                       force: bool = False) -> ReferenceSet:  # fmt: skip
    """:func:`build_reference_set` from a Hydra ``cfg.data`` node (or any mapping of :class:`ReferenceSetSpec` fields)."""
    from omegaconf import DictConfig, OmegaConf

    if isinstance(cfg_data, DictConfig):
        cfg_data = OmegaConf.to_container(cfg_data, resolve=True)
    return build_reference_set(garment, body, material, ReferenceSetSpec.from_config(cfg_data), n_jobs, progress, force)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description="Build the reference drapes of a garment (training data of supervised methods).")
    parser.add_argument("--garment", default="tshirt", help="garment kind (conf/garment), made on --body with default parameters")
    parser.add_argument("--body", default="anny", help="body the garment is made for and draped on (conf/body)")
    parser.add_argument("--data", default="cpu", help="preset in conf/data (cpu, paper, quick)")
    parser.add_argument("--material", default="cotton", help="material preset (conf/material)")
    parser.add_argument("--jobs", type=int, default=None, help="worker processes (default: the preset's n_jobs)")
    parser.add_argument("--force", action="store_true", help="simulate every sequence again, failed ones included")
    args = parser.parse_args(argv)
    from drapebench.body import load_body
    from drapebench.garments import make_garment
    from drapebench.physics import Material

    if args.jobs is not None and args.jobs < 1:
        parser.error(f"--jobs: at least 1 worker process, got {args.jobs} (leave it out for the preset's)")
    flag = "--data"  # the cheap checks first: a typo is found before the garment is made
    try:
        spec = ReferenceSetSpec.preset(args.data)
        flag = "--material"
        material = Material.preset(args.material)
        flag = "--body"
        body = load_body(args.body)
        flag = "--garment"
        garment = make_garment(args.garment, body)
    except (FileNotFoundError, KeyError, ValueError) as err:
        parser.error(f"{flag} {getattr(args, flag[2:])}: {err.args[0] if err.args else err}")
    refs = build_reference_set(garment, body, material, spec, args.jobs, force=args.force)
    print(refs.summary())
    for f in refs.failed:
        print(f"  failed {f['sequence']}: {f['cause']}")


if __name__ == "__main__":
    main()
