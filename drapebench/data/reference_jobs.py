"""A reference set on a cluster: one Hydra job per planned sequence, through the sweeps' launchers.

    python -m drapebench.data.reference_jobs data=paper garment=tshirt hydra/launcher=submitit_slurm \\
        hydra.launcher.partition=<partition> hydra.launcher.timeout_min=720 hydra.launcher.gpus_per_node=1
    python -m drapebench.data.reference_jobs data=cpu garment=skirt hydra/launcher=submitit_local   # this machine

The command plans the set of ``conf/data/<name>.yaml`` (``data.*`` overrides apply) for the garment on the body,
asks the reference cache what is done and what failed (:func:`drapebench.data.reference_set.collect_reference_set`),
and submits one job per sequence left (a Hydra multirun over ``sequence=<indices>``, config
``conf/reference_jobs.yaml``). Each job simulates its sequence (:func:`drapebench.data.reference_set.simulate_one`)
into the shared reference cache (a cluster needs a shared filesystem, as for sweeps) and writes ``result.json``
(the drape's cache file, or the failure and its cause) into its job folder. Run the command again after a kill, a
time limit or a lost node: the finished sequences are skipped, and so are those whose simulation diverged
(recorded beside the cache; ``force=true`` simulates them again). It ends with the set's summary and its failures;
a training run with the same ``data=`` then reads the drapes from the cache (``python run.py method=<a supervised method> data=paper``).
"""

from __future__ import annotations

import logging
import sys
from pathlib import Path

import hydra
from hydra.errors import HydraException
from omegaconf import DictConfig, OmegaConf

from drapebench.cache import PROJECT_ROOT, write_json

log = logging.getLogger("drapebench")
CONFIG = "reference_jobs"


def scene(cfg: DictConfig):
    """(garment, body, material, spec) of a ``conf/reference_jobs.yaml`` config; the garment is made on the mean body,
    as a run's default garment is."""
    from drapebench.body import load_body
    from drapebench.data.reference_set import ReferenceSetSpec
    from drapebench.garments import garment_from_config
    from drapebench.physics import Material

    body = load_body(cfg.body.name)
    garment = garment_from_config(OmegaConf.to_container(cfg.garment, resolve=True), body)
    material = Material.from_config(OmegaConf.to_container(cfg.material, resolve=True))
    return garment, body, material, ReferenceSetSpec.from_config(OmegaConf.to_container(cfg.data, resolve=True))


@hydra.main(config_path=str(PROJECT_ROOT / "conf"), config_name=CONFIG, version_base="1.3")
def job(cfg: DictConfig) -> dict:
    """One job: simulate planned sequence ``cfg.sequence``; ``result.json`` in the job folder."""
    from hydra.core.hydra_config import HydraConfig

    from drapebench.body import load_body
    from drapebench.body.dataset import spec_sequences
    from drapebench.data.reference_set import simulate_one

    garment, body, material, spec = scene(cfg)
    seq = spec_sequences(spec.dataset_spec())[int(cfg.sequence)]
    result = simulate_one(garment, seq, load_body(spec.body) if spec.body else body, material, spec, bool(cfg.force))
    write_json(Path(HydraConfig.get().runtime.output_dir) / "result.json", result)
    log.info("%s %s: %s", garment.name, seq.name, f"failed ({result['cause']})" if "error" in result else
             f"{'loaded from' if result['from_cache'] else 'simulated into'} {result['path']}")  # fmt: skip
    return result


def plan(overrides: list[str]):
    """The set's (garment, body, material, spec, force) from the command's overrides (those of ``hydra`` aside)."""
    from hydra import compose, initialize_config_dir

    with initialize_config_dir(config_dir=str(PROJECT_ROOT / "conf"), version_base="1.3"):
        cfg = compose(CONFIG, overrides=[o for o in overrides if not o.lstrip("+~").startswith("hydra")])
    return (*scene(cfg), bool(cfg.force))


def composition_error(err: Exception) -> str:
    """``err``'s message for the user: Hydra's own (its config search path left out) and, where Hydra gives only the
    override it could not apply, the first line of the cause (e.g. "Key 'n_jbs' is not in struct")."""
    text = str(err.args[0] if isinstance(err, KeyError) and err.args else err).split("\nConfig search path:")[0].rstrip()
    cause = str(err.__cause__ or "").splitlines()
    return text + (f" ({cause[0].strip()})" if cause else "")


def main(argv: list[str] | None = None) -> int:
    """Submit the sequences left to simulate (module docstring); returns 0 when every planned sequence has a drape or a
    recorded failure, 1 when some have neither (a job that was killed or crashed: run the command again)."""
    from drapebench.data.reference_set import collect_reference_set

    argv = list(sys.argv[1:] if argv is None else argv)
    if any(a.startswith("-") for a in argv):  # Hydra's own flags (--help, --cfg job, ...): Hydra answers them
        sys.argv = [sys.argv[0], *argv]
        job()
        return 0
    if "sequence" in {a.split("=")[0].lstrip("+") for a in argv}:
        raise SystemExit("reference_jobs sets sequence= itself (the sequences left to simulate); drop it from the command")
    try:
        garment, body, material, spec, force = plan(argv)
    except (HydraException, KeyError, ValueError, FileNotFoundError) as err:  # an override it cannot compose or a scene it cannot make
        raise SystemExit(f"reference_jobs: {composition_error(err)}") from None
    refs, missing = collect_reference_set(garment, body, material, spec)
    todo = list(range(len(refs.planned))) if force else [refs.planned.index(s) for s in missing]
    print(f"reference set {spec.name} ({garment.name}): {len(refs.planned)} sequences planned, {len(refs)} done, "
          f"{len(refs.failed)} failed, {len(todo)} to simulate", flush=True)  # fmt: skip
    if todo:
        sys.argv = [sys.argv[0], "-m", *argv, f"sequence={','.join(map(str, todo))}"]
        try:
            job()
        except SystemExit as stop:  # Hydra ends a multirun in which a job raised this way; the jobs that ran are in the cache
            if stop.code:
                print(f"some jobs did not finish (exit {stop.code}); their folders hold the error", file=sys.stderr)
        refs, missing = collect_reference_set(garment, body, material, spec)
    print(refs.summary())
    for f in refs.failed:
        print(f"  failed {f['sequence']}: {f['cause']}")
    if missing:
        print(f"{len(missing)} sequence(s) have no drape yet ({', '.join(s.name for s in missing[:5])}"
              f"{', ...' if len(missing) > 5 else ''}): run the same command again", file=sys.stderr)  # fmt: skip
    return 1 if missing else 0


if __name__ == "__main__":
    sys.exit(main())
