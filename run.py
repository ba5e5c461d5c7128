"""drapebench entry point: `python run.py [overrides]` or `python run.py -m key=a,b` for sweeps.

See conf/config.yaml for the defaults and README.md for examples.
"""

import hydra
from omegaconf import DictConfig

from drapebench.schema import register

register()


@hydra.main(version_base="1.3", config_path="conf", config_name="config")
def main(cfg: DictConfig) -> float:
    from drapebench.experiment import run

    record = run(cfg)
    return float("inf") if record.get("status") == "failed" else record["eps_c"]  # what an optimising sweeper minimises


if __name__ == "__main__":
    main()
