"""`python -m searchrl.evaluate controller=<name> [+model=...]`, `checkpoint=<model.zip>` or `suite=<name> ...`

`<name>` is a heuristic of searchrl/controllers/registry.py. The entry point: the OpenMP wait policy (before torch
loads), then what a command line must pass before Hydra runs it (searchrl/command_line.py: the user's `extensions=`,
group options that exist, jobs that compose), then one grid (searchrl/evaluate/app.py) or a suite's scenarios
(searchrl/evaluate/suite.py); a refused job of a multirun lets the others run (searchrl/multirun.py).
"""

import sys

from searchrl.threads import set_wait_policy

set_wait_policy(sys.argv)
import hydra  # noqa: E402
from hydra.core.hydra_config import HydraConfig  # noqa: E402
from omegaconf import DictConfig  # noqa: E402

from searchrl.command_line import check_group_choices, check_jobs_compose, import_from_command_line  # noqa: E402
from searchrl.evaluate.app import evaluate  # noqa: E402  (loads torch: after the wait policy)
from searchrl.evaluate.schema import register_configs  # noqa: E402
from searchrl.evaluate.suite import evaluate_suite  # noqa: E402
from searchrl.multirun import exits, in_sweep  # noqa: E402
from searchrl.shared_schema import CONF_DIR  # noqa: E402


@hydra.main(version_base="1.3", config_path=str(CONF_DIR), config_name="evaluate")
def main(cfg: DictConfig) -> None:
    overrides = list(HydraConfig.get().overrides.task)
    in_sweep(evaluate_suite if cfg.get("suite") is not None else evaluate, cfg, overrides)


if __name__ == "__main__":
    with exits():
        import_from_command_line(sys.argv[1:])  # the extensions' parts, before any name is checked
        register_configs()  # the heuristics they registered become controller= options
        check_group_choices(sys.argv[1:])
        check_jobs_compose(sys.argv[1:], "evaluate")
    main()
