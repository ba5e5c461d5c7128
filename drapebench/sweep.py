"""The Hydra callback of every sweep and run (``hydra.callbacks.sweep_summary`` in ``conf/config.yaml``): a sweep's
summary, and a single run's copy of the ``.hydra/`` an earlier run left in its folder (:mod:`drapebench.hydra_folder`).

It is instantiated when a sweep starts, before any job runs, so this module imports only Hydra: a sweep
with a bad override fails within about a second instead of after the pipeline's imports.
"""

from __future__ import annotations

import logging
from pathlib import Path

from hydra.experimental.callback import Callback
from omegaconf import DictConfig

log = logging.getLogger("drapebench")


class SweepSummary(Callback):
    """Hydra callback: at the end of a sweep, gather every job's metrics.json into summary.md / summary.csv.
    A job that raises leaves ``failed.json`` (the error and its message) in its folder; a sweep that stops
    early still gets its summary (finished, failed and unfinished jobs, the last with the command that finishes
    each), and one that stops before any job started (a bad override) leaves no empty folder behind."""

    def on_run_start(self, config: DictConfig, **kwargs) -> None:
        """A single run, before Hydra writes its ``.hydra/`` into the run folder: keep a copy of the one there (an
        earlier run's), which the run puts back when it does not take the folder."""
        if config.hydra.output_subdir is not None:
            from drapebench.hydra_folder import keep_earlier_hydra

            keep_earlier_hydra(Path(str(config.hydra.run.dir)), str(config.hydra.output_subdir))

    def on_multirun_start(self, config: DictConfig, **kwargs) -> None:
        import atexit

        self._ended = False
        atexit.register(self._after_early_stop, Path(config.hydra.sweep.dir))

    def on_job_end(self, config: DictConfig, job_return, **kwargs) -> None:
        from hydra.core.utils import JobStatus

        out = Path(job_return.hydra_cfg.hydra.runtime.output_dir) if job_return.hydra_cfg else None
        refused = type(job_return._return_value).__name__ == "RunFolderInUse"  # the folder is another run's: left as it is
        if job_return.status == JobStatus.FAILED and out is not None and out.is_dir() and not (out / "failed.json").exists() and not refused:
            from drapebench.cache import write_json
            from drapebench.experiment import failure_record

            write_json(out / "failed.json", failure_record(config, job_return._return_value))

    def on_multirun_end(self, config: DictConfig, **kwargs) -> None:
        self._ended = True
        self._summarise(Path(config.hydra.sweep.dir))

    def _summarise(self, sweep_dir: Path) -> None:
        from drapebench.report import write_summary

        if sweep_dir.exists():
            log.info("sweep summary: %s", write_summary(sweep_dir))

    def _after_early_stop(self, sweep_dir: Path) -> None:
        if self._ended or not sweep_dir.is_dir():
            return
        import re
        import shutil
        import sys

        if not any(p.is_dir() for p in sweep_dir.iterdir()):
            shutil.rmtree(sweep_dir)
            if re.fullmatch(r"\d{4}-\d{2}-\d{2}", sweep_dir.parent.name) and not any(sweep_dir.parent.iterdir()):
                sweep_dir.parent.rmdir()  # the default layout's multirun/<date>/, when this was its only sweep
            print(f"the sweep stopped before any job started; removed its empty folder {sweep_dir}", file=sys.stderr)
            return
        try:
            self._summarise(sweep_dir)
            print(f"the sweep stopped early; finished, failed and unfinished jobs: {sweep_dir / 'summary.md'}", file=sys.stderr)
        except FileNotFoundError:  # no job finished or recorded a failure
            print(f"the sweep stopped before any job finished; see the run.log in each job folder of {sweep_dir}", file=sys.stderr)
