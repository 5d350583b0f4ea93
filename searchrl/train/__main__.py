"""`python -m searchrl.train +model=<a|b|c|diagonal> [algo=a2c] [network=small] [scenario=...] [key=value ...]`
or `python -m searchrl.train +experiment=<recipe>` (conf/experiment/, the recipe of a shipped policy).

The entry point: the OpenMP wait policy (before torch loads), then what a command line must pass before Hydra runs
it (searchrl/command_line.py: the user's `extensions=`, a `resume=` that is a folder, group options that exist,
jobs that compose), then the app (searchrl/train/app.py: what a run does and writes).
"""

import sys

from searchrl.threads import set_wait_policy

set_wait_policy(sys.argv)
from searchrl.command_line import (  # noqa: E402
    check_group_choices,
    check_jobs_compose,
    check_resume_argument,
    check_run_dir_argument,
    import_from_command_line,
)
from searchrl.multirun import exits  # noqa: E402
from searchrl.train.app import main  # noqa: E402  (loads torch: after the wait policy)
from searchrl.train.schema import register_configs  # noqa: E402

if __name__ == "__main__":
    with exits():
        import_from_command_line(sys.argv[1:])  # the extensions' parts, before any name is checked
        register_configs()  # the networks, critics and rewards they registered become group options
        check_resume_argument(sys.argv[1:])
        check_run_dir_argument(sys.argv[1:])
        check_group_choices(sys.argv[1:])
        check_jobs_compose(sys.argv[1:], "train")
    main()
